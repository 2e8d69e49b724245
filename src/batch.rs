//! `tactus render INPUT... --out-dir DIR`: the arguments, one progress bar for the library,
//! and the printing. The work is `tactus_batch`'s.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::ValueEnum;

use tactus_glove::png::{plot_bytes, PlotFormat};

use crate::{EngineArgs, ModeArg};

#[derive(Clone, Copy, ValueEnum)]
pub enum PlotArg {
    Svg,
    Png,
}

/// The batch options of `render`.
#[derive(clap::Args)]
pub struct BatchArgs {
    /// Render a library: DIR/a/b.pattern.json for INPUT_ROOT/a/b.mp3, DIR/manifest.jsonl
    /// with one record per input; a rerun skips songs whose outputs are up to date.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Songs rendered at once (with --out-dir) [default: the available cores].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub jobs: Option<u32>,
    /// Threads per song (with --out-dir) [default: cores / jobs, at least 1; 1 runs each
    /// song on one thread].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub job_threads: Option<u32>,
    /// Also write DIR/a/b.features.json (with --out-dir).
    #[arg(long)]
    pub with_features: bool,
    /// Also write DIR/a/b.svg or DIR/a/b.png (with --out-dir).
    #[arg(long, value_enum, value_name = "svg|png")]
    pub with_plot: Option<PlotArg>,
}

impl BatchArgs {
    /// A batch-only option that was given, if any.
    pub fn given(&self) -> Option<&'static str> {
        [
            ("--jobs", self.jobs.is_some()),
            ("--job-threads", self.job_threads.is_some()),
            ("--with-features", self.with_features),
            ("--with-plot", self.with_plot.is_some()),
        ]
        .into_iter()
        .find_map(|(f, on)| on.then_some(f))
    }
}

/// Runs the batch and prints a summary; an error if any input failed.
pub fn run(
    inputs: &[PathBuf],
    dir: &Path,
    args: &BatchArgs,
    engine: &EngineArgs,
    mode: ModeArg,
    verbose: bool,
) -> Result<()> {
    let plan = tactus_batch::plan(inputs, Some(dir))?;
    let plot_fn = |format| {
        move |out: &tactus_engine::render::RenderOutput| {
            plot_bytes(&out.pattern, &out.features, format)
                .map(|p| p.bytes)
                .map_err(|e| e.to_string())
        }
    };
    let svg = plot_fn(PlotFormat::Svg);
    let png = plot_fn(PlotFormat::Png);
    let mut spec = tactus_batch::BatchSpec::new(dir.to_path_buf(), engine.options(mode));
    spec.features = args.with_features;
    spec.jobs = args.jobs.map_or(0, |n| n as usize);
    spec.job_threads = args.job_threads.map_or(0, |n| n as usize);
    match args.with_plot {
        Some(PlotArg::Svg) => spec.extras.push(tactus_batch::Extra {
            suffix: ".svg".into(),
            make: &svg,
        }),
        Some(PlotArg::Png) => spec.extras.push(tactus_batch::Extra {
            suffix: ".png".into(),
            make: &png,
        }),
        None => {}
    }
    let total = plan.jobs.len() + plan.rejected.len();
    if total == 0 {
        bail!("no audio files found in the inputs");
    }
    // Ctrl-C: remove the temporary files; finished songs are in the manifest already.
    let _ = ctrlc::set_handler(|| {
        tactus_glove::atomic::remove_pending_temporaries();
        eprintln!("tactus: interrupted: finished songs are kept; run again to resume");
        std::process::exit(130);
    });
    let bar = if std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new(total as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} [{bar:40}] {pos}/{len} songs {elapsed} (eta {eta}) {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        Some(b)
    } else {
        None
    };
    let t = std::time::Instant::now();
    let mut failed = 0;
    let summary = tactus_batch::run(&plan, &spec, &mut |r, _done, _total| {
        let line = match (&r.status, &r.error) {
            (tactus_batch::Status::Failed, Some(e)) => {
                failed += 1;
                Some(format!("tactus: error: {e}"))
            }
            (status, _) if verbose => Some(format!(
                "tactus: {} {} ({:.2} s)",
                match status {
                    tactus_batch::Status::Ok => "rendered",
                    _ => "up to date",
                },
                r.path.display(),
                r.seconds
            )),
            _ => None,
        };
        match (&bar, line) {
            (Some(b), Some(l)) => b.println(l),
            (None, Some(l)) => eprintln!("{l}"),
            _ => {}
        }
        if let Some(b) = &bar {
            b.inc(1);
            if failed > 0 {
                b.set_message(format!("{failed} failed"));
            }
        }
    })?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let secs = t.elapsed().as_secs_f64();
    eprintln!(
        "tactus: {} songs in {:.1} s ({:.1} songs/min): {} rendered, {} up to date, {} failed; \
         manifest {}",
        total,
        secs,
        total as f64 * 60.0 / secs.max(1e-9),
        summary.ok,
        summary.skipped,
        summary.failed,
        dir.join(tactus_batch::MANIFEST).display()
    );
    if summary.failed > 0 {
        bail!(
            "{} of {} songs failed (see above and {})",
            summary.failed,
            total,
            dir.join(tactus_batch::MANIFEST).display()
        );
    }
    Ok(())
}
