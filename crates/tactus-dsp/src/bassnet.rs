//! A learned bass-line salience for mixtures: a small network reads the separated bass
//! band's log-frequency spectrum around a hop and says which pitch candidate (or none) the
//! bass line has there. [`crate::shs`] decodes its output with the same fixed-lag Viterbi as
//! the harmonic sum ([`crate::shs::ShsConfig::learned`]).
//!
//! Why: on a mixture's low band the harmonic sum follows whatever is loudest there. A kick's or
//! an 808's body under a bass note with a weak fundamental makes the subharmonic an octave or a
//! fifth below win (`f/2` collects the body and every harmonic of the note), and the Viterbi
//! then holds it (`docs/decisions/0024-learned-bass-salience.md`). A network that sees a few
//! frames around the hop learns what a drum's body looks like (a decaying, falling sine that
//! starts with a hit) and what a bass note looks like.
//!
//! # Algorithm
//! 1. **Spectrum** of the frame exactly as the harmonic sum computes it ([`BassFront`]):
//!    frame minus its mean, scaled to unit peak, times a Hann window, zero-padded, real FFT,
//!    magnitudes.
//! 2. **Log-frequency bands**: [`BANDS`] bands, [`BINS_PER_SEMITONE`] per semitone from
//!    [`LOW_HZ`] (30 Hz to about 1 kHz); band `b` is the largest magnitude among the FFT
//!    bins within a sixth of a semitone of `LOW_HZ · 2^(b / 36)` (at least one bin), in dB,
//!    minus the frame's largest band, plus 60, over 60, clipped to `[0, 1]` (level
//!    invariant: the frame's loudest band is 1, 60 dB under it is 0). A silent frame is all
//!    zeros.
//! 3. **Context**: the bands of the frames at the model's offsets from the hop (for the
//!    embedded model −8, −4, −2, 0, +2, +4 hops), zeros before the stream and after its end.
//! 4. **Network**: a multilayer perceptron with ReLU hidden layers and a softmax over the
//!    candidates (the harmonic sum's grid: 35–400 Hz, 3 per semitone) and one "no bass"
//!    class. Trained by `models/bassnet/train.py` on features dumped by this very code
//!    (`examples/bass_features.rs`), provenance in `models/bassnet/README.md`.
//!
//! # Latency
//! The hop is decided once the frame at the largest offset exists: `max offset · hop`
//! samples more than the harmonic sum (4 hops = 40 ms for the embedded model), stated by
//! [`crate::shs::Shs`]'s `latency_samples()`.
//!
//! # The lead models and their ensemble
//! The same network over a mixture's lead band ([`BassNet::embedded_lead`]: 216 bands from
//! 70 Hz, candidates 70–1400 Hz). Two more lead models share its recipe: one trained with 80
//! more sung songs ([`BassNet::embedded_lead_sung`]), which finds sung leads better and
//! instrumental ones as well but alone moved a chorale's level range now and then, and one
//! trained with another seed on 180 other songs ([`BassNet::embedded_lead_3`]). With
//! [`crate::shs::ShsConfig::learned_ensemble`] the tracker decodes the mean of the three
//! models' probabilities, `log(Σᵢ pᵢ / 3)` per class (a mixture of experts with equal
//! weights; [`BassNet::forward_ensemble_batch`]). Same latency; three times the network's
//! cost.
//!
//! # The harmonic view
//! The spectral separator's lead band loses part of the voice to its other masks (a low
//! voice's fundamental goes to the bass band, a vowel's harmonics under a chord to the
//! other band). Three more lead models share the lead recipe but read the separator's
//! harmonic sum, vocals + bass + other (the mix without the drum stem), through the same
//! front end ([`BassNet::embedded_lead_harmonic`], [`BassNet::embedded_lead_harmonic_others`];
//! [`crate::shs::ShsConfig::learned_harmonic`]). The pair's voicing tracker still reads the
//! lead band (the pitch tracker of a [`crate::pair::VoicingPitchPair`] reads the sum as
//! the side input, [`crate::HopStage::process_with`]). The bass has one such model
//! too ([`BassNet::embedded_bass_harmonic`]): its network reads the harmonic sum while the
//! harmonic sum it is blended with still reads the bass band (the side input of [`crate::shs::Shs`]). On songs none of the models
//! trained on, their ensemble's argmax is the lead's pitch on 0.891 / 0.731 / 0.787 of the
//! voiced hops (chorales / instrumental leads over an unseen kit / sung) against 0.837 /
//! 0.676 / 0.683 for the lead-band ensemble (`models/bassnet/README.md`).
//!
//! # The live models
//! The models above need a 209 ms (bass) or 70 ms (lead) frame and look ahead 3–4 hops: with
//! the Viterbi's lag and the full separator they cannot answer within the live profile's
//! pitch budget. Two more models share the recipe but read the live profile's separator's
//! harmonic sum on short frames with a context of past frames only
//! ([`BassNet::embedded_bass_live`]: 256 samples at 4.9 kHz, 52 ms, frames −8, −4, −2, −1, 0;
//! [`BassNet::embedded_lead_live`]: 512 samples at 14.7 kHz, 35 ms, frames −6, −3, −2, −1,
//! 0), trained on songs none of the benches scores
//! (`docs/decisions/0057-learned-live-pitch.md`). Latency: half the frame plus the
//! Viterbi's lag, nothing ahead.

use std::sync::OnceLock;

use crate::nn::format::{read_f32s, read_u32, take};
use crate::nn::Layer;
use crate::spectrum::FrameFft;
use crate::ConfigError;

/// Log-frequency bands of the bass model's front end.
pub const BANDS: usize = 183;
/// Centre of the bass model's band 0, Hz.
pub const LOW_HZ: f32 = 30.0;
/// Bands (and candidates) per semitone.
pub const BINS_PER_SEMITONE: u32 = 3;
/// Dynamic range of a band below the frame's loudest, dB.
pub const RANGE_DB: f32 = 60.0;

const WHAT: &str = "bass model";

/// Power ratio under a frame's loudest band (63 dB, 3 dB past [`RANGE_DB`]) below which the
/// front end skips a band's logarithm: its feature is 0 whatever the logarithm's rounding.
const QUIET_POWER: f32 = 5e-7;

const MAGIC: &[u8; 8] = b"TACTUSBN";

/// The embedded model (see `models/bassnet/README.md`).
static EMBEDDED: &[u8] = include_bytes!("../weights/bassnet.bin");

/// The embedded lead model: the same network over a mixture's lead band (216 bands from
/// 70 Hz, candidates 70–1400 Hz; `models/bassnet/README.md`).
static EMBEDDED_LEAD: &[u8] = include_bytes!("../weights/leadnet.bin");

/// The second embedded lead model: the same recipe trained with 80 more sung songs
/// (`docs/decisions/0031-lead-ensemble.md`), averaged with the first
/// ([`crate::shs::ShsConfig::learned_ensemble`]).
static EMBEDDED_LEAD_SUNG: &[u8] = include_bytes!("../weights/leadnet_sung.bin");

/// The third embedded lead model: the lead recipe with another seed on other songs
/// (`docs/decisions/0033-third-lead-ensemble-member.md`).
static EMBEDDED_LEAD_3: &[u8] = include_bytes!("../weights/leadnet_3.bin");

/// The harmonic-view lead models: the lead recipe trained on the spectral separator's
/// harmonic sum (vocals + bass + other) instead of its vocals stem, seeds 7, 11 and 13 on
/// the same 348 songs (`docs/decisions/0037-learned-lead-reads-the-harmonic-sum.md`; module
/// docs, "The harmonic view").
static EMBEDDED_LEAD_HARM: &[u8] = include_bytes!("../weights/leadnet_harm.bin");
static EMBEDDED_LEAD_HARM_2: &[u8] = include_bytes!("../weights/leadnet_harm_2.bin");
static EMBEDDED_LEAD_HARM_3: &[u8] = include_bytes!("../weights/leadnet_harm_3.bin");

/// The harmonic-view bass model: the bass recipe trained on the spectral separator's
/// harmonic sum (vocals + bass + other) instead of its bass stem, seed 7 on
/// `models/bassnet/bass_train_songs_2.txt` (`docs/decisions/0042-bass-reads-the-harmonic-sum.md`;
/// module docs, "The harmonic view").
static EMBEDDED_BASS_HARM: &[u8] = include_bytes!("../weights/bassnet_harm.bin");

/// The live models: the bass and the lead recipes on the live profile's separator's
/// harmonic sum, short frames and a past-only context (module docs, "The live models";
/// `docs/decisions/0057-learned-live-pitch.md`).
static EMBEDDED_BASS_LIVE: &[u8] = include_bytes!("../weights/bassnet_live.bin");
static EMBEDDED_LEAD_LIVE: &[u8] = include_bytes!("../weights/leadnet_live.bin");

/// The network and its input layout.
#[derive(Clone, Debug, PartialEq)]
pub struct BassNet {
    bands: usize,
    low_hz: f32,
    offsets: Vec<i32>,
    candidates: usize,
    cand_fmin_hz: f32,
    layers: Vec<Layer>,
}

impl BassNet {
    /// The model embedded in the binary (parsed once).
    pub fn embedded() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // The embedded file is checked by a unit test, so this cannot fail in a build whose
        // tests pass.
        MODEL.get_or_init(|| Self::from_bytes(EMBEDDED).expect("embedded bass model is valid"))
    }

    /// The embedded lead model (parsed once), for a mixture's lead
    /// ([`crate::shs::ShsConfig::learned`] on the lead's candidate grid).
    pub fn embedded_lead() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the bass model.
        MODEL.get_or_init(|| Self::from_bytes(EMBEDDED_LEAD).expect("embedded lead model is valid"))
    }

    /// The second embedded lead model (parsed once; see [`BassNet::embedded_lead`]), whose
    /// candidates, bands and offsets are the first's.
    pub fn embedded_lead_sung() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other two.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_LEAD_SUNG).expect("embedded sung lead model is valid")
        })
    }

    /// The lead ensemble's models besides [`BassNet::embedded_lead`]
    /// ([`crate::shs::ShsConfig::learned_ensemble`]; module docs, "The lead models and their
    /// ensemble").
    pub fn embedded_lead_others() -> Vec<&'static BassNet> {
        vec![Self::embedded_lead_sung(), Self::embedded_lead_3()]
    }

    /// The third embedded lead model (parsed once; see [`BassNet::embedded_lead_others`]),
    /// whose candidates, bands and offsets are the first's.
    pub fn embedded_lead_3() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other three.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_LEAD_3).expect("embedded third lead model is valid")
        })
    }

    /// The harmonic-view bass model (parsed once; module docs, "The harmonic view"): the
    /// bass model's front end, context and classes, trained on the spectral separator's
    /// harmonic sum.
    pub fn embedded_bass_harmonic() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other models.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_BASS_HARM).expect("embedded harmonic bass model is valid")
        })
    }

    /// The first harmonic-view lead model (parsed once; module docs, "The harmonic view"):
    /// the first lead model's front end, context and classes, trained on the spectral
    /// separator's harmonic sum.
    pub fn embedded_lead_harmonic() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other lead models.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_LEAD_HARM).expect("embedded harmonic lead model is valid")
        })
    }

    /// The harmonic-view ensemble's models besides [`BassNet::embedded_lead_harmonic`]
    /// (the same recipe with seeds 11 and 13).
    pub fn embedded_lead_harmonic_others() -> Vec<&'static BassNet> {
        static TWO: OnceLock<BassNet> = OnceLock::new();
        static THREE: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other lead models.
        vec![
            TWO.get_or_init(|| {
                Self::from_bytes(EMBEDDED_LEAD_HARM_2)
                    .expect("embedded harmonic lead model is valid")
            }),
            THREE.get_or_init(|| {
                Self::from_bytes(EMBEDDED_LEAD_HARM_3)
                    .expect("embedded harmonic lead model is valid")
            }),
        ]
    }

    /// The live bass model (parsed once; module docs, "The live models").
    pub fn embedded_bass_live() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other models.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_BASS_LIVE).expect("embedded live bass model is valid")
        })
    }

    /// The live lead model (parsed once; module docs, "The live models").
    pub fn embedded_lead_live() -> &'static BassNet {
        static MODEL: OnceLock<BassNet> = OnceLock::new();
        // Checked by a unit test, like the other models.
        MODEL.get_or_init(|| {
            Self::from_bytes(EMBEDDED_LEAD_LIVE).expect("embedded live lead model is valid")
        })
    }

    /// Parses the format written by `models/bassnet/train.py`: `"TACTUSBN"`, then
    /// little-endian u32 `version = 1, bands, bins_per_semitone`, f32 `low_hz, range_db`,
    /// u32 `n_offsets`, i32 `offsets[n_offsets]`, u32 `candidates`, f32 `cand_fmin_hz`,
    /// u32 `layers`, then per layer u32 `n_in, n_out`, f32 `w[n_out·n_in], b[n_out]`. The
    /// last layer has `candidates + 1` outputs (the last one: no bass).
    pub fn from_bytes(mut bytes: &[u8]) -> Result<BassNet, ConfigError> {
        let b = &mut bytes;
        if take(b, 8, WHAT)? != MAGIC {
            return Err(ConfigError::invalid(
                "bass model",
                "not a Tactus bass model",
            ));
        }
        if read_u32(b, WHAT)? != 1 {
            return Err(ConfigError::invalid(
                "bass model",
                "only version 1 is supported",
            ));
        }
        let bands = read_u32(b, WHAT)? as usize;
        let bps = read_u32(b, WHAT)?;
        let front = read_f32s(b, 2, WHAT)?;
        if !(1..=512).contains(&bands)
            || bps != BINS_PER_SEMITONE
            || !front[0].is_finite()
            || front[0] <= 0.0
            || front[1] != RANGE_DB
        {
            return Err(ConfigError::invalid(
                "bass model",
                "its front end is not this build's",
            ));
        }
        let n_off = read_u32(b, WHAT)? as usize;
        if !(1..=32).contains(&n_off) {
            return Err(ConfigError::invalid("bass model", "implausible context"));
        }
        let offsets: Vec<i32> = take(b, 4 * n_off, WHAT)?
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if offsets.iter().any(|o| o.abs() > 64) {
            return Err(ConfigError::invalid("bass model", "implausible context"));
        }
        let candidates = read_u32(b, WHAT)? as usize;
        let cand_fmin_hz = read_f32s(b, 1, WHAT)?[0];
        let n_layers = read_u32(b, WHAT)? as usize;
        if !(1..=4096).contains(&candidates) || !(1..=8).contains(&n_layers) || cand_fmin_hz <= 0.0
        {
            return Err(ConfigError::invalid("bass model", "implausible shape"));
        }
        let layers = crate::nn::format::read_layers(b, n_layers, n_off * bands, WHAT)?;
        let expect = layers.last().map_or(0, |l| l.n_out);
        if expect != candidates + 1 {
            return Err(ConfigError::invalid(
                "bass model",
                "last layer must have candidates + 1 outputs",
            ));
        }
        if !b.is_empty() {
            return Err(ConfigError::invalid("bass model", "trailing bytes"));
        }
        Ok(BassNet {
            bands,
            low_hz: front[0],
            offsets,
            candidates,
            cand_fmin_hz,
            layers,
        })
    }

    /// Log-frequency bands of its front end.
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// Centre of its front end's band 0, Hz.
    pub fn low_hz(&self) -> f32 {
        self.low_hz
    }

    /// Frame offsets of the context, in hops, in input order.
    pub fn offsets(&self) -> &[i32] {
        &self.offsets
    }

    /// Pitch candidates (the last output is "no bass").
    pub fn candidates(&self) -> usize {
        self.candidates
    }

    /// f0 of candidate 0, Hz.
    pub fn cand_fmin_hz(&self) -> f32 {
        self.cand_fmin_hz
    }

    /// Values in one network input.
    pub fn input_len(&self) -> usize {
        self.offsets.len() * self.bands
    }

    /// The widest layer (scratch size for [`BassNet::forward`]).
    pub fn width(&self) -> usize {
        self.layers
            .iter()
            .map(|l| l.n_in.max(l.n_out))
            .max()
            .unwrap_or(0)
    }

    /// Hops of look-ahead (the largest offset, at least 0).
    pub fn future(&self) -> usize {
        self.offsets.iter().copied().max().unwrap_or(0).max(0) as usize
    }

    /// Hops of look-back (minus the smallest offset, at least 0).
    pub fn past(&self) -> usize {
        (-self.offsets.iter().copied().min().unwrap_or(0)).max(0) as usize
    }

    /// Runs the network on one input; `a` and `b` are scratch of at least
    /// [`BassNet::width`] values. Writes the log-softmax over `candidates + 1` classes into
    /// `out`.
    pub fn forward(&self, input: &[f32], a: &mut [f32], b: &mut [f32], out: &mut [f32]) {
        self.forward_batch(input, 1, a, b, out);
    }

    /// [`BassNet::forward`] on `count` inputs at once (`inputs`: `count` ×
    /// [`BassNet::input_len`] values; `a`, `b`: `count` × [`BassNet::width`]; `out`: `count`
    /// × `candidates + 1`): row `h` of `out` is [`BassNet::forward`] of input `h`, bit for
    /// bit, and each weight is read once for the batch. No allocation.
    pub fn forward_batch(
        &self,
        inputs: &[f32],
        count: usize,
        a: &mut [f32],
        b: &mut [f32],
        out: &mut [f32],
    ) {
        let z = crate::nn::mlp::run_layers_batch(&self.layers, inputs, count, a, b);
        let k = self.candidates + 1;
        for (zr, or) in z.chunks_exact(k).zip(out.chunks_exact_mut(k)).take(count) {
            let mx = zr.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            let lse = mx + zr.iter().map(|&v| (v - mx).exp()).sum::<f32>().ln();
            for (o, &v) in or.iter_mut().zip(zr) {
                *o = v - lse;
            }
        }
    }

    /// The mean of this model's and `other`'s probabilities, as log-probabilities into `out`:
    /// `log(½·p₁ + ½·p₂)` per class (module docs, "The lead models and their ensemble");
    /// `other` must read the same input and have the same classes. `scratch` (one value per
    /// class) holds `other`'s log-probabilities; `a`, `b` as [`BassNet::forward`]. No
    /// allocation.
    pub fn forward_mean(
        &self,
        other: &BassNet,
        input: &[f32],
        a: &mut [f32],
        b: &mut [f32],
        out: &mut [f32],
        scratch: &mut [f32],
    ) {
        self.forward_ensemble_batch(&[other], input, 1, a, b, out, scratch);
    }

    /// The mean of this model's and every one of `others`' probabilities over `count`
    /// inputs, as log-probabilities into `out`: `log(Σᵢ pᵢ / n)` per class over the `n =
    /// 1 + others.len()` models, computed as `m + ln(Σᵢ exp(lᵢ − m) / n)` with `m` the
    /// largest log-probability (for two models the very bits of [`BassNet::forward_mean`]).
    /// `scratch` holds `others.len()` × `count` × `candidates + 1` values; the rest as
    /// [`BassNet::forward_batch`]. No allocation.
    #[allow(clippy::too_many_arguments)] // the batch's shapes
    pub fn forward_ensemble_batch(
        &self,
        others: &[&BassNet],
        inputs: &[f32],
        count: usize,
        a: &mut [f32],
        b: &mut [f32],
        out: &mut [f32],
        scratch: &mut [f32],
    ) {
        let k = count * (self.candidates + 1);
        self.forward_batch(inputs, count, a, b, out);
        for (o, s) in others.iter().zip(scratch.chunks_exact_mut(k)) {
            o.forward_batch(inputs, count, a, b, s);
        }
        let n = (1 + others.len()) as f32;
        for (i, l) in out[..k].iter_mut().enumerate() {
            let mut m = *l;
            for j in 0..others.len() {
                m = m.max(scratch[j * k + i]);
            }
            let mut sum = (*l - m).exp();
            for j in 0..others.len() {
                sum += (scratch[j * k + i] - m).exp();
            }
            *l = m + (sum / n).ln();
        }
    }
}

/// The front end (steps 1 and 2 of the module docs) for frames of `frame` samples at
/// `sample_rate`, zero-padded to `n_fft`.
pub struct BassFront {
    fft: FrameFft,
    /// FFT bin range `(lo, hi)` per band.
    ranges: Vec<(usize, usize)>,
    /// Power per FFT bin of the frame in hand (scratch, `n_fft / 2 + 1` values).
    power: Vec<f32>,
    /// Peak of the last frame before normalisation (its level).
    pub last_peak: f32,
}

impl std::fmt::Debug for BassFront {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BassFront")
            .field("n_fft", &self.fft.n_fft())
            .finish_non_exhaustive()
    }
}

impl BassFront {
    /// A front end of `bands` bands from `low_hz` (a model's: [`BassNet::bands`],
    /// [`BassNet::low_hz`]); every band must lie below Nyquist.
    pub fn with_bands(
        sample_rate: u32,
        frame: usize,
        n_fft: usize,
        bands: usize,
        low_hz: f32,
    ) -> Result<BassFront, ConfigError> {
        if frame < 8 || n_fft < frame || !n_fft.is_multiple_of(2) {
            return Err(ConfigError::invalid("bass front end", "frame and n_fft"));
        }
        ConfigError::require(bands > 0, "bass front end", "at least one band")?;
        let df = sample_rate as f64 / n_fft as f64;
        let nyq = n_fft / 2;
        let half = 2f64.powf(1.0 / (6.0 * BINS_PER_SEMITONE as f64));
        let mut ranges = Vec::with_capacity(bands);
        for b in 0..bands {
            let f = low_hz as f64 * (b as f64 / (12.0 * BINS_PER_SEMITONE as f64)).exp2();
            let lo = ((f / half / df).round() as usize).max(1);
            let hi = ((f * half / df).round() as usize).max(lo);
            if hi > nyq {
                return Err(ConfigError::invalid(
                    "bass front end",
                    "sample rate too low for the bands",
                ));
            }
            ranges.push((lo, hi));
        }
        Ok(BassFront {
            fft: FrameFft::new(frame, n_fft),
            ranges,
            power: vec![0.0; nyq + 1],
            last_peak: 0.0,
        })
    }

    /// Bands of the front end.
    pub fn bands(&self) -> usize {
        self.ranges.len()
    }

    /// Bands of `frame` into `out` ([`BassFront::bands`] values); false (and zeros) when the
    /// frame is silent.
    pub fn features(&mut self, frame: &[f32], out: &mut [f32]) -> bool {
        let peak = self.fft.analyse(frame);
        let spec = std::mem::take(&mut self.fft.spec);
        let voiced = self.features_from_spectrum(&spec, peak, out);
        self.fft.spec = spec;
        voiced
    }

    /// [`BassFront::features`] from a spectrum already computed by a [`FrameFft`] of the same
    /// frame and FFT length (`peak = None`: the frame was silent), as the harmonic sum's own
    /// is: the same values bit for bit, without a second FFT.
    pub(crate) fn features_from_spectrum(
        &mut self,
        spec: &[realfft::num_complex::Complex<f32>],
        peak: Option<f32>,
        out: &mut [f32],
    ) -> bool {
        let nb = self.ranges.len();
        out[..nb].fill(0.0);
        self.last_peak = 0.0;
        let Some(peak) = peak else {
            return false;
        };
        self.last_peak = peak;
        // Each bin's power (in vector registers: no bin depends on another), then each
        // band's (its largest bin's), floored at 1e-24. A power may be NaN (a NaN frame) but
        // is never −0, and the running maximum starts at 0, so `max_skip_nan` is `f32::max`
        // here.
        let (first, last) = (self.ranges[0].0, self.ranges[nb - 1].1);
        for (p, c) in self.power[first..=last].iter_mut().zip(&spec[first..=last]) {
            *p = c.re * c.re + c.im * c.im;
        }
        let mut loudest = 1e-24f32;
        for (o, &(lo, hi)) in out.iter_mut().zip(&self.ranges) {
            let mut mx = 0.0f32;
            for &p in &self.power[lo..=hi] {
                mx = crate::max_skip_nan(mx, p);
            }
            *o = mx.max(1e-24);
            loudest = loudest.max(*o);
        }
        // In dB. A band more than 63 dB under the loudest ends at 0 below, whatever the last
        // bit of its logarithm (the range is 60 dB), and cannot be the top: its logarithm
        // is not taken (-∞ clamps to the same 0), so the values are those of taking every one.
        let quiet = loudest * QUIET_POWER;
        let mut top = f32::NEG_INFINITY;
        for o in out[..nb].iter_mut() {
            if *o >= quiet {
                let db = 10.0 * o.log10();
                *o = db;
                top = top.max(db);
            } else {
                *o = f32::NEG_INFINITY;
            }
        }
        for o in out[..nb].iter_mut() {
            *o = ((*o - top + RANGE_DB) / RANGE_DB).clamp(0.0, 1.0);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::{BassFront, BANDS, LOW_HZ};
    use crate::spectrum::FrameFft;

    #[test]
    fn features_from_a_shared_spectrum_are_the_features_bit_for_bit() {
        // The learned bass tracker hands the network the harmonic sum's spectrum of the same
        // frame (same frame and FFT length) instead of a second FFT: same bands, same bits,
        // silent frames included.
        let (sr, frame, n_fft) = (4900u32, 1024usize, 2048usize);
        let mut own = BassFront::with_bands(sr, frame, n_fft, BANDS, LOW_HZ).unwrap();
        let mut shared = BassFront::with_bands(sr, frame, n_fft, BANDS, LOW_HZ).unwrap();
        let mut fft = FrameFft::new(frame, n_fft);
        let (mut a, mut b) = (vec![0.0f32; BANDS], vec![0.0f32; BANDS]);
        for (k, f0) in [41.2f32, 55.0, 98.0, 0.0].into_iter().enumerate() {
            let x: Vec<f32> = (0..frame)
                .map(|i| {
                    let t = i as f32 / sr as f32;
                    (1..=5)
                        .map(|h| (std::f32::consts::TAU * f0 * h as f32 * t).sin() / h as f32)
                        .sum::<f32>()
                        * 0.3
                        + 0.01 * ((i * 7919 + k) % 13) as f32 / 13.0 * (f0 > 0.0) as u8 as f32
                })
                .collect();
            let va = own.features(&x, &mut a);
            let peak = fft.analyse(&x);
            let vb = shared.features_from_spectrum(&fft.spec, peak, &mut b);
            assert_eq!(va, vb, "frame {k}");
            assert_eq!(va, f0 > 0.0, "frame {k}: silent only when it is");
            assert_eq!(own.last_peak.to_bits(), shared.last_peak.to_bits());
            for (p, q) in a.iter().zip(&b) {
                assert_eq!(p.to_bits(), q.to_bits(), "frame {k}");
            }
        }
    }

    /// The front end's bands from a spectrum the obvious way: every band's logarithm taken.
    fn bands_every_log(f: &BassFront, spec: &[realfft::num_complex::Complex<f32>]) -> Vec<f32> {
        let db: Vec<f32> = f
            .ranges
            .iter()
            .map(|&(lo, hi)| {
                let mx = spec[lo..=hi]
                    .iter()
                    .fold(0.0f32, |m, c| m.max(c.re * c.re + c.im * c.im));
                10.0 * mx.max(1e-24).log10()
            })
            .collect();
        let top = db.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        db.iter()
            .map(|&d| ((d - top + super::RANGE_DB) / super::RANGE_DB).clamp(0.0, 1.0))
            .collect()
    }

    #[test]
    fn skipped_logarithms_change_no_band() {
        use realfft::num_complex::Complex;
        let (sr, frame, n_fft) = (4900u32, 1024usize, 2048usize);
        let mut front = BassFront::with_bands(sr, frame, n_fft, BANDS, LOW_HZ).unwrap();
        let mut seed = 0x1234_5677u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let mut out = vec![0.0f32; BANDS];
        // Spectra spread over 160 dB, or bunched around the 60 and 63 dB lines under the
        // loudest bin, or all but silent (the 1e-24 floor), or all zero.
        for case in 0..40 {
            let spec: Vec<Complex<f32>> = (0..n_fft / 2 + 1)
                .map(|i| {
                    let db = match case % 4 {
                        0 => -160.0 * rnd(),
                        1 => -58.0 - 7.0 * rnd() - if i == 100 { -60.0 } else { 0.0 },
                        2 => -250.0 - 30.0 * rnd(),
                        _ => f32::NEG_INFINITY,
                    };
                    let a = 10f32.powf(db / 20.0);
                    Complex::new(a * (rnd() - 0.5), a * (rnd() - 0.5))
                })
                .collect();
            assert!(front.features_from_spectrum(&spec, Some(1.0), &mut out));
            for (b, (g, w)) in out.iter().zip(bands_every_log(&front, &spec)).enumerate() {
                assert_eq!(g.to_bits(), w.to_bits(), "case {case} band {b}");
            }
        }
    }
}
