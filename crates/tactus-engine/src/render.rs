//! The offline driver: a song file (plus optional supplied stems) through the engine to a
//! pattern and a features file. Decoding and resampling stream, so in `streaming` mode
//! memory does not grow with the song beyond the per-hop feature records.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use tactus_dsp::Stem;
use tactus_glove::{Features, Pattern, SourceInfo};
use tactus_separate::SegmentStats;

use crate::engine::{Engine, EngineConfig, StageTimes};
use crate::resample::StreamResampler;
use crate::source::AudioSource;
use crate::EngineError;

/// Samples per engine block in offline rendering (1 s at 44.1 kHz): large enough for the
/// stem chains to run on separate threads.
const BLOCK: usize = 88_200;
/// Decoded blocks the reader thread may hold ready ahead of the engine.
const DECODE_AHEAD: usize = 4;

/// One block of decoded planar stereo at the file's rate; `last` marks the end of the stream.
struct DecodedBlock {
    left: Vec<f32>,
    right: Vec<f32>,
    last: bool,
}

/// Decodes one block of about [`BLOCK`] frames into `block` (its buffers reused).
fn decode_block(
    source: &mut AudioSource,
    block: &mut DecodedBlock,
) -> Result<(), crate::source::SourceError> {
    block.left.clear();
    block.right.clear();
    block.last = false;
    while block.left.len() < BLOCK {
        if source.read_block(&mut block.left, &mut block.right)? == 0 {
            block.last = true;
            break;
        }
    }
    Ok(())
}

fn new_block() -> DecodedBlock {
    DecodedBlock {
        left: Vec::with_capacity(BLOCK * 2),
        right: Vec::with_capacity(BLOCK * 2),
        last: false,
    }
}

/// The reader thread: decodes blocks (reusing the buffers sent back on `spare`) until the
/// stream ends, an error occurs (sent on, then it stops) or the receiver hangs up. Returns
/// the source (for its warnings) and the time spent decoding.
fn decode_blocks(
    mut source: AudioSource,
    blocks: &mpsc::SyncSender<Result<DecodedBlock, EngineError>>,
    spare: &mpsc::Receiver<DecodedBlock>,
) -> (AudioSource, Duration) {
    let mut spent = Duration::ZERO;
    loop {
        let mut block = spare.try_recv().unwrap_or_else(|_| new_block());
        let t = Instant::now();
        let r = decode_block(&mut source, &mut block);
        spent += t.elapsed();
        if let Err(e) = r {
            let _ = blocks.send(Err(e.into()));
            return (source, spent);
        }
        let last = block.last;
        if blocks.send(Ok(block)).is_err() || last {
            return (source, spent);
        }
    }
}

/// What to render.
#[derive(Debug, Clone)]
pub struct RenderRequest {
    /// The song.
    pub input: PathBuf,
    /// Stems supplied directly (`--stem NAME=PATH`).
    pub stems: Vec<(Stem, PathBuf)>,
    /// Engine settings (the `supplied` field is filled in from `stems`).
    pub config: EngineConfig,
}

/// What came out.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// The pattern file contents.
    pub pattern: Pattern,
    /// The features file contents.
    pub features: Features,
    /// Things the user should know (sanitized samples, padded stems, truncation).
    pub warnings: Vec<String>,
    /// Time per stage, decode and resample included.
    pub times: StageTimes,
    /// Latency budget (stage, ms).
    pub latency: Vec<(String, f64)>,
    /// Stems the engine computed.
    pub stems: Vec<Stem>,
    /// Separator that ran.
    pub separator: Option<&'static str>,
    /// Duration of the input in seconds.
    pub duration_s: f64,
    /// Per-segment timing of an ONNX separator (`None` for the others).
    pub segments: Option<SegmentStats>,
}

impl RenderOutput {
    /// Assembles the output of a finished `engine` whose input was `source`: the pattern
    /// from `frames` and the engine's configuration, the features, the latency budget, and
    /// the stage times with `outside` (stages timed by the caller, such as decode and
    /// resample) first and the wall time since `started` last.
    pub fn from_engine(
        engine: &Engine,
        source: SourceInfo,
        frames: Vec<tactus_glove::Frame>,
        outside: &[(&str, Duration)],
        started: Instant,
        warnings: Vec<String>,
    ) -> Self {
        let cfg = engine.config();
        let duration_s = source.duration_s;
        let pattern = Pattern {
            source,
            bin_ms: cfg.bin_ms,
            levels: cfg.levels,
            map: cfg.map.clone(),
            frames,
        };
        let mut times = engine.stage_times();
        for (k, (name, t)) in outside.iter().enumerate() {
            times.stages.insert(k, ((*name).into(), *t));
        }
        times
            .stages
            .push(("total (wall)".into(), started.elapsed()));
        RenderOutput {
            features: engine.features(),
            latency: engine.latency_budget(),
            stems: engine.stems(),
            separator: engine.separator_name(),
            segments: engine.segment_stats(),
            pattern,
            warnings,
            times,
            duration_s,
        }
    }

    /// The report `render --verbose` prints: what ran, what each stage cost, the speed, an
    /// ONNX separator's segments, and the latency budget (stage by stage, then the total).
    pub fn report_text(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let stems: Vec<&str> = self.stems.iter().map(|s| s.name()).collect();
        let _ = writeln!(
            s,
            "tactus: {} ({:.1} s), separator {}, stems {}",
            self.pattern.source.path,
            self.duration_s,
            self.separator.unwrap_or("none needed"),
            stems.join(", ")
        );
        for (name, t) in &self.times.stages {
            let _ = writeln!(s, "  {:<36} {:>9.3} s", name, t.as_secs_f64());
        }
        let total = self.times.stages.last().map_or(0.0, |t| t.1.as_secs_f64());
        if total > 0.0 {
            let _ = writeln!(s, "  speed: {:.1}x real time", self.duration_s / total);
        }
        if let Some(st) = &self.segments {
            let _ = writeln!(
                s,
                "  network segments: {}, per segment mean {:.3} s, min {:.3} s, max {:.3} s",
                st.segments,
                st.network_mean().as_secs_f64(),
                st.network_min.as_secs_f64(),
                st.network_max.as_secs_f64()
            );
            let _ = writeln!(
                s,
                "  outside the network (STFT, iSTFT, overlap-add, masks): {:.3} s = {:.1} % of the network's {:.3} s",
                st.outside().as_secs_f64(),
                100.0 * st.outside_share(),
                st.network.as_secs_f64()
            );
        }
        let _ = writeln!(s, "  latency budget (streaming):");
        for (name, ms) in &self.latency {
            let _ = writeln!(s, "    {name:<44} {ms:>7.1} ms");
        }
        let sum: f64 = self.latency.iter().map(|(_, ms)| ms).sum();
        let _ = writeln!(s, "    {:<44} {sum:>7.1} ms", "total");
        s
    }
}

/// A supplied stem, decoded and resampled whole, read out in step with the mix.
struct SuppliedStem {
    stem: Stem,
    samples: Vec<f32>,
    pos: usize,
    buf: Vec<f32>,
}

fn load_stem(
    stem: Stem,
    path: &Path,
    rate: u32,
    warnings: &mut Vec<String>,
) -> Result<SuppliedStem, EngineError> {
    let d = crate::source::decode_all(path)?;
    if d.non_finite > 0 {
        warnings.push(format!(
            "{}: {} NaN/Inf samples replaced by 0",
            path.display(),
            d.non_finite
        ));
    }
    let mono: Vec<f32> = d
        .left
        .iter()
        .zip(&d.right)
        .map(|(l, r)| 0.5 * (l + r))
        .collect();
    let samples = if d.info.sample_rate == rate {
        mono
    } else {
        let mut rs = StreamResampler::new(d.info.sample_rate, rate, 1)?;
        let mut out = vec![Vec::new()];
        rs.process(&[&mono], &mut out);
        rs.finish(&mut out);
        out.pop().unwrap_or_default()
    };
    Ok(SuppliedStem {
        stem,
        samples,
        pos: 0,
        buf: Vec::with_capacity(BLOCK),
    })
}

impl SuppliedStem {
    /// The next `n` samples, zero-padded past the end.
    fn next(&mut self, n: usize) {
        self.buf.clear();
        let end = (self.pos + n).min(self.samples.len());
        if self.pos < end {
            self.buf.extend_from_slice(&self.samples[self.pos..end]);
        }
        self.buf.resize(n, 0.0);
        self.pos += n;
    }
}

/// Renders a song. `progress(fraction)` is called after every block when the duration is
/// known: the fraction of the input read, or, with a separator that runs a network in
/// segments (htdemucs, Spleeter: nearly all the time), the fraction of its segments done,
/// so the bar advances per segment and does not reach 1 before the last one.
pub fn render(
    req: &RenderRequest,
    progress: &mut dyn FnMut(f64),
) -> Result<RenderOutput, EngineError> {
    render_with(req, progress, &mut |_, _| true)
}

/// [`render`], also handing every glove frame to `on_frame(bin, frame)` as soon as it is
/// final: in `streaming` mode while the song is still being decoded (what `tactus play`
/// uses), in `offline` mode all at the end. `on_frame` returns whether to go on: `false`
/// stops decoding and rendering at once and the call returns [`EngineError::Cancelled`]
/// (how `play` stops on Ctrl-C without rendering the rest of a long file).
pub fn render_with(
    req: &RenderRequest,
    progress: &mut dyn FnMut(f64),
    on_frame: &mut dyn FnMut(usize, tactus_glove::Frame) -> bool,
) -> Result<RenderOutput, EngineError> {
    render_tapped(req, progress, &mut |_, _| {}, on_frame)
}

/// [`render_with`], also handing every decoded block of the song (planar stereo at the
/// file's own rate, [`AudioSource::info`]) to `on_block(left, right)` once the block's
/// frames have been handed to `on_frame`: how `tactus play` feeds the speakers from the
/// same decode as the engine.
pub fn render_tapped(
    req: &RenderRequest,
    progress: &mut dyn FnMut(f64),
    on_block: &mut dyn FnMut(&[f32], &[f32]),
    on_frame: &mut dyn FnMut(usize, tactus_glove::Frame) -> bool,
) -> Result<RenderOutput, EngineError> {
    render_inner(req, progress, on_block, on_frame, &mut || true)
}

/// [`render`], asking `keep_going()` after every decoded block (about 2 s of audio): `false`
/// stops decoding and rendering and the call returns [`EngineError::Cancelled`]. In
/// `offline` mode no frame exists before the end, so this is how a caller stops a
/// whole-song render early (`tactus play --whole` on Ctrl-C).
pub fn render_until(
    req: &RenderRequest,
    progress: &mut dyn FnMut(f64),
    keep_going: &mut dyn FnMut() -> bool,
) -> Result<RenderOutput, EngineError> {
    render_inner(req, progress, &mut |_, _| {}, &mut |_, _| true, keep_going)
}

fn render_inner(
    req: &RenderRequest,
    progress: &mut dyn FnMut(f64),
    on_block: &mut dyn FnMut(&[f32], &[f32]),
    on_frame: &mut dyn FnMut(usize, tactus_glove::Frame) -> bool,
    keep_going: &mut dyn FnMut() -> bool,
) -> Result<RenderOutput, EngineError> {
    let t_all = Instant::now();
    let mut warnings = Vec::new();
    let source = AudioSource::open(&req.input)?;
    let info = source.info().clone();
    let rate = req.config.sample_rate;

    let mut cfg = req.config.clone();
    cfg.pipeline = true;
    let mut t_decode = Duration::ZERO;
    let t = Instant::now();
    let mut supplied = Vec::new();
    for (stem, path) in &req.stems {
        cfg.supplied = cfg.supplied.with(*stem);
        supplied.push(load_stem(*stem, path, rate, &mut warnings)?);
    }
    t_decode += t.elapsed();
    let mut engine = Engine::new(cfg)?;
    // Only the supplied stems the map uses are fed.
    let used = engine.stems();
    supplied.retain(|s| used.contains(&s.stem));

    let mut resampler = if info.sample_rate != rate {
        Some(StreamResampler::new(info.sample_rate, rate, 2)?)
    } else {
        None
    };
    let mut t_resample = Duration::ZERO;
    let mut out = vec![Vec::with_capacity(BLOCK * 2), Vec::with_capacity(BLOCK * 2)];
    let mut frames_in: u64 = 0;
    let total = info.frames.unwrap_or(0);
    let mut delivered = 0usize;
    // Everything done with one decoded block (at the file's rate).
    let mut consume = |block: &DecodedBlock| -> Result<(), EngineError> {
        frames_in += block.left.len() as u64;
        let t = Instant::now();
        match &mut resampler {
            Some(rs) => {
                rs.process(&[&block.left, &block.right], &mut out);
                if block.last {
                    rs.finish(&mut out);
                }
            }
            None => {
                out[0].extend_from_slice(&block.left);
                out[1].extend_from_slice(&block.right);
            }
        }
        t_resample += t.elapsed();
        let len = out[0].len().min(out[1].len());
        feed(&mut engine, &out[0][..len], &out[1][..len], &mut supplied);
        out[0].clear();
        out[1].clear();
        if let Some(e) = engine.take_separator_error() {
            return Err(e);
        }
        if req.config.mode == crate::Mode::Streaming {
            let ready = engine.ready_bins();
            while delivered < ready {
                if !on_frame(delivered, engine.frame(delivered)) {
                    return Err(EngineError::Cancelled);
                }
                delivered += 1;
            }
        }
        on_block(&block.left, &block.right);
        if !keep_going() {
            return Err(EngineError::Cancelled);
        }
        if total > 0 {
            progress(match engine.segment_stats() {
                Some(st) => {
                    let samples = total * rate as u64 / info.sample_rate.max(1) as u64;
                    let expected = st.expected_segments(samples);
                    (st.segments as f64 / expected as f64).min(0.999)
                }
                None => (frames_in as f64 / total as f64).min(1.0),
            });
        }
        Ok(())
    };
    let (source, t_dec) = decode_through(source, req.config.parallel, &mut consume)?;
    t_decode += t_dec;
    engine.finish();
    if let Some(e) = engine.take_separator_error() {
        return Err(e);
    }
    progress(1.0);

    let n = engine.samples_in();
    end_warnings(
        req,
        &source,
        frames_in,
        info.sample_rate,
        &supplied,
        n,
        &mut warnings,
    );

    let duration_s = n as f64 / rate as f64;
    let frames = engine.frames();
    for (k, f) in frames.iter().enumerate().skip(delivered) {
        if !on_frame(k, *f) {
            return Err(EngineError::Cancelled);
        }
    }
    let source = SourceInfo {
        path: req.input.display().to_string(),
        sha256: tactus_glove::sha256_file(&req.input)
            .map_err(|e| EngineError::Io(req.input.clone(), e))?,
        duration_s,
        sample_rate: info.sample_rate,
    };
    Ok(RenderOutput::from_engine(
        &engine,
        source,
        frames,
        &[("decode", t_decode), ("resample", t_resample)],
        t_all,
        warnings,
    ))
}

fn feed(engine: &mut Engine, l: &[f32], r: &[f32], supplied: &mut [SuppliedStem]) {
    for s in supplied.iter_mut() {
        s.next(l.len());
    }
    let views: Vec<(Stem, &[f32])> = supplied
        .iter()
        .map(|s| (s.stem, s.buf.as_slice()))
        .collect();
    engine.process(l, r, &views);
}

/// Decodes `source` block by block and hands each block to `consume`: on a reader thread a
/// few blocks ahead when `parallel`, otherwise on the calling thread. Returns the source
/// (for its warnings) and the time spent decoding.
fn decode_through(
    source: AudioSource,
    parallel: bool,
    consume: &mut dyn FnMut(&DecodedBlock) -> Result<(), EngineError>,
) -> Result<(AudioSource, Duration), EngineError> {
    Ok(if parallel {
        // Decoding runs on its own thread, a few blocks ahead (a bounded channel), so that
        // it overlaps the separator and the stem chains; blocks go back to it for reuse.
        let (block_tx, block_rx) =
            mpsc::sync_channel::<Result<DecodedBlock, EngineError>>(DECODE_AHEAD);
        let (spare_tx, spare_rx) = mpsc::channel::<DecodedBlock>();
        std::thread::scope(|scope| -> Result<_, EngineError> {
            let reader = scope.spawn(move || decode_blocks(source, &block_tx, &spare_rx));
            let mut result = Ok(());
            for block in block_rx.iter() {
                let r = block.and_then(|b| {
                    let r = consume(&b);
                    // The reader may be gone after the last block; the buffer is simply
                    // dropped then.
                    let _ = spare_tx.send(b);
                    r
                });
                if let Err(e) = r {
                    result = Err(e);
                    break;
                }
            }
            // Dropping the receiver stops a reader that is still decoding (after an error).
            drop(block_rx);
            let joined = reader
                .join()
                .map_err(|_| EngineError::Panicked("decoding"))?;
            result.map(|()| joined)
        })?
    } else {
        // One thread (EngineConfig::parallel off): decode a block, then process it.
        let mut source = source;
        let mut block = new_block();
        let mut spent = Duration::ZERO;
        loop {
            let t = Instant::now();
            decode_block(&mut source, &mut block)?;
            spent += t.elapsed();
            consume(&block)?;
            if block.last {
                break;
            }
        }
        (source, spent)
    })
}

/// The warnings a finished render adds: non-finite samples, a truncated file, and each
/// supplied stem whose length differs from the mix's `n` samples by more than 10 ms.
fn end_warnings(
    req: &RenderRequest,
    source: &AudioSource,
    frames_in: u64,
    file_rate: u32,
    supplied: &[SuppliedStem],
    n: usize,
    warnings: &mut Vec<String>,
) {
    let rate = req.config.sample_rate;
    if source.non_finite() > 0 {
        warnings.push(format!(
            "{}: {} NaN/Inf samples replaced by 0",
            req.input.display(),
            source.non_finite()
        ));
    }
    if source.truncated() {
        warnings.push(format!(
            "{}: the file ends early; rendered the {:.2} s that could be decoded",
            req.input.display(),
            frames_in as f64 / file_rate.max(1) as f64
        ));
    }
    for s in supplied {
        let diff = s.samples.len() as i64 - n as i64;
        if diff.unsigned_abs() as usize > rate as usize / 100 {
            warnings.push(format!(
                "stem {}: {:.3} s {} than the mix; {}",
                s.stem.name(),
                diff.unsigned_abs() as f64 / rate as f64,
                if diff > 0 { "longer" } else { "shorter" },
                if diff > 0 {
                    "trimmed"
                } else {
                    "padded with silence"
                }
            ));
        }
    }
}
