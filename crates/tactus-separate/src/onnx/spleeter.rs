//! Spleeter 2-stem separation (vocals / accompaniment) with Deezer's pre-trained U-Nets.
//!
//! Source: Hennequin et al., "Spleeter: a fast and efficient music source separation tool
//! with pre-trained models", JOSS 2020 (MIT code and weights). The network is the
//! `2stems` model, converted to ONNX without TensorFlow or torch by
//! `models/convert_spleeter.py` (input `mag [batch, 2, frames, 1024]`, outputs `vocals`
//! and `accompaniment`, each the sigmoid mask × the input magnitude).
//!
//! **Processing, as Spleeter does it** (`spleeter/model/__init__.py`):
//! 1. 4096 zeros are prepended to the stereo input; STFT with a 4096-sample periodic Hann
//!    window, hop 1024, no centring (frame `i` covers input samples `[i·1024 − 4096,
//!    i·1024)`). This is [`crate::stft::StftAnalysis`] (which centres, i.e. prepends 2048
//!    zeros) fed 2048 extra zeros first.
//! 2. The magnitudes of bins 0–1023 (0–11 kHz) of both channels go through the network in
//!    segments of 512 frames (11.9 s) — Spleeter's own `T = 512`.
//! 3. Ratio masks per channel and bin, Spleeter's `separation_exponent = 2`, `EPSILON =
//!    1e-10`: `m_v = (v² + ε/2) / (v² + a² + ε)` and `m_a = (a² + ε/2) / (v² + a² + ε)`,
//!    where `v`, `a` are the two network outputs; `m_v + m_a = 1`. Bins ≥ 1024 are zero in
//!    both stems (as in Spleeter, which zero-pads the masks above `F = 1024`).
//! 4. Inverse STFT of `mask × complex STFT` by overlap-add. Spleeter uses a Hann synthesis
//!    window and scales by 2/3 (the Hann² sum at hop n/4 is 3/2); [`crate::stft::OverlapAdd`]
//!    divides by the actual window sum, which is the same 3/2 everywhere except in the
//!    last 3072 samples of a stream, where it reconstructs exactly instead of fading out.
//!    The first 4096 samples of the padded output are dropped.
//!
//! **Streaming.** Unlike Spleeter (which cuts the spectrogram into disjoint segments),
//! consecutive segments overlap by [`OVERLAP_FRAMES`] (64 frames, 1.5 s) and their ratio
//! masks are cross-faded linearly over the overlap, which hides segment seams; memory is
//! bounded (one segment of spectra, about 9 MB). The stream's end is zero-padded to a
//! full segment, as Spleeter does.
//!
//! **Stems.** Vocals are the network's vocal stem, mono = `(L + R) / 2`. Drums, bass and
//! other are split from the (stereo) accompaniment by [`SpectralSeparator`] with its
//! default configuration; its vocal-band share of the accompaniment is added to `other`,
//! so `drums + bass + other` is the accompaniment and all four stems sum to the mix below
//! 11 kHz. The accompaniment is synthesised and split only when one of drums, bass or
//! other is requested; the vocal stem is synthesised only when requested.
//!
//! **Latency**: a segment runs when its last frame has arrived, and its first 448 frames
//! are then final: `511 · 1024 + 4095 = 527 359` samples (11.96 s at 44.1 kHz), plus the
//! spectral separator's 4095 when drums, bass or other are requested. Only 44.1 kHz input
//! is accepted (the model's rate): resample first.
//!
//! **Failure at run time**: if ONNX Runtime fails on a segment (it should not), that
//! segment's vocal mask is 0 (everything goes to the accompaniment) and the message is
//! kept in [`SpleeterSeparator::last_error`] and reported by [`Separator::take_error`],
//! which fails a render.

use std::time::Instant;

use ort::session::Session;
use ort::value::TensorRef;
use realfft::num_complex::Complex;
use tactus_dsp::sanitize::sanitize_sample;

use super::{open_session, OnnxConfig, OnnxError, Port};
use crate::spectral::{SpectralConfig, SpectralSeparator};
use crate::stft::{OverlapAdd, StftAnalysis, StftConfig};
use crate::{SegmentStats, SeparateError, Separator, Stem, StemOutput, StemSet};

/// The only sample rate the model accepts, in Hz.
pub const SAMPLE_RATE: u32 = 44_100;
/// STFT frame length.
pub const N_FFT: usize = 4096;
/// STFT hop.
pub const HOP: usize = 1024;
/// Frequency bins the network sees (0..1024, i.e. up to 11.0 kHz).
pub const NET_BINS: usize = 1024;
/// Frames per network call (Spleeter's `T`).
pub const SEGMENT_FRAMES: usize = 512;
/// Frames shared by consecutive segments (cross-faded).
pub const OVERLAP_FRAMES: usize = 64;
const STRIDE: usize = SEGMENT_FRAMES - OVERLAP_FRAMES;
/// Spleeter's `EPSILON` in the ratio masks.
const EPS: f32 = 1e-10;
/// Samples the Spleeter framing prepends on top of the centred STFT's own `N_FFT / 2`.
const EXTRA_PAD: usize = N_FFT / 2;
/// Input samples are clamped to ±this before the STFT, so magnitudes stay finite.
const INPUT_LIMIT: f32 = 1e9;
const BLOCK: usize = 1024;
/// Room reserved in the accompaniment splitter's output (per stem): one hop of
/// accompaniment in `process`, or the splitter's whole tail in `finish`.
const SPLIT_ROOM: usize = 16_384;

const SEG_LEN: usize = 2 * SEGMENT_FRAMES * NET_BINS;

/// Input / output contract of `models/spleeter-2stems.onnx`.
const INPUTS: [Port; 1] = [Port {
    name: "mag",
    shape: &[None, Some(2), None, Some(NET_BINS as i64)],
}];
const OUTPUTS: [Port; 2] = [
    Port {
        name: "vocals",
        shape: &[None, Some(2), None, Some(NET_BINS as i64)],
    },
    Port {
        name: "accompaniment",
        shape: &[None, Some(2), None, Some(NET_BINS as i64)],
    },
];

/// The Spleeter separator. See the module docs.
pub struct SpleeterSeparator {
    stems: StemSet,
    analysis: StftAnalysis,
    core: Core,
    blk_l: Vec<f32>,
    blk_r: Vec<f32>,
}

/// Synthesis channels.
const CH_VOCALS: usize = 0;
const CH_ACC_L: usize = 1;
const CH_ACC_R: usize = 2;

struct Core {
    want_vocals: bool,
    session: Session,
    /// Per channel (L, R): complex bins 0..NET_BINS of the last SEGMENT_FRAMES frames,
    /// frame `t` in slot `t % SEGMENT_FRAMES`.
    spec: [Vec<Complex<f32>>; 2],
    /// Per channel: accumulated (cross-faded) vocal ratio mask, same layout.
    vmask: [Vec<f32>; 2],
    /// Network input `[1, 2, SEGMENT_FRAMES, NET_BINS]`.
    net_in: Vec<f32>,
    /// Frames analysed, segments run, frames synthesised.
    frames_in: usize,
    segments: usize,
    frames_out: usize,
    /// Full-length spectrum used for each inverse transform.
    work: Vec<Complex<f32>>,
    synthesis: OverlapAdd,
    /// Output samples (per channel) of the padded stream dropped so far (≤ EXTRA_PAD).
    dropped: usize,
    /// One hop of synthesised samples per channel (vocals, acc L, acc R) and its length.
    hop_buf: [Vec<f32>; 3],
    hop_len: usize,
    /// The synthesis's final samples per channel (up to N_FFT) and their number.
    tail: [Vec<f32>; 3],
    tail_len: usize,
    split: Option<Split>,
    last_error: Option<String>,
    stats: SegmentStats,
}

/// The accompaniment splitter (drums / bass / other).
struct Split {
    sep: SpectralSeparator,
    out: StemOutput,
    want_other: bool,
}

impl SpleeterSeparator {
    /// A Spleeter separator at `sample_rate` (must be 44 100 Hz) that outputs `stems`,
    /// with the model and runtime named in `cfg`.
    pub fn new(sample_rate: u32, stems: StemSet, cfg: &OnnxConfig) -> Result<Self, OnnxError> {
        if sample_rate != SAMPLE_RATE {
            return Err(SeparateError::SampleRate(sample_rate).into());
        }
        if stems.is_empty() {
            return Err(SeparateError::NoStems.into());
        }
        let session = open_session(cfg, "Spleeter 2stems", &INPUTS, &OUTPUTS)?;
        let stft = StftConfig {
            n_fft: N_FFT,
            hop: HOP,
        };
        let rest: StemSet = [Stem::Drums, Stem::Bass, Stem::Other]
            .into_iter()
            .filter(|&s| stems.contains(s))
            .collect();
        let split = if rest.is_empty() {
            None
        } else {
            let want_other = rest.contains(Stem::Other);
            let split_stems = if want_other {
                rest.with(Stem::Vocals)
            } else {
                rest
            };
            let sep = SpectralSeparator::new(sample_rate, split_stems, SpectralConfig::default())
                .map_err(OnnxError::from)?;
            Some(Split {
                sep,
                out: StemOutput::with_capacity(split_stems, SPLIT_ROOM),
                want_other,
            })
        };
        let zero = Complex::new(0.0, 0.0);
        let core = Core {
            want_vocals: stems.contains(Stem::Vocals),
            session,
            spec: [
                vec![zero; SEGMENT_FRAMES * NET_BINS],
                vec![zero; SEGMENT_FRAMES * NET_BINS],
            ],
            vmask: [
                vec![0.0; SEGMENT_FRAMES * NET_BINS],
                vec![0.0; SEGMENT_FRAMES * NET_BINS],
            ],
            net_in: vec![0.0; SEG_LEN],
            frames_in: 0,
            segments: 0,
            frames_out: 0,
            work: vec![zero; stft.bins()],
            synthesis: OverlapAdd::new(stft, 3).map_err(SeparateError::from)?,
            dropped: 0,
            hop_buf: [vec![0.0; HOP], vec![0.0; HOP], vec![0.0; HOP]],
            hop_len: 0,
            tail: [vec![0.0; N_FFT], vec![0.0; N_FFT], vec![0.0; N_FFT]],
            tail_len: 0,
            split,
            last_error: None,
            stats: SegmentStats::new(STRIDE * HOP),
        };
        let mut sep = SpleeterSeparator {
            stems,
            analysis: StftAnalysis::new(stft, 2).map_err(SeparateError::from)?,
            core,
            blk_l: vec![0.0; BLOCK],
            blk_r: vec![0.0; BLOCK],
        };
        sep.reset();
        Ok(sep)
    }

    /// The message of the last failed network call, if any (see the module docs).
    pub fn last_error(&self) -> Option<&str> {
        self.core.last_error.as_deref()
    }
}

/// Cross-fade weight of frame `j` (0..SEGMENT_FRAMES) of segment `k`.
fn segment_weight(k: usize, j: usize) -> f32 {
    if k > 0 && j < OVERLAP_FRAMES {
        (j as f32 + 0.5) / OVERLAP_FRAMES as f32
    } else if j >= STRIDE {
        1.0 - ((j - STRIDE) as f32 + 0.5) / OVERLAP_FRAMES as f32
    } else {
        1.0
    }
}

impl Core {
    fn on_frame(&mut self, t: usize, spectra: &[Vec<Complex<f32>>], out: &mut StemOutput) {
        let slot = (t % SEGMENT_FRAMES) * NET_BINS;
        for ((spec, vmask), src) in self.spec.iter_mut().zip(&mut self.vmask).zip(spectra) {
            spec[slot..slot + NET_BINS].copy_from_slice(&src[..NET_BINS]);
            vmask[slot..slot + NET_BINS].fill(0.0);
        }
        self.frames_in = t + 1;
        let k = self.segments;
        if self.frames_in == k * STRIDE + SEGMENT_FRAMES {
            self.run_segment(k);
            self.synthesise_until((k + 1) * STRIDE, out);
        }
    }

    /// Runs the network on segment `k` (frames `k·STRIDE ..+ SEGMENT_FRAMES`, frames not
    /// analysed yet read as silence) and accumulates its weighted vocal ratio masks.
    fn run_segment(&mut self, k: usize) {
        let first = k * STRIDE;
        let plane = SEGMENT_FRAMES * NET_BINS;
        for j in 0..SEGMENT_FRAMES {
            let t = first + j;
            let slot = (t % SEGMENT_FRAMES) * NET_BINS;
            for c in 0..2 {
                let dst = &mut self.net_in[c * plane + j * NET_BINS..][..NET_BINS];
                if t < self.frames_in {
                    for (d, x) in dst.iter_mut().zip(&self.spec[c][slot..slot + NET_BINS]) {
                        *d = x.norm();
                    }
                } else {
                    dst.fill(0.0);
                }
            }
        }
        self.segments = k + 1;
        let result = (|| -> Result<(), String> {
            let input = TensorRef::from_array_view((
                [1usize, 2, SEGMENT_FRAMES, NET_BINS],
                &self.net_in[..],
            ))
            .map_err(|e| e.to_string())?;
            let t_net = Instant::now();
            let outputs = self.session.run(ort::inputs![input]);
            self.stats.record_network(t_net.elapsed());
            let outputs = outputs.map_err(|e| e.to_string())?;
            let get = |name: &str| -> Result<&[f32], String> {
                let v = outputs
                    .get(name)
                    .ok_or_else(|| format!("no output `{name}`"))?;
                let (_, data) = v.try_extract_tensor::<f32>().map_err(|e| e.to_string())?;
                if data.len() != SEG_LEN {
                    return Err(format!(
                        "output `{name}` has {} values, expected {SEG_LEN} (shape [1, 2, \
                         {SEGMENT_FRAMES}, {NET_BINS}]): is the model a Spleeter export?",
                        data.len()
                    ));
                }
                Ok(data)
            };
            let (v, a) = (get("vocals")?, get("accompaniment")?);
            for j in 0..SEGMENT_FRAMES {
                let t = first + j;
                if t >= self.frames_in {
                    break;
                }
                let w = segment_weight(k, j);
                let slot = (t % SEGMENT_FRAMES) * NET_BINS;
                for c in 0..2 {
                    let src = c * plane + j * NET_BINS;
                    let m = &mut self.vmask[c][slot..slot + NET_BINS];
                    for ((m, &v), &a) in m
                        .iter_mut()
                        .zip(&v[src..src + NET_BINS])
                        .zip(&a[src..src + NET_BINS])
                    {
                        let (v2, a2) = (v * v, a * a);
                        let mv = (v2 + EPS / 2.0) / (v2 + a2 + EPS);
                        // NaN from a broken model must not reach the output.
                        *m += if mv.is_finite() { w * mv } else { 0.0 };
                    }
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
    }

    /// Synthesises frames `frames_out..end` (clipped to the frames analysed).
    fn synthesise_until(&mut self, end: usize, out: &mut StemOutput) {
        let end = end.min(self.frames_in);
        while self.frames_out < end {
            let slot = (self.frames_out % SEGMENT_FRAMES) * NET_BINS;
            let zero = Complex::new(0.0, 0.0);
            let (xl, xr) = (
                &self.spec[0][slot..slot + NET_BINS],
                &self.spec[1][slot..slot + NET_BINS],
            );
            let (ml, mr) = (
                &self.vmask[0][slot..slot + NET_BINS],
                &self.vmask[1][slot..slot + NET_BINS],
            );
            if self.want_vocals {
                for (k, w) in self.work.iter_mut().enumerate() {
                    *w = if k < NET_BINS {
                        (xl[k] * ml[k] + xr[k] * mr[k]) * 0.5
                    } else {
                        zero
                    };
                }
                self.synthesis.add(CH_VOCALS, &mut self.work);
                self.stats.inverse_ffts += 1;
            }
            if self.split.is_some() {
                for (ch, x, m) in [(CH_ACC_L, xl, ml), (CH_ACC_R, xr, mr)] {
                    for (k, w) in self.work.iter_mut().enumerate() {
                        *w = if k < NET_BINS {
                            x[k] * (1.0 - m[k])
                        } else {
                            zero
                        };
                    }
                    self.synthesis.add(ch, &mut self.work);
                    self.stats.inverse_ffts += 1;
                }
            }
            self.frames_out += 1;
            self.hop_len = 0;
            let (bufs, len) = (&mut self.hop_buf, &mut self.hop_len);
            self.synthesis.advance(|ch, s| {
                bufs[ch][..s.len()].copy_from_slice(s);
                *len = s.len();
            });
            self.deliver(out);
        }
    }

    /// Drops the leading pad from `hop_buf` and hands the rest to `out` / the splitter.
    fn deliver(&mut self, out: &mut StemOutput) {
        let skip = (EXTRA_PAD - self.dropped).min(self.hop_len);
        self.dropped += skip;
        let range = skip..self.hop_len;
        if range.is_empty() {
            return;
        }
        if self.want_vocals {
            out.extend(Stem::Vocals, &self.hop_buf[CH_VOCALS][range.clone()]);
        }
        if let Some(split) = self.split.as_mut() {
            split.sep.process(
                &self.hop_buf[CH_ACC_L][range.clone()],
                &self.hop_buf[CH_ACC_R][range],
                &mut split.out,
            );
            split.transfer(out);
        }
    }

    /// Runs the remaining segments (zero-padded), synthesises every frame and flushes
    /// the stream of `total_input` samples.
    fn finish(&mut self, total_input: usize, out: &mut StemOutput) {
        while self.segments * STRIDE < self.frames_in {
            let k = self.segments;
            self.run_segment(k);
            self.synthesise_until((k + 1) * STRIDE, out);
        }
        self.synthesise_until(self.frames_in, out);
        // The synthesis saw the padded stream: EXTRA_PAD zeros + the input. Its finish
        // emits up to N_FFT samples per channel at once; deliver them HOP at a time.
        let (tail, tail_len) = (&mut self.tail, &mut self.tail_len);
        *tail_len = 0;
        self.synthesis.finish(total_input + EXTRA_PAD, |ch, s| {
            tail[ch][..s.len()].copy_from_slice(s);
            *tail_len = s.len();
        });
        let n = self.tail_len;
        let mut pos = 0;
        while pos < n {
            let m = (n - pos).min(HOP);
            for ch in 0..3 {
                self.hop_buf[ch][..m].copy_from_slice(&self.tail[ch][pos..pos + m]);
            }
            self.hop_len = m;
            self.deliver(out);
            pos += m;
        }
        if let Some(split) = self.split.as_mut() {
            split.sep.finish(&mut split.out);
            split.transfer(out);
        }
    }

    fn reset(&mut self) {
        for c in 0..2 {
            self.spec[c].fill(Complex::new(0.0, 0.0));
            self.vmask[c].fill(0.0);
        }
        self.frames_in = 0;
        self.segments = 0;
        self.frames_out = 0;
        self.dropped = 0;
        self.hop_len = 0;
        self.synthesis.reset();
        if let Some(split) = self.split.as_mut() {
            split.sep.reset();
            split.out.clear();
        }
        self.last_error = None;
        self.stats = SegmentStats::new(STRIDE * HOP);
    }
}

impl Split {
    /// Moves the splitter's output into `out`: drums and bass as they are, other = the
    /// splitter's other + vocals (the accompaniment's vocal-band share).
    fn transfer(&mut self, out: &mut StemOutput) {
        for s in [Stem::Drums, Stem::Bass] {
            if self.sep.stems().contains(s) {
                out.extend(s, self.out.get(s));
            }
        }
        if self.want_other {
            for (&o, &v) in self
                .out
                .get(Stem::Other)
                .iter()
                .zip(self.out.get(Stem::Vocals))
            {
                out.push(Stem::Other, o + v);
            }
        }
        self.out.clear();
    }
}

impl Separator for SpleeterSeparator {
    fn name(&self) -> &'static str {
        "spleeter"
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
        for (bl, br) in crate::stereo_blocks(left, right, BLOCK) {
            let m = bl.len();
            for (i, (&l, &r)) in bl.iter().zip(br).enumerate() {
                self.blk_l[i] = sanitize_sample(l).0.clamp(-INPUT_LIMIT, INPUT_LIMIT);
                self.blk_r[i] = sanitize_sample(r).0.clamp(-INPUT_LIMIT, INPUT_LIMIT);
            }
            let core = &mut self.core;
            self.analysis
                .push(&[&self.blk_l[..m], &self.blk_r[..m]], |t, spectra| {
                    core.on_frame(t, spectra, out)
                });
        }
        self.core.stats.busy += t_busy.elapsed();
    }

    fn finish(&mut self, out: &mut StemOutput) {
        let t_busy = Instant::now();
        out.declare(self.stems);
        let core = &mut self.core;
        self.analysis
            .finish(|t, spectra| core.on_frame(t, spectra, out));
        let total = self.analysis.samples_seen() - EXTRA_PAD;
        self.core.finish(total, out);
        self.core.stats.busy += t_busy.elapsed();
    }

    fn reset(&mut self) {
        self.analysis.reset();
        self.core.reset();
        // Spleeter's framing: EXTRA_PAD zeros before the centred STFT's own N_FFT / 2.
        // They complete frame 0 (all zeros), which is stored like any other frame; no
        // output can result from it, so a throw-away (non-allocating) output is passed.
        self.blk_l.fill(0.0);
        let zeros = &self.blk_l[..EXTRA_PAD.min(BLOCK)];
        let core = &mut self.core;
        let mut scratch = StemOutput::new();
        let mut fed = 0;
        while fed < EXTRA_PAD {
            self.analysis.push(&[zeros, zeros], |t, spectra| {
                core.on_frame(t, spectra, &mut scratch)
            });
            fed += zeros.len();
        }
    }

    fn latency_samples(&self) -> usize {
        let split = self
            .core
            .split
            .as_ref()
            .map_or(0, |s| s.sep.latency_samples());
        (SEGMENT_FRAMES - 1) * HOP + N_FFT - 1 + split
    }

    fn segment_stats(&self) -> Option<SegmentStats> {
        Some(self.core.stats)
    }

    fn take_error(&mut self) -> Option<SeparateError> {
        self.core
            .last_error
            .take()
            .map(|message| SeparateError::Failed {
                backend: "spleeter",
                message,
            })
    }
}
