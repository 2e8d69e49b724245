//! `tactus render`: one song to its pattern, features, plot, preview and exports, or a
//! library with `--out-dir` (`batch`). The work is the engine's; this parses and prints.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};

use tactus_batch::Command;
use tactus_engine::render::{render, RenderOutput, RenderRequest};
use tactus_glove::export::ExportFormat;
use tactus_glove::png::{plot_bytes, PlotFormat};
use tactus_glove::{write_atomic, OutputSet};

use crate::args::{EngineArgs, ModeArg};
use crate::batch;

// The arguments of `tactus render` (its help text is the subcommand's, in main.rs).
#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// The song: WAV, FLAC, MP3, OGG/Vorbis, AAC/M4A. With --out-dir, any number of
    /// songs, directories (searched recursively for audio files) and quoted globs.
    #[arg(required = true, num_args = 1..)]
    pub(crate) inputs: Vec<PathBuf>,
    #[command(flatten)]
    pub(crate) batch: batch::BatchArgs,
    /// Pattern file to write ("-" for stdout).
    #[arg(short = 'o', long = "output")]
    pub(crate) output: Option<PathBuf>,
    /// Features file to write (JSON).
    #[arg(long)]
    pub(crate) features: Option<PathBuf>,
    /// Plot to write (.svg, or .png rasterised with the system's fonts).
    #[arg(long)]
    pub(crate) plot: Option<PathBuf>,
    /// Browser preview to write: one self-contained page that plays the song (embedded)
    /// and animates the glove in sync with it.
    #[arg(long, value_name = "PAGE.html")]
    pub(crate) html: Option<PathBuf>,
    /// Export for other tools, by extension (repeatable): .csv (one row per bin, one 0/1
    /// column per dot) or .ahap (Apple Core Haptics: drums as transients, bass as
    /// continuous sharpness).
    #[arg(long, value_name = "FILE.csv|FILE.ahap")]
    pub(crate) export: Vec<PathBuf>,
    #[command(flatten)]
    pub(crate) engine: EngineArgs,
    /// Statistics: offline (whole track, paper) or streaming (causal, as live).
    #[arg(long, value_enum, default_value = "offline")]
    pub(crate) mode: ModeArg,
    /// Print which stages ran, what each cost, and the latency budget.
    #[arg(short, long)]
    pub(crate) verbose: bool,
}

/// Renders one song, or a library with `--out-dir`.
pub(crate) fn run(args: RenderArgs) -> Result<()> {
    let RenderArgs {
        inputs,
        batch,
        output,
        features,
        plot,
        html,
        export,
        engine,
        mode,
        verbose,
    } = &args;
    let (mode, verbose) = (*mode, *verbose);
    if let Some(dir) = &batch.out_dir {
        let single = [
            ("-o", output.is_some()),
            ("--features", features.is_some()),
            ("--plot", plot.is_some()),
            ("--html", html.is_some()),
            ("--export", !export.is_empty()),
            ("--stem", !engine.stems.is_empty()),
        ];
        if let Some((flag, _)) = single.iter().find(|(_, on)| *on) {
            bail!(
                "{flag} names one song's output and does not go with --out-dir \
                 (use --with-features or --with-plot svg|png for a library)"
            );
        }
        return batch::run(inputs, dir, batch, engine, mode, verbose);
    }
    if let Some(flag) = batch.given() {
        bail!("{flag} needs --out-dir DIR");
    }
    let [input] = &inputs[..] else {
        bail!(
            "{} inputs: rendering several songs needs --out-dir DIR",
            inputs.len()
        );
    };
    if input.is_dir() {
        bail!(
            "{} is a directory: add --out-dir DIR to render the songs in it",
            input.display()
        );
    }
    render_one(input, &args)
}

/// The files one song's render writes, in the order they are written: (flag, path).
fn outputs(args: &RenderArgs) -> Vec<(&'static str, &Path)> {
    [
        ("-o", args.output.as_deref()),
        ("--features", args.features.as_deref()),
        ("--plot", args.plot.as_deref()),
        ("--html", args.html.as_deref()),
    ]
    .into_iter()
    .chain(args.export.iter().map(|p| ("--export", Some(p.as_path()))))
    .filter_map(|(label, p)| p.map(|p| (label, p)))
    .collect()
}

/// `tactus render SONG`: renders `input` and writes every output the arguments name, all
/// or none.
fn render_one(input: &Path, args: &RenderArgs) -> Result<()> {
    let RenderArgs {
        plot,
        export,
        engine,
        mode,
        verbose,
        ..
    } = args;
    let input = input.to_path_buf();
    let (config, stems) = engine.config(Command::Render, *mode)?;
    let export_kinds = export
        .iter()
        .map(|p| {
            ExportFormat::of(p).ok_or_else(|| {
                anyhow!(
                    "--export {}: unknown format (use a .csv or .ahap file name)",
                    p.display()
                )
            })
        })
        .collect::<Result<Vec<_>>>()?;
    // Outputs are one transaction: checked and their temporary files created now,
    // renamed over their targets only when every one is complete.
    let outputs = outputs(args);
    let mut inputs: Vec<&Path> = vec![input.as_path()];
    inputs.extend(stems.iter().map(|(_, p)| p.as_path()));
    inputs.extend(engine.model.as_deref());
    inputs.extend(engine.map.as_deref());
    let mut out_set = OutputSet::prepare(&outputs, &inputs)?;
    let plot_format =
        match plot.as_deref() {
            Some(p) => Some(PlotFormat::of(p).ok_or_else(|| {
                anyhow!("--plot {}: the plot must end in .svg or .png", p.display())
            })?),
            None => None,
        };
    // Ctrl-C: remove the temporary files and leave every existing file as it was.
    let _ = ctrlc::set_handler(|| {
        tactus_glove::atomic::remove_pending_temporaries();
        eprintln!("tactus: interrupted: no output written");
        std::process::exit(130);
    });
    let out = render_with_bar(RenderRequest {
        input: input.clone(),
        stems,
        config,
    })?;
    for w in &out.warnings {
        eprintln!("tactus: warning: {w}");
    }
    let Drawn {
        mut plot_bytes,
        mut html_bytes,
        mut export_bytes,
    } = draw(args, &input, &out, plot_format, &export_kinds)?;
    let mut stdout_bytes = None;
    for (i, &(label, p)) in outputs.iter().enumerate() {
        let bytes = match label {
            "-o" => out.pattern.to_json_string()?.into_bytes(),
            "--features" => out.features.to_json_string()?.into_bytes(),
            "--html" => html_bytes.take().unwrap_or_default(),
            "--export" => export_bytes.next().unwrap_or_default(),
            _ => plot_bytes.take().unwrap_or_default(),
        };
        if p == Path::new("-") {
            stdout_bytes = Some(bytes);
        } else {
            out_set.write(i, &bytes)?;
        }
    }
    out_set.commit()?;
    if let Some(bytes) = stdout_bytes {
        write_atomic(Path::new("-"), |w| w.write_all(&bytes))
            .context("writing the pattern to standard output")?;
    }
    if outputs.is_empty() {
        eprintln!(
            "tactus: rendered {} ({:.1} s, {} frames of {} ms) and wrote nothing: add \
             -o PATTERN.json (or -o - for standard output), --features FEAT.json or \
             --plot OUT.svg to keep the result",
            input.display(),
            out.duration_s,
            out.pattern.frames.len(),
            out.pattern.bin_ms
        );
    }
    if *verbose {
        eprint!("{}", out.report_text());
    }
    Ok(())
}

/// Renders `req` with a progress bar on a terminal's stderr.
fn render_with_bar(req: RenderRequest) -> Result<RenderOutput> {
    let input = &req.input;
    let bar = if std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new(1000);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {msg} [{bar:40}] {percent}% {elapsed}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b.set_message(input.display().to_string());
        Some(b)
    } else {
        None
    };
    let result = render(&req, &mut |f| {
        if let Some(b) = &bar {
            b.set_position((f * 1000.0) as u64);
        }
    });
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    Ok(result?)
}

/// The plot, the preview page and the exports of a render, drawn before anything is
/// written, so a failure leaves no output.
struct Drawn<I> {
    plot_bytes: Option<Vec<u8>>,
    html_bytes: Option<Vec<u8>>,
    /// One per `--export`, in order.
    export_bytes: I,
}

/// [`Drawn`] for the outputs `args` names.
fn draw<'a>(
    args: &RenderArgs,
    input: &Path,
    out: &'a RenderOutput,
    plot_format: Option<PlotFormat>,
    export_kinds: &'a [ExportFormat],
) -> Result<Drawn<impl Iterator<Item = Vec<u8>> + 'a>> {
    let RenderArgs { plot, html, .. } = args;
    let plot_bytes = match (&plot, plot_format) {
        (Some(p), Some(format)) => {
            let png = plot_bytes(&out.pattern, &out.features, format)
                .with_context(|| format!("--plot {}", p.display()))?;
            if !png.fonts {
                eprintln!(
                    "tactus: warning: --plot {}: no system font found, so the PNG \
                     has no text (install e.g. fonts-dejavu-core, or use .svg)",
                    p.display()
                );
            }
            Some(png.bytes)
        }
        _ => None,
    };
    let html_bytes = match &html {
        Some(p) => Some(html_page(input, out).with_context(|| format!("--html {}", p.display()))?),
        None => None,
    };
    let export_bytes = export_kinds
        .iter()
        .map(|k| k.bytes(&out.pattern, &out.features));
    Ok(Drawn {
        plot_bytes,
        html_bytes,
        export_bytes,
    })
}

/// The `--html` page, with a note of its size and a warning when browsers may not play
/// the song.
fn html_page(input: &Path, out: &RenderOutput) -> Result<Vec<u8>> {
    let page = tactus_glove::html::page_for_song(input, &out.pattern, &out.features)?;
    if let Some(why) = &page.audio.unplayable {
        eprintln!("tactus: warning: --html: browsers may not play this audio ({why}); the page's glove runs on the wall clock");
    }
    eprintln!(
        "tactus: --html: page {:.1} MB, of which audio {:.1} MB ({}, the source file as base64)",
        page.html.len() as f64 / 1e6,
        page.audio_bytes as f64 * 4.0 / 3.0 / 1e6,
        page.audio.name
    );
    Ok(page.html.into_bytes())
}
