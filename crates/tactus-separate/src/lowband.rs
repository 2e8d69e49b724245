//! The drum kit's share of the low band: a small learned mask that moves the kick's and the
//! low toms' bodies out of the spectral separator's bass stem.
//!
//! A median-filter separator calls a drum body harmonic (a kick or a floor tom rings as a
//! low, slowly decaying partial for 100–300 ms), so it stays in the bass stem and the bass
//! tracker hears a second, louder "bass" an octave or a fifth under the real one. Subtracting
//! the drum stem from the corpus mixes lifted held-out mix bass RPA from 0.61–0.71 to
//! 0.88–0.92 (docs/decisions/0020-kit-mask.md); no hand-made rule found the bodies (attack-tail
//! subtraction, sustain weighting: ±0.03).
//!
//! ## Model
//! Per STFT frame `t` of the mono mix (the separator's own analysis, 2048-point periodic
//! Hann, hop 1024 at 44.1 kHz), a feature vector of `LOW + BANDS` values:
//! * `ln(|X_k| + ε)` for the lowest `LOW` = 24 bins (0–495 Hz);
//! * `ln(mean |X_k| + ε)` over each of the `BANDS` = 5 octave bands between the
//!   weight file's edges (500 Hz … 16 kHz): the broadband context of an attack;
//! * `ε = 10⁻³ · max_{k < LOW} |X_k| + 10⁻⁶` (a 60 dB floor under the frame's strongest low
//!   bin, so a synthetic tone over digital silence reads like music over a noise floor);
//! * all minus a running reference `r ← r + max(a, 1/(t+1))·(m_t − r)`, `m_t` the mean of
//!   the 24 low values and `a = hop / (2 s · rate)` (a level-free input);
//! * (version 2) per low bin `k < SLOW` = 24, its steadiness `x_k − s_k`, where `x_k` is its
//!   value above and `s_k ← s_k + max(b, 1/(t+1))·(x_k − s_k)`, `b = hop / (1 s · rate)`:
//!   a held note sits near 0 while a kit's repeated decays swing (without it a steady pure
//!   tone read as a drum body).
//!
//! The network sees the frames `t − PAST ..= t + FUTURE` (6 and 2; frames before the start
//! read as `PAD` = −10 in every value, frames after the end repeat the last one), one
//! hidden layer of ReLU units, and
//! gives per low output bin `k < OUT` (15 bins, 0–301 Hz) the drums' share
//! `p_k = σ(…)` of that bin, trained against `|D_k|² / (|D_k|² + |X_k − D_k|²)` on corpus
//! songs whose drum stem is known (`models/lowband/train.py`; the kits used and held out are
//! in `models/lowband/README.md`). The separator moves `p_k` of the bass mask to the drums
//! (`bass ← bass·(1 − p)`, `drums ← drums + bass·p`), so the four masks still sum to 1.
//!
//! **Held tones.** After the network, a low output bin whose log magnitude stays within
//! 0.25 nats over the whole context (9 frames, about 210 ms; frames before the start do
//! not count) keeps its bass share (`p_k = 0`): a kick or a tom decays, a held sub-bass
//! tone does not (a 41 Hz or 55 Hz sine otherwise went to the drums whole and fired kicks;
//! docs/decisions/0052-kit-mask-spares-held-tones.md).
//!
//! **Latency**: none added: the 2 future frames are the separator's own look-ahead.
//! **Allocation**: none after construction.
//! **Rate**: the weights hold for one bin width (44.1 kHz / 2048); another bin width turns
//! the mask off ([`LowBand::new`] returns `None`).

use realfft::num_complex::Complex;

/// The embedded weights (`models/lowband/train.py` writes them).
pub const WEIGHTS: &[u8] = include_bytes!("../weights/lowband.bin");

/// Value of every feature of a frame before the start or after the end of the stream.
pub const PAD: f32 = -10.0;

/// Magnitude floor inside the logarithms: `REL_FLOOR` times the frame's strongest low bin,
/// plus `FLOOR`.
const FLOOR: f32 = 1e-6;
const REL_FLOOR: f32 = 1e-3;

/// Time constant of the running reference, seconds.
const REF_S: f32 = 2.0;

/// Time constant of the steadiness features' running means, seconds.
const SLOW_S: f32 = 1.0;

/// A parsed weight file.
#[derive(Clone, Debug)]
pub struct LowBandModel {
    /// Low bins in the features.
    pub low: usize,
    /// Low bins that also get a steadiness feature (version 2 files; 0 in version 1).
    pub slow: usize,
    /// Band edges in Hz (`bands + 1` values).
    pub edges: Vec<f32>,
    /// Context frames before and after the frame.
    pub past: usize,
    pub future: usize,
    /// Hidden units and output bins.
    pub hidden: usize,
    pub out: usize,
    /// Bin width (Hz) the model was trained at.
    pub bin_hz: f32,
    /// `inputs × hidden`, row-major by input.
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    /// `hidden × out`, row-major by hidden unit.
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
}

impl LowBandModel {
    /// Features per frame.
    pub fn per_frame(&self) -> usize {
        self.low + self.edges.len() - 1 + self.slow
    }

    /// Network inputs (`per_frame · (past + 1 + future)`).
    pub fn inputs(&self) -> usize {
        self.per_frame() * (self.past + 1 + self.future)
    }

    /// Parses a weight file: `b"TLBM"`, u32 version (1 or 2), u32 low, bands, past, future,
    /// hidden, out, (version 2) u32 slow, f32 bin width, `bands + 1` f32 edges, then W1, b1,
    /// W2, b2 as little-endian f32.
    pub fn parse(bytes: &[u8]) -> Result<Self, String> {
        let mut pos = 0usize;
        let mut take = |n: usize| -> Result<&[u8], String> {
            let s = bytes
                .get(pos..pos + n)
                .ok_or_else(|| "low-band weights: truncated".to_string())?;
            pos += n;
            Ok(s)
        };
        if take(4)? != b"TLBM" {
            return Err("low-band weights: bad magic".into());
        }
        let mut u = || -> Result<usize, String> {
            let b = take(4)?;
            Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        };
        let version = u()?;
        if !(1..=2).contains(&version) {
            return Err(format!("low-band weights: version {version} unsupported"));
        }
        let (low, bands, past, future, hidden, out) = (u()?, u()?, u()?, u()?, u()?, u()?);
        let slow = if version >= 2 { u()? } else { 0 };
        if low == 0 || bands == 0 || hidden == 0 || out == 0 || out > low || low > 4096 {
            return Err("low-band weights: bad shape".into());
        }
        if slow > low {
            return Err("low-band weights: bad shape".into());
        }
        if past > 64 || future > 64 || hidden > 4096 || bands > 64 {
            return Err("low-band weights: bad shape".into());
        }
        let n_in = (low + bands + slow) * (past + 1 + future);
        let want = 4 * (1 + bands + 1 + n_in * hidden + hidden + hidden * out + out);
        let rest = &bytes[pos..];
        if rest.len() != want {
            return Err(format!(
                "low-band weights: {} bytes of values, expected {want}",
                rest.len()
            ));
        }
        let mut f = rest
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        let mut vec = |n: usize| -> Vec<f32> { (&mut f).take(n).collect() };
        let bin_hz = vec(1)[0];
        let edges = vec(bands + 1);
        let w1 = vec(n_in * hidden);
        let b1 = vec(hidden);
        let w2 = vec(hidden * out);
        let b2 = vec(out);
        let all = [&edges, &w1, &b1, &w2, &b2];
        if !bin_hz.is_finite() || all.iter().any(|v| v.iter().any(|x| !x.is_finite())) {
            return Err("low-band weights: non-finite value".into());
        }
        Ok(LowBandModel {
            low,
            slow,
            edges,
            past,
            future,
            hidden,
            out,
            bin_hz,
            w1,
            b1,
            w2,
            b2,
        })
    }
}

/// The streaming low-band drum mask of one separator. See the module docs.
#[derive(Clone, Debug)]
pub struct LowBand {
    model: LowBandModel,
    /// Bin ranges of the bands, `[lo, hi)`.
    band_bins: Vec<(usize, usize)>,
    /// Ring of the last `past + 1 + future` frames' features.
    ring: Vec<f32>,
    /// Frames pushed so far (real and padding).
    frames: usize,
    /// Real frames pushed so far (the reference's count).
    real: usize,
    reference: f32,
    rate_a: f32,
    /// Per steadiness bin: the running mean of its normalised log magnitude.
    slow_mean: Vec<f32>,
    slow_a: f32,
    x: Vec<f32>,
    h: Vec<f32>,
    /// Log magnitude of each output bin per context frame, before the running reference
    /// (NaN: a frame before the start), ring-indexed like `ring`.
    held: Vec<f32>,
}

impl LowBand {
    /// The embedded model for a separator with this rate, FFT length and hop; `None` when
    /// the bin width differs from the model's by more than 1 % or the spectrum is too short.
    pub fn new(sample_rate: u32, n_fft: usize, hop: usize) -> Option<Self> {
        let model = LowBandModel::parse(WEIGHTS).expect("embedded low-band weights parse");
        Self::with_model(model, sample_rate, n_fft, hop)
    }

    /// [`LowBand::new`] with a given model.
    pub fn with_model(
        model: LowBandModel,
        sample_rate: u32,
        n_fft: usize,
        hop: usize,
    ) -> Option<Self> {
        let bin_hz = sample_rate as f32 / n_fft as f32;
        let bins = n_fft / 2 + 1;
        if (bin_hz / model.bin_hz - 1.0).abs() > 0.01 || model.low > bins {
            return None;
        }
        let band_bins: Vec<(usize, usize)> = model
            .edges
            .windows(2)
            .map(|e| {
                let lo = ((e[0] / bin_hz).ceil() as usize).min(bins);
                let hi = ((e[1] / bin_hz).ceil() as usize).min(bins);
                (lo, hi.max(lo))
            })
            .collect();
        let ctx = model.past + 1 + model.future;
        let per = model.per_frame();
        let (n_in, hidden) = (model.inputs(), model.hidden);
        let mut lb = LowBand {
            band_bins,
            ring: vec![PAD; per * ctx],
            frames: 0,
            real: 0,
            reference: 0.0,
            rate_a: hop as f32 / (REF_S * sample_rate as f32),
            slow_mean: vec![0.0; model.slow],
            slow_a: hop as f32 / (SLOW_S * sample_rate as f32),
            x: vec![0.0; n_in],
            h: vec![0.0; hidden],
            held: vec![f32::NAN; model.out * ctx],
            model,
        };
        lb.reset();
        Some(lb)
    }

    /// The model in use.
    pub fn model(&self) -> &LowBandModel {
        &self.model
    }

    /// Output bins (the lowest bins whose bass mask it scales).
    pub fn out_bins(&self) -> usize {
        self.model.out
    }

    /// Frames between the newest pushed frame and the frame [`LowBand::drum_share`] is for.
    pub fn future(&self) -> usize {
        self.model.future
    }

    /// Back to the start of a stream.
    pub fn reset(&mut self) {
        self.ring.fill(PAD);
        self.frames = 0;
        self.real = 0;
        self.reference = 0.0;
        self.slow_mean.fill(0.0);
        self.held.fill(f32::NAN);
    }

    /// Computes frame features of `spectrum` into `out` (`per_frame` values), updating the
    /// running reference. Used by [`LowBand::push`] and by the training dump.
    pub fn frame_features(&mut self, spectrum: &[Complex<f32>], out: &mut [f32]) {
        let low = self.model.low;
        let mut peak = 0.0f32;
        for (o, x) in out[..low].iter_mut().zip(spectrum) {
            *o = x.norm_sqr().sqrt();
            peak = peak.max(*o);
        }
        // Floor: 60 dB under the frame's strongest low bin (a synthetic tone over digital
        // silence then reads like music over a noise floor).
        let eps = REL_FLOOR * peak + FLOOR;
        let mut sum = 0.0f32;
        for o in &mut out[..low] {
            *o = (*o + eps).ln();
            sum += *o;
        }
        for (o, &(lo, hi)) in out[low..].iter_mut().zip(&self.band_bins) {
            let mean = if hi > lo {
                spectrum[lo..hi]
                    .iter()
                    .map(|x| x.norm_sqr().sqrt())
                    .sum::<f32>()
                    / (hi - lo) as f32
            } else {
                0.0
            };
            *o = (mean + eps).ln();
        }
        let m = sum / low as f32;
        self.real += 1;
        let w = self.rate_a.max(1.0 / self.real as f32);
        self.reference += w * (m - self.reference);
        let head = low + self.band_bins.len();
        for o in out[..head].iter_mut() {
            *o -= self.reference;
        }
        // Steadiness: each low bin against its own running mean (a held note sits near 0,
        // a kit's repeated decays swing).
        let ws = self.slow_a.max(1.0 / self.real as f32);
        let (feats, steady) = out.split_at_mut(head);
        for ((s, mean), &x) in steady
            .iter_mut()
            .zip(&mut self.slow_mean)
            .zip(&feats[..low])
        {
            *mean += ws * (x - *mean);
            *s = x - *mean;
        }
    }

    /// Pushes the next frame's spectrum (`None`: a frame after the end of the stream, which
    /// repeats the newest frame's features).
    pub fn push(&mut self, spectrum: Option<&[Complex<f32>]>) {
        let per = self.model.per_frame();
        let ctx = self.model.past + 1 + self.model.future;
        let slot = self.frames % ctx;
        let mut buf = std::mem::take(&mut self.ring);
        match spectrum {
            Some(s) => self.frame_features(s, &mut buf[slot * per..(slot + 1) * per]),
            None if self.frames > 0 => {
                // After the end: the newest frame again (a held sound, not a cut that
                // would look like a decaying hit).
                let prev = (self.frames - 1) % ctx;
                buf.copy_within(prev * per..(prev + 1) * per, slot * per);
            }
            None => buf[slot * per..(slot + 1) * per].fill(PAD),
        }
        let n_out = self.model.out.min(self.model.low);
        let held = &mut self.held[slot * self.model.out..][..n_out];
        match spectrum {
            Some(_) => {
                for (h, &v) in held.iter_mut().zip(&buf[slot * per..]) {
                    *h = v + self.reference;
                }
            }
            None if self.frames > 0 => {
                let prev = (self.frames - 1) % ctx;
                self.held.copy_within(
                    prev * self.model.out..prev * self.model.out + n_out,
                    slot * self.model.out,
                );
            }
            None => held.fill(f32::NAN),
        }
        self.ring = buf;
        self.frames += 1;
    }

    /// The drums' share per output bin of the frame `future` frames before the newest pushed
    /// one, into `out` (`out_bins` values in [0, 1]). Frames not pushed read as padding.
    pub fn drum_share(&mut self, out: &mut [f32]) {
        let m = &self.model;
        let per = m.per_frame();
        let ctx = m.past + 1 + m.future;
        // Oldest first: frames (newest − ctx + 1) ..= newest.
        for j in 0..ctx {
            let dst = &mut self.x[j * per..(j + 1) * per];
            let age = ctx - 1 - j; // 0 = newest
            if age >= self.frames {
                dst.fill(PAD);
            } else {
                let slot = (self.frames - 1 - age) % ctx;
                dst.copy_from_slice(&self.ring[slot * per..(slot + 1) * per]);
            }
        }
        let hidden = m.hidden;
        self.h.copy_from_slice(&m.b1);
        for (i, &xi) in self.x.iter().enumerate() {
            if xi != 0.0 {
                let row = &m.w1[i * hidden..(i + 1) * hidden];
                for (h, &w) in self.h.iter_mut().zip(row) {
                    *h += xi * w;
                }
            }
        }
        for h in &mut self.h {
            *h = h.max(0.0);
        }
        let n_out = m.out;
        out[..n_out].copy_from_slice(&m.b2);
        for (j, &hj) in self.h.iter().enumerate() {
            if hj != 0.0 {
                let row = &m.w2[j * n_out..(j + 1) * n_out];
                for (o, &w) in out[..n_out].iter_mut().zip(row) {
                    *o += hj * w;
                }
            }
        }
        for o in &mut out[..n_out] {
            *o = 1.0 / (1.0 + (-*o).exp());
        }
        // A held tone is not a drum body: a low bin whose log magnitude stays within
        // STEADY_NATS over the whole context (about 210 ms; an attack in it breaks this,
        // frames before the start do not count) keeps its bass share
        // (docs/decisions/0052-kit-mask-spares-held-tones.md).
        let stride = m.out;
        for (k, o) in out[..n_out.min(m.low)].iter_mut().enumerate() {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for j in 0..ctx.min(self.frames) {
                let v = self.held[j * stride + k];
                if !v.is_nan() {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            if hi >= lo && hi - lo < STEADY_NATS {
                *o = 0.0;
            }
        }
    }
}

/// How far (nats of magnitude) a low bin's level may move over the context and still count
/// as held (docs/decisions/0052-kit-mask-spares-held-tones.md).
const STEADY_NATS: f32 = 0.25;
