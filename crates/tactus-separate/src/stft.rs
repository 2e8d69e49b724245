//! Streaming short-time Fourier transform and its inverse by weighted overlap-add.
//!
//! **Analysis** ([`StftAnalysis`]): frame `i` covers input samples
//! `[i·hop − n_fft/2, i·hop + n_fft/2)` (librosa's `center=True`, the same convention as
//! `tactus_dsp::framer::Framer`: `n_fft/2` zeros precede the input). Each frame is
//! multiplied by a periodic Hann window `w[n] = ½ − ½·cos(2πn/n_fft)` and transformed
//! with `realfft` (unnormalised, `n_fft/2 + 1` bins). A stream of `n` samples has
//! `n.div_ceil(hop)` frames; [`StftAnalysis::finish`] emits the last ones with zeros after
//! the input. Non-finite input samples become 0 (`tactus_dsp::sanitize`).
//!
//! **Synthesis** ([`OverlapAdd`]): each frame is inverse-transformed (scaled by `1/n_fft`),
//! multiplied by the same window and added into an accumulator; the accumulator is divided
//! by the running sum of the squared windows that touched each sample (Griffin & Lim 1984,
//! "window-sum normalisation"). Analysis → synthesis of unmodified frames is therefore an
//! exact reconstruction (to float round-off) for every sample, edges included, for any
//! `hop <= n_fft / 2` (a periodic Hann window is non-zero everywhere but at its first
//! sample, which is always covered by the previous frame's centre). With `hop = n_fft/2`
//! the last samples of a stream are covered only by the tail of the last window, so they
//! are divided by a tiny window sum: exact for unmodified frames, but it amplifies changes
//! made to the spectra. Use `hop <= n_fft/4` (the defaults) when masking.
//!
//! **Latency**: output sample `j` is final once the last frame that covers it has been
//! added, i.e. after input sample `j + n_fft − 1` (at most) has arrived; frames that are
//! held back for look-ahead add `hop` each. Both halves allocate only at construction.
//!
//! Typical shapes: `n_fft 2048, hop 512` (spectral separator), `n_fft 4096, hop 1024`
//! (Demucs, Spleeter).

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use tactus_dsp::sanitize::sanitize_sample;
use tactus_dsp::ConfigError;

/// Frame length and hop of an STFT.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StftConfig {
    /// Frame (FFT) length in samples; even, at least 4.
    pub n_fft: usize,
    /// Samples between frame centres; `1..=n_fft/2`.
    pub hop: usize,
}

impl StftConfig {
    /// Checks the shape.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.n_fft < 4 || self.n_fft & 1 == 1 {
            return Err(ConfigError::invalid(
                "n_fft",
                format!("{} must be even and at least 4", self.n_fft),
            ));
        }
        if self.hop == 0 || self.hop > self.n_fft / 2 {
            return Err(ConfigError::invalid(
                "hop",
                format!("{} must be in 1..={} (n_fft / 2)", self.hop, self.n_fft / 2),
            ));
        }
        Ok(())
    }

    /// Number of frequency bins, `n_fft / 2 + 1`.
    pub fn bins(&self) -> usize {
        self.n_fft / 2 + 1
    }

    /// Number of frames of a stream of `n` samples.
    pub fn frames(&self, n: usize) -> usize {
        n.div_ceil(self.hop)
    }
}

/// `spec` = the real FFT of `src · window` (through `frame` and `scratch`, all sized for
/// `fft` at construction, so it cannot fail; were it to, `spec` is zeroed).
pub(crate) fn windowed_fft(
    fft: &dyn RealToComplex<f32>,
    window: &[f32],
    src: &[f32],
    frame: &mut [f32],
    spec: &mut [Complex<f32>],
    scratch: &mut [Complex<f32>],
) {
    for ((f, &x), &w) in frame.iter_mut().zip(src).zip(window) {
        *f = x * w;
    }
    if fft.process_with_scratch(frame, spec, scratch).is_err() {
        spec.fill(Complex::new(0.0, 0.0));
    }
}

/// The periodic Hann window of length `n`.
pub fn hann_periodic(n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let x = std::f64::consts::TAU * i as f64 / n as f64;
            (0.5 - 0.5 * x.cos()) as f32
        })
        .collect()
}

/// Streaming multi-channel STFT analysis. See the module docs.
pub struct StftAnalysis {
    cfg: StftConfig,
    window: Vec<f32>,
    fft: Arc<dyn RealToComplex<f32>>,
    /// One sliding buffer of `n_fft` samples per channel.
    bufs: Vec<Vec<f32>>,
    /// Samples currently held in each buffer (the same for every channel).
    fill: usize,
    frame: Vec<f32>,
    scratch: Vec<Complex<f32>>,
    spectra: Vec<Vec<Complex<f32>>>,
    frames_emitted: usize,
    samples_seen: usize,
}

impl StftAnalysis {
    /// An analysis of `channels` lock-stepped channels.
    pub fn new(cfg: StftConfig, channels: usize) -> Result<Self, ConfigError> {
        cfg.validate()?;
        if channels == 0 {
            return Err(ConfigError::invalid("channels", "must be at least 1"));
        }
        let fft = RealFftPlanner::<f32>::new().plan_fft_forward(cfg.n_fft);
        let mut a = StftAnalysis {
            cfg,
            window: hann_periodic(cfg.n_fft),
            scratch: fft.make_scratch_vec(),
            fft,
            bufs: vec![vec![0.0; cfg.n_fft]; channels],
            fill: 0,
            frame: vec![0.0; cfg.n_fft],
            spectra: vec![vec![Complex::new(0.0, 0.0); cfg.bins()]; channels],
            frames_emitted: 0,
            samples_seen: 0,
        };
        a.reset();
        Ok(a)
    }

    /// The STFT shape.
    pub fn config(&self) -> StftConfig {
        self.cfg
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.bufs.len()
    }

    /// Frames emitted so far.
    pub fn frames_emitted(&self) -> usize {
        self.frames_emitted
    }

    /// Input samples (per channel) accepted so far.
    pub fn samples_seen(&self) -> usize {
        self.samples_seen
    }

    /// Back to the just-constructed state (the `n_fft / 2` leading zeros in place).
    pub fn reset(&mut self) {
        for b in &mut self.bufs {
            b.fill(0.0);
        }
        self.fill = self.cfg.n_fft / 2;
        self.frames_emitted = 0;
        self.samples_seen = 0;
    }

    /// Feeds one block per channel; calls `emit(frame_index, spectra)` (one spectrum of
    /// `n_fft/2 + 1` bins per channel) for every frame the block completes.
    ///
    /// Uses the common prefix of the slices; a channel missing from `input` reads as
    /// silence, extra slices are ignored. Never allocates.
    pub fn push<F: FnMut(usize, &[Vec<Complex<f32>>])>(&mut self, input: &[&[f32]], mut emit: F) {
        let n = input.iter().map(|c| c.len()).min().unwrap_or(0);
        self.samples_seen += n;
        self.feed(input, 0, n, true, &mut emit);
    }

    /// Ends the stream: emits the remaining frames (`n.div_ceil(hop)` in all) as if zeros
    /// followed the input. Call [`StftAnalysis::reset`] before feeding a new stream.
    pub fn finish<F: FnMut(usize, &[Vec<Complex<f32>>])>(&mut self, mut emit: F) {
        let total = self.cfg.frames(self.samples_seen);
        while self.frames_emitted < total {
            // Zero-fill up to the next frame boundary.
            let need = self.cfg.n_fft - self.fill;
            self.feed(&[], 0, need, false, &mut emit);
        }
    }

    fn feed<F: FnMut(usize, &[Vec<Complex<f32>>])>(
        &mut self,
        input: &[&[f32]],
        mut pos: usize,
        end: usize,
        real: bool,
        emit: &mut F,
    ) {
        let n_fft = self.cfg.n_fft;
        while pos < end {
            let take = (n_fft - self.fill).min(end - pos);
            for (ch, buf) in self.bufs.iter_mut().enumerate() {
                let dst = &mut buf[self.fill..self.fill + take];
                match input.get(ch) {
                    Some(src) if real => {
                        for (d, &x) in dst.iter_mut().zip(&src[pos..pos + take]) {
                            *d = sanitize_sample(x).0;
                        }
                    }
                    _ => dst.fill(0.0),
                }
            }
            self.fill += take;
            pos += take;
            if self.fill == n_fft {
                for (buf, spec) in self.bufs.iter().zip(self.spectra.iter_mut()) {
                    let (frame, scratch) = (&mut self.frame, &mut self.scratch);
                    windowed_fft(&*self.fft, &self.window, buf, frame, spec, scratch);
                }
                emit(self.frames_emitted, &self.spectra);
                self.frames_emitted += 1;
                let hop = self.cfg.hop;
                for buf in &mut self.bufs {
                    buf.copy_within(hop.., 0);
                }
                self.fill -= hop;
            }
        }
    }
}

/// Streaming multi-channel inverse STFT by weighted overlap-add with window-sum
/// normalisation. All channels share the frame clock. See the module docs.
pub struct OverlapAdd {
    cfg: StftConfig,
    window: Vec<f32>,
    ifft: Arc<dyn ComplexToReal<f32>>,
    scratch: Vec<Complex<f32>>,
    time: Vec<f32>,
    /// Per channel: accumulator; `acc[c][0]` is padded-stream position `frames * hop`.
    acc: Vec<Vec<f32>>,
    /// Sum of squared windows per position (shared by the channels).
    wsum: Vec<f32>,
    /// Normalised output of one hop.
    norm: Vec<f32>,
    frames: usize,
    emitted: usize,
    /// No more than this many samples per channel are ever emitted (see
    /// [`OverlapAdd::limit_output`]).
    limit: usize,
}

impl OverlapAdd {
    /// A synthesis of `channels` signals.
    pub fn new(cfg: StftConfig, channels: usize) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let ifft = RealFftPlanner::<f32>::new().plan_fft_inverse(cfg.n_fft);
        Ok(OverlapAdd {
            cfg,
            window: hann_periodic(cfg.n_fft),
            scratch: ifft.make_scratch_vec(),
            ifft,
            time: vec![0.0; cfg.n_fft],
            acc: vec![vec![0.0; cfg.n_fft]; channels],
            wsum: vec![0.0; cfg.n_fft],
            norm: vec![0.0; cfg.n_fft],
            frames: 0,
            emitted: 0,
            limit: usize::MAX,
        })
    }

    /// Number of output channels.
    pub fn channels(&self) -> usize {
        self.acc.len()
    }

    /// Frames completed so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Output samples (per channel) emitted so far.
    pub fn samples_emitted(&self) -> usize {
        self.emitted
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        for a in &mut self.acc {
            a.fill(0.0);
        }
        self.wsum.fill(0.0);
        self.frames = 0;
        self.emitted = 0;
        self.limit = usize::MAX;
    }

    /// From now on, emit at most `total` samples per channel in all: a caller that pads
    /// the input past its real end (to give the last frames signal instead of zeros) keeps
    /// the padding's own output from ever leaving.
    pub fn limit_output(&mut self, total: usize) {
        self.limit = total;
    }

    /// Adds the spectrum (`n_fft/2 + 1` bins) of the current frame to `channel`. The
    /// spectrum is used as scratch and is garbage afterwards. A channel that is not added
    /// to in a frame contributes silence. Out-of-range channels and wrongly sized spectra
    /// are ignored.
    pub fn add(&mut self, channel: usize, spectrum: &mut [Complex<f32>]) {
        let Some(acc) = self.acc.get_mut(channel) else {
            return;
        };
        if spectrum.len() != self.cfg.bins() {
            return;
        }
        // A real signal has real DC and Nyquist bins.
        spectrum[0].im = 0.0;
        spectrum[self.cfg.n_fft / 2].im = 0.0;
        if self
            .ifft
            .process_with_scratch(spectrum, &mut self.time, &mut self.scratch)
            .is_err()
        {
            return;
        }
        let scale = 1.0 / self.cfg.n_fft as f32;
        for ((a, &t), &w) in acc.iter_mut().zip(&self.time).zip(&self.window) {
            *a += t * w * scale;
        }
    }

    /// Completes the current frame and calls `emit(channel, samples)` for each channel with
    /// the output samples that are now final (`hop` of them, fewer at the start).
    pub fn advance<F: FnMut(usize, &[f32])>(&mut self, mut emit: F) {
        let hop = self.cfg.hop;
        for (s, &w) in self.wsum.iter_mut().zip(&self.window) {
            *s += w * w;
        }
        // Padded positions [frames*hop, frames*hop + hop) are final; the first n_fft/2
        // padded positions are the leading pad and are dropped.
        let start = self.frames * hop;
        let skip = (self.cfg.n_fft / 2).saturating_sub(start).min(hop);
        self.frames += 1;
        // Positions past the limit (a caller's padding after the end) are never emitted.
        let end = hop.min(skip.saturating_add(self.limit.saturating_sub(self.emitted)));
        for (ch, acc) in self.acc.iter_mut().enumerate() {
            if skip < end {
                normalise(
                    &acc[skip..end],
                    &self.wsum[skip..end],
                    &mut self.norm[..end - skip],
                );
                emit(ch, &self.norm[..end - skip]);
            }
            acc.copy_within(hop.., 0);
            let n = acc.len();
            acc[n - hop..].fill(0.0);
        }
        self.emitted += end.saturating_sub(skip);
        self.wsum.copy_within(hop.., 0);
        let n = self.wsum.len();
        self.wsum[n - hop..].fill(0.0);
    }

    /// Ends the stream of `total_input` samples (whose `total_input.div_ceil(hop)` frames
    /// must all have been advanced): emits the remaining samples so that exactly
    /// `total_input` samples per channel were emitted in all. Call [`OverlapAdd::reset`]
    /// before a new stream.
    pub fn finish<F: FnMut(usize, &[f32])>(&mut self, total_input: usize, mut emit: F) {
        let pos0 = self.frames * self.cfg.hop;
        let skip = (self.cfg.n_fft / 2).saturating_sub(pos0);
        let remaining = total_input.saturating_sub(self.emitted);
        let end = (skip + remaining).min(self.cfg.n_fft);
        if skip >= end {
            return;
        }
        for (ch, acc) in self.acc.iter_mut().enumerate() {
            normalise(
                &acc[skip..end],
                &self.wsum[skip..end],
                &mut self.norm[..end - skip],
            );
            emit(ch, &self.norm[..end - skip]);
            acc.fill(0.0);
        }
        self.emitted += end - skip;
        self.wsum.fill(0.0);
    }
}

fn normalise(acc: &[f32], wsum: &[f32], out: &mut [f32]) {
    for ((o, &a), &w) in out.iter_mut().zip(acc).zip(wsum) {
        *o = if w > 1e-30 { a / w } else { 0.0 };
    }
}
