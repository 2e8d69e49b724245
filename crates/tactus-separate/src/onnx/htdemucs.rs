//! Demucs v4 (`htdemucs`, Rouard, Massa & Défossez, "Hybrid Transformers for Music Source
//! Separation", ICASSP 2023; MIT code and weights) with the STFT and iSTFT done here.
//!
//! The network is exported by `models/export_htdemucs.py` (see `models/README.md`) with
//! this contract, at 44.1 kHz, for one segment of `SEGMENT_SAMPLES` = 343 980 samples
//! (7.8 s, htdemucs's training length):
//!
//! | tensor | shape | meaning |
//! |---|---|---|
//! | input `mix` | `[1, 2, 343980]` | the stereo segment |
//! | input `mag` | `[1, 4, 2048, 336]` | its spectrogram, channels `[L.re, L.im, R.re, R.im]` |
//! | output `freq` | `[1, 4, 4, 2048, 336]` | per source, the frequency branch's spectrogram |
//! | output `time` | `[1, 4, 2, 343980]` | per source, the time branch's waveform |
//!
//! Sources in order: drums, bass, other, vocals. Each stem is `iSTFT(freq) + time`.
//!
//! **Demucs's spectrogram** (`HTDemucs._spec` / `_ispec`, `demucs/spec.py`), replicated:
//! the segment is reflect-padded by 1536 samples before and `1536 + 336·1024 − 343980`
//! after; frame `j` (0..336) is the 4096 samples starting at padded index `j·1024`
//! (input samples `[j·1024 − 1536, j·1024 + 2560)`), times a periodic Hann window, FFT,
//! scaled by `1/√4096` (`normalized=True`), bins 0..2048 (the Nyquist bin is dropped).
//! The inverse adds a zero Nyquist bin, inverse-FFTs each frame, scales by `√4096 / 4096`,
//! windows, overlap-adds at the same positions and divides by the Hann² envelope (3/2 to
//! float precision everywhere in the segment: every sample is covered by four frames,
//! the two zero frames Demucs adds at each end included).
//!
//! **Segments** as Demucs's `apply_model(split=True, overlap=0.25, transition_power=1)`:
//! segments start every `STRIDE_SAMPLES` = 257 985 samples (75 % of a segment) and their
//! outputs are blended with triangular weights `1, 2, …, L/2, L/2, …, 1` (normalised by
//! the sum of the weights of the segments that cover a sample). Deviation: the last,
//! shorter segment is zero-padded after the end of the stream, whereas Demucs centres it
//! in real context; Demucs's whole-file normalisation (`(mix − mean) / std` over the
//! file) is not applied either — a stream has no "whole file"; the network normalises
//! each segment internally anyway.
//!
//! **Output**: mono `(L + R) / 2` per requested stem; the iSTFT is done on the mono
//! spectrum `(Z_L + Z_R) / 2` (it is linear) and only for requested stems.
//!
//! **Latency**: a segment runs when its last sample has arrived; then the first
//! `STRIDE_SAMPLES` of it are final: `SEGMENT_SAMPLES − 1` = 343 979 samples (7.8 s).
//! Only 44.1 kHz is accepted. A failed network call (it should not happen) yields silence
//! for that segment and is reported by [`Separator::take_error`] (and
//! [`HtDemucsSeparator::last_error`]), which fails a render.

use std::sync::Arc;
use std::time::Instant;

use ort::session::Session;
use ort::value::TensorRef;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use tactus_dsp::sanitize::sanitize_sample;

use super::{open_session, OnnxConfig, OnnxError, Port};
use crate::stft::{hann_periodic, windowed_fft};
use crate::{stem_index, SegmentStats, SeparateError, Separator, Stem, StemOutput, StemSet};

/// The only sample rate the model accepts, in Hz.
pub const SAMPLE_RATE: u32 = 44_100;
/// Samples per segment (7.8 s at 44.1 kHz).
pub const SEGMENT_SAMPLES: usize = 343_980;
/// Samples between segment starts (Demucs's 25 % overlap).
pub const STRIDE_SAMPLES: usize = SEGMENT_SAMPLES * 3 / 4;
/// STFT frame length and hop.
pub const N_FFT: usize = 4096;
/// STFT hop.
pub const HOP: usize = 1024;
/// Bins per frame in the graph (the Nyquist bin is dropped).
pub const BINS: usize = N_FFT / 2;
/// Frames per segment, `ceil(SEGMENT_SAMPLES / HOP)`.
pub const FRAMES: usize = SEGMENT_SAMPLES.div_ceil(HOP);
/// Demucs's extra reflect padding, `HOP / 2 · 3`.
const PAD: usize = HOP / 2 * 3;
/// Complex values per one-sided spectrum (`BINS` + the Nyquist bin).
const SPEC_LEN: usize = N_FFT / 2 + 1;
/// Frames transposed together between our frame-major spectra and the graph's
/// bin-major tensors (16 floats = one 64-byte cache line; divides `FRAMES` = 336).
const BLOCK_FRAMES: usize = 16;
/// The network's sources, in output order.
pub const SOURCES: [Stem; 4] = [Stem::Drums, Stem::Bass, Stem::Other, Stem::Vocals];
const INPUT_LIMIT: f32 = 1e9;

const INPUTS: [Port; 2] = [
    Port {
        name: "mix",
        shape: &[Some(1), Some(2), Some(SEGMENT_SAMPLES as i64)],
    },
    Port {
        name: "mag",
        shape: &[Some(1), Some(4), Some(BINS as i64), Some(FRAMES as i64)],
    },
];
const OUTPUTS: [Port; 2] = [
    Port {
        name: "freq",
        shape: &[
            Some(1),
            Some(4),
            Some(4),
            Some(BINS as i64),
            Some(FRAMES as i64),
        ],
    },
    Port {
        name: "time",
        shape: &[Some(1), Some(4), Some(2), Some(SEGMENT_SAMPLES as i64)],
    },
];

/// The htdemucs separator. See the module docs.
pub struct HtDemucsSeparator {
    stems: StemSet,
    session: Session,
    fft: Arc<dyn RealToComplex<f32>>,
    ifft: Arc<dyn ComplexToReal<f32>>,
    window: Vec<f32>,
    /// Hann² envelope (sum of the squared windows of the frames covering a sample), by
    /// the sample's position within the hop.
    envelope: Vec<f32>,
    /// Transition weights of one segment.
    weight: Vec<f32>,
    /// Planar stereo input of the current segment: `[L; SEGMENT], [R; SEGMENT]`.
    input: Vec<f32>,
    /// Samples of the current segment present in `input`.
    fill: usize,
    /// Stream index of `input[0]`.
    start: usize,
    /// Samples accepted so far.
    seen: usize,
    /// Graph input `mag`.
    mag: Vec<f32>,
    padded: Vec<f32>,
    frame: Vec<f32>,
    /// Spectra of `BLOCK_FRAMES` consecutive frames (`BINS + 1` each): the graph's
    /// layout is bin-major, so spectra go in and out a block of frames at a time (one
    /// cache line per bin and plane instead of one per value).
    block: Vec<Complex<f32>>,
    scratch_fwd: Vec<Complex<f32>>,
    scratch_inv: Vec<Complex<f32>>,
    /// Per requested stem (indexed by `stem_index`): weighted output accumulator over
    /// the current segment's span; empty when not requested.
    acc: [Vec<f32>; 4],
    /// Sum of weights over the current segment's span.
    wsum: Vec<f32>,
    /// One segment of one stem's mono output.
    stem_out: Vec<f32>,
    /// Final samples being delivered.
    ready: Vec<f32>,
    last_error: Option<String>,
    stats: SegmentStats,
}

impl HtDemucsSeparator {
    /// An htdemucs separator at `sample_rate` (must be 44 100 Hz) that outputs `stems`,
    /// with the model and runtime named in `cfg`.
    pub fn new(sample_rate: u32, stems: StemSet, cfg: &OnnxConfig) -> Result<Self, OnnxError> {
        if sample_rate != SAMPLE_RATE {
            return Err(SeparateError::SampleRate(sample_rate).into());
        }
        if stems.is_empty() {
            return Err(SeparateError::NoStems.into());
        }
        let session = open_session(cfg, "htdemucs", &INPUTS, &OUTPUTS)?;
        let mut planner = RealFftPlanner::<f32>::new();
        let fft = planner.plan_fft_forward(N_FFT);
        let ifft = planner.plan_fft_inverse(N_FFT);
        let window = hann_periodic(N_FFT);
        // Envelope: for a sample at padded-istft position p, the sum of w² over the
        // frames covering it; with hop N/4 it depends only on p mod HOP.
        let envelope: Vec<f32> = (0..HOP)
            .map(|r| (0..N_FFT / HOP).map(|q| window[r + q * HOP].powi(2)).sum())
            .collect();
        let half = SEGMENT_SAMPLES / 2;
        let weight: Vec<f32> = (1..=half)
            .chain((1..=SEGMENT_SAMPLES - half).rev())
            .map(|w| w as f32 / half.max(SEGMENT_SAMPLES - half) as f32)
            .collect();
        let per_stem = |s: Stem| {
            if stems.contains(s) {
                vec![0.0; SEGMENT_SAMPLES]
            } else {
                Vec::new()
            }
        };
        Ok(HtDemucsSeparator {
            stems,
            session,
            scratch_fwd: fft.make_scratch_vec(),
            scratch_inv: ifft.make_scratch_vec(),
            fft,
            ifft,
            window,
            envelope,
            weight,
            input: vec![0.0; 2 * SEGMENT_SAMPLES],
            fill: 0,
            start: 0,
            seen: 0,
            mag: vec![0.0; 4 * BINS * FRAMES],
            padded: vec![0.0; FRAMES * HOP + 2 * PAD],
            frame: vec![0.0; N_FFT],
            block: vec![Complex::new(0.0, 0.0); BLOCK_FRAMES * SPEC_LEN],
            acc: [
                per_stem(Stem::Drums),
                per_stem(Stem::Bass),
                per_stem(Stem::Vocals),
                per_stem(Stem::Other),
            ],
            wsum: vec![0.0; SEGMENT_SAMPLES],
            stem_out: vec![0.0; SEGMENT_SAMPLES],
            ready: vec![0.0; SEGMENT_SAMPLES],
            last_error: None,
            stats: SegmentStats::new(STRIDE_SAMPLES),
        })
    }

    /// The message of the last failed network call, if any (see the module docs).
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// Separates one segment on its own, as Demucs's `model(mix)` does for a mix of at
    /// most one segment: the input (its first `SEGMENT_SAMPLES` samples at most) is
    /// zero-padded to a segment, run once, and the first `n` samples of each requested
    /// stem (mono) are appended to `out`. No blending. This resets the streaming state
    /// (before and after).
    pub fn separate_segment(&mut self, left: &[f32], right: &[f32], out: &mut StemOutput) {
        self.reset();
        out.declare(self.stems);
        let n = left.len().min(right.len()).min(SEGMENT_SAMPLES);
        for (c, src) in [left, right].into_iter().enumerate() {
            let dst = &mut self.input[c * SEGMENT_SAMPLES..][..n];
            for (d, &x) in dst.iter_mut().zip(&src[..n]) {
                *d = sanitize_sample(x).0.clamp(-INPUT_LIMIT, INPUT_LIMIT);
            }
        }
        self.fill = n;
        if n > 0 {
            // Weighted and then divided by the same weights: the plain network output.
            self.run_segment(n);
            self.deliver(n, n, out);
        }
        self.reset();
    }

    /// Demucs's `_spec` of the current segment into `mag` (see the module docs).
    fn analyse(&mut self) {
        let plane = BINS * FRAMES;
        let n = SEGMENT_SAMPLES as isize;
        let scale = 1.0 / (N_FFT as f32).sqrt();
        for c in 0..2 {
            let x = &self.input[c * SEGMENT_SAMPLES..(c + 1) * SEGMENT_SAMPLES];
            for (i, p) in self.padded.iter_mut().enumerate() {
                // Reflect padding (edge sample not repeated), as torch's "reflect".
                let mut j = i as isize - PAD as isize;
                if j < 0 {
                    j = -j;
                }
                if j >= n {
                    j = 2 * (n - 1) - j;
                }
                *p = x[j.clamp(0, n - 1) as usize];
            }
            for t0 in (0..FRAMES).step_by(BLOCK_FRAMES) {
                let nb = BLOCK_FRAMES.min(FRAMES - t0);
                for (j, spec) in self.block.chunks_exact_mut(SPEC_LEN).take(nb).enumerate() {
                    let src = &self.padded[(t0 + j) * HOP..(t0 + j) * HOP + N_FFT];
                    let (frame, scratch) = (&mut self.frame, &mut self.scratch_fwd);
                    windowed_fft(&*self.fft, &self.window, src, frame, spec, scratch);
                }
                let (re_plane, im_plane) =
                    self.mag[2 * c * plane..(2 * c + 2) * plane].split_at_mut(plane);
                for k in 0..BINS {
                    let re = &mut re_plane[k * FRAMES + t0..][..nb];
                    let im = &mut im_plane[k * FRAMES + t0..][..nb];
                    for (j, (r, i)) in re.iter_mut().zip(im).enumerate() {
                        let z = self.block[j * SPEC_LEN + k];
                        *r = z.re * scale;
                        *i = z.im * scale;
                    }
                }
            }
        }
    }

    /// Runs the network on the current segment and adds the weighted mono stems of its
    /// first `len` samples into the accumulators.
    fn run_segment(&mut self, len: usize) {
        self.analyse();
        let result = (|| -> Result<(), String> {
            let mix = TensorRef::from_array_view(([1usize, 2, SEGMENT_SAMPLES], &self.input[..]))
                .map_err(|e| e.to_string())?;
            let mag = TensorRef::from_array_view(([1usize, 4, BINS, FRAMES], &self.mag[..]))
                .map_err(|e| e.to_string())?;
            let t_net = Instant::now();
            let outputs = self.session.run(ort::inputs!["mix" => mix, "mag" => mag]);
            self.stats.record_network(t_net.elapsed());
            let outputs = outputs.map_err(|e| e.to_string())?;
            let get = |name: &str, len: usize| -> Result<&[f32], String> {
                let v = outputs
                    .get(name)
                    .ok_or_else(|| format!("no output `{name}`"))?;
                let (_, data) = v.try_extract_tensor::<f32>().map_err(|e| e.to_string())?;
                if data.len() != len {
                    return Err(format!("output `{name}` has {} values", data.len()));
                }
                Ok(data)
            };
            let freq = get("freq", 4 * 4 * BINS * FRAMES)?;
            let time = get("time", 4 * 2 * SEGMENT_SAMPLES)?;
            for (s_idx, &stem) in SOURCES.iter().enumerate() {
                if !self.stems.contains(stem) {
                    continue;
                }
                let f = &freq[s_idx * 4 * BINS * FRAMES..(s_idx + 1) * 4 * BINS * FRAMES];
                let t = &time[s_idx * 2 * SEGMENT_SAMPLES..(s_idx + 1) * 2 * SEGMENT_SAMPLES];
                synthesise_mono(
                    f,
                    t,
                    &*self.ifft,
                    &self.window,
                    &self.envelope,
                    &mut self.block,
                    &mut self.frame,
                    &mut self.scratch_inv,
                    &mut self.stem_out,
                );
                self.stats.inverse_ffts += FRAMES as u64;
                let acc = &mut self.acc[stem_index(stem)];
                for ((a, &y), &w) in acc[..len].iter_mut().zip(&self.stem_out).zip(&self.weight) {
                    *a += if y.is_finite() { w * y } else { 0.0 };
                }
            }
            Ok(())
        })();
        if let Err(e) = result {
            // The first failure is the one to report (see `Separator::take_error`).
            if self.last_error.is_none() {
                self.last_error = Some(format!("network call {}: {e}", self.stats.segments));
            }
        }
        for (s, &w) in self.wsum[..len].iter_mut().zip(&self.weight) {
            *s += w;
        }
    }

    /// Delivers the first `n` accumulated samples (final) and shifts the accumulators
    /// and the input by `shift` samples.
    fn deliver(&mut self, n: usize, shift: usize, out: &mut StemOutput) {
        for stem in self.stems.iter() {
            let acc = &mut self.acc[stem_index(stem)];
            for ((r, &a), &w) in self.ready[..n].iter_mut().zip(&acc[..n]).zip(&self.wsum) {
                *r = if w > 0.0 { a / w } else { 0.0 };
            }
            out.extend(stem, &self.ready[..n]);
            acc.copy_within(shift.., 0);
            acc[SEGMENT_SAMPLES - shift..].fill(0.0);
        }
        self.wsum.copy_within(shift.., 0);
        self.wsum[SEGMENT_SAMPLES - shift..].fill(0.0);
        for c in 0..2 {
            let ch = &mut self.input[c * SEGMENT_SAMPLES..(c + 1) * SEGMENT_SAMPLES];
            ch.copy_within(shift.., 0);
        }
        self.fill = self.fill.saturating_sub(shift);
        self.start += shift;
    }
}

/// `iSTFT((Z_L + Z_R) / 2) + (t_L + t_R) / 2` of one source (see the module docs).
#[allow(clippy::too_many_arguments)]
fn synthesise_mono(
    freq: &[f32],
    time: &[f32],
    ifft: &dyn ComplexToReal<f32>,
    window: &[f32],
    envelope: &[f32],
    block: &mut [Complex<f32>],
    frame: &mut [f32],
    scratch: &mut [Complex<f32>],
    out: &mut [f32],
) {
    let plane = BINS * FRAMES;
    out.fill(0.0);
    // torch.istft(normalized=True): irfft (1/N) times √N.
    let scale = 1.0 / (N_FFT as f32).sqrt();
    for t0 in (0..FRAMES).step_by(BLOCK_FRAMES) {
        let nb = BLOCK_FRAMES.min(FRAMES - t0);
        // Transpose a block of frames out of the bin-major planes, averaging L and R.
        for k in 0..BINS {
            let at = k * FRAMES + t0;
            let (lr, li) = (&freq[at..at + nb], &freq[plane + at..plane + at + nb]);
            let (rr, ri) = (
                &freq[2 * plane + at..2 * plane + at + nb],
                &freq[3 * plane + at..3 * plane + at + nb],
            );
            for j in 0..nb {
                block[j * SPEC_LEN + k] =
                    Complex::new(0.5 * (lr[j] + rr[j]), 0.5 * (li[j] + ri[j]));
            }
        }
        for (j, spectrum) in block.chunks_exact_mut(SPEC_LEN).take(nb).enumerate() {
            spectrum[0].im = 0.0;
            spectrum[BINS] = Complex::new(0.0, 0.0);
            if ifft.process_with_scratch(spectrum, frame, scratch).is_err() {
                continue;
            }
            // Frame t covers segment samples [t·HOP − PAD, t·HOP − PAD + N_FFT).
            let first = (t0 + j) * HOP;
            let lo = PAD.saturating_sub(first);
            let hi = (SEGMENT_SAMPLES + PAD - first).min(N_FFT);
            if lo >= hi {
                continue;
            }
            let dst = &mut out[first + lo - PAD..first + hi - PAD];
            for ((o, &y), &w) in dst.iter_mut().zip(&frame[lo..hi]).zip(&window[lo..hi]) {
                *o += y * w * scale;
            }
        }
    }
    // Divide by the Hann² envelope; output sample i sits at istft position i + 3584
    // (2048 centre pad + 1536), i.e. at (i + 512) mod HOP within the hop.
    let shift = (N_FFT / 2 + PAD) % HOP;
    for (i, (o, (&l, &r))) in out
        .iter_mut()
        .zip(time[..SEGMENT_SAMPLES].iter().zip(&time[SEGMENT_SAMPLES..]))
        .enumerate()
    {
        *o = *o / envelope[(i + shift) % HOP] + 0.5 * (l + r);
    }
}

impl Separator for HtDemucsSeparator {
    fn name(&self) -> &'static str {
        "htdemucs"
    }

    fn sample_rate(&self) -> u32 {
        SAMPLE_RATE
    }

    fn stems(&self) -> StemSet {
        self.stems
    }

    fn process(&mut self, left: &[f32], right: &[f32], out: &mut StemOutput) {
        let t_busy = Instant::now();
        out.declare(self.stems);
        let n = left.len().min(right.len());
        let mut pos = 0;
        while pos < n {
            let take = (SEGMENT_SAMPLES - self.fill).min(n - pos);
            for (c, src) in [left, right].into_iter().enumerate() {
                let dst = &mut self.input[c * SEGMENT_SAMPLES + self.fill..][..take];
                for (d, &x) in dst.iter_mut().zip(&src[pos..pos + take]) {
                    *d = sanitize_sample(x).0.clamp(-INPUT_LIMIT, INPUT_LIMIT);
                }
            }
            self.fill += take;
            self.seen += take;
            pos += take;
            if self.fill == SEGMENT_SAMPLES {
                self.run_segment(SEGMENT_SAMPLES);
                self.deliver(STRIDE_SAMPLES, STRIDE_SAMPLES, out);
            }
        }
        self.stats.busy += t_busy.elapsed();
    }

    fn finish(&mut self, out: &mut StemOutput) {
        let t_busy = Instant::now();
        out.declare(self.stems);
        // Segments start at every multiple of the stride below the stream's length.
        while self.start < self.seen {
            let len = self.seen - self.start;
            for c in 0..2 {
                self.input[c * SEGMENT_SAMPLES + self.fill..(c + 1) * SEGMENT_SAMPLES].fill(0.0);
            }
            self.run_segment(len.min(SEGMENT_SAMPLES));
            if len <= STRIDE_SAMPLES {
                self.deliver(len, len, out);
            } else {
                self.deliver(STRIDE_SAMPLES, STRIDE_SAMPLES, out);
            }
        }
        self.stats.busy += t_busy.elapsed();
    }

    fn reset(&mut self) {
        self.fill = 0;
        self.start = 0;
        self.seen = 0;
        self.input.fill(0.0);
        for a in &mut self.acc {
            a.fill(0.0);
        }
        self.wsum.fill(0.0);
        self.last_error = None;
        self.stats = SegmentStats::new(STRIDE_SAMPLES);
    }

    fn latency_samples(&self) -> usize {
        SEGMENT_SAMPLES - 1
    }

    fn segment_stats(&self) -> Option<SegmentStats> {
        Some(self.stats)
    }

    fn take_error(&mut self) -> Option<SeparateError> {
        self.last_error.take().map(|message| SeparateError::Failed {
            backend: "htdemucs",
            message,
        })
    }
}
