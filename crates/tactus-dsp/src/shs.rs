//! Bass-line and lead-melody tracking for mixtures: harmonic-sum (subharmonic summation)
//! salience with fixed-lag Viterbi over the candidates.
//!
//! After Hermes, "Measurement of pitch by subharmonic summation", JASA 83(1), 1988 (the
//! salience), Klapuri, "Multiple fundamental frequency estimation by summing harmonic
//! amplitudes", ISMIR 2006 (the max over each harmonic's neighbourhood, decaying weights)
//! and Goto, "A real-time music-scene-description system: predominant-F0 estimation for
//! detecting melody and bass lines in real-world audio signals", Speech Communication 43(4),
//! 2004 (a bass line is the lowest strong harmonic source, tracked with continuity). The
//! Viterbi is pYIN's idea ([`crate::pyin`]): the pitch of a frame is decided together with its
//! neighbours, with a fixed lag when streaming.
//!
//! ## Algorithm (per hop)
//! 1. **Spectrum.** The frame (`frame` samples centred on the hop, see [`Framer`]) minus its
//!    mean, scaled to unit peak, times a Hann window, zero-padded to `n_fft`, real FFT;
//!    `A_k = |X_k|^compress`.
//! 2. **Salience** of each candidate f0 on a log grid (`bins_per_semitone` per semitone over
//!    `[fmin, fmax]`):
//!    `S(f) = tilt(f) · Σ_{h=1..H, h·f ≤ max_harmonic_hz} w^{h−1} · max_{k ∈ K(h·f)} A_k`, where
//!    `K(x)` are the FFT bins within ± `harmonic_width_st` semitones of `x` (below Nyquist),
//!    `w` = `harmonic_decay` and `tilt(f) = (f / fmin)^(−low_tilt)` can favour the lowest of
//!    several harmonic sources (off by default: it pulls plucked basses an octave down).
//!    Decaying weights make `f` beat both `f/2` (which only collects every other harmonic)
//!    and `2f`.
//! 3. **Observation.** Voiced candidate `c`: `log(V · p_c)` with
//!    `p_c = (S_c / max S)^γ` (γ = `sharpness`); unvoiced: `log(1 − V)`. The voicing evidence
//!    `V = σ((ln(peak / floor) − ln r0) / 0.5)` compares the best harmonic sum with what noise
//!    of the same spectrum level would give (`floor` = mean `A_k` over the searched band times
//!    `Σ w^{h−1}`), clamped to `[0.02, 0.98]`; a silent frame has `V = 0.02`.
//! 4. **HMM** with `M` voiced states (the candidates) and one unvoiced state. Voiced → voiced:
//!    triangular weights over `±max_jump_bins`, 1 for staying (peak-normalised, so that the
//!    voiced layer pays nothing for having a pitch that the unvoiced state lacks), times
//!    `1 − switch_prob`; voiced ↔ unvoiced (into any bin): `switch_prob`.
//! 5. **Decoding**: Viterbi in the log domain, O(M · (2·max_jump_bins + 1)) per hop, with a
//!    fixed lag: once hop `t` is observed, hop `t − lag_hops` is decided by backtracking from
//!    the best current state (exactly offline Viterbi when `lag_hops ≥` the track's hops).
//! 6. **Output.** A voiced hop reports the candidate's f0 refined by a parabola through the
//!    salience of the decided candidate and its neighbours (the grid is 1/`bins_per_semitone`
//!    of a semitone).
//! 7. **Contour voicing** (`contour_gate_db` > 0; after Salamon & Gómez, "Melody extraction
//!    from polyphonic music signals using pitch contour characteristics", IEEE TASLP 20(6),
//!    2012, where contours whose mean salience falls well below the track's are dropped).
//!    A *contour* is a run of decoded voiced, non-silent hops whose bins move by at most
//!    `contour_jump_bins` from hop to hop. Its level at hop `h` is
//!    `L_h = 20·log10(S_h(c_h) · peak_h)`, the harmonic sum of the decoded candidate in the
//!    input's units (`peak_h` undoes the frame's normalisation). When hop `h` is decided
//!    (at hop `t = h + lag_hops`), its contour's mean level is taken over the contour's
//!    emitted hops up to `h` and, along the provisional path backtracked from the best
//!    state at `t`, its hops after `h` up to `t` (so no latency is added; offline, where
//!    the whole track is decoded at the end, this is the whole contour). The reference is
//!    the running mean of `L` over the emitted voiced hops, `R ← R + w·(L_h − R)` with
//!    `w = max(1/n, hop / contour_ref_s)` (the plain mean for the first `contour_ref_s`
//!    seconds). The hop is reported unvoiced when the contour mean is below
//!    `R − contour_gate_db`. Off by default; the engine turns it on (6 dB) for the lead on a
//!    band of the mix, where the chords left in the vocals band keep a pitch through the
//!    lead's rests.
//! 8. **Register prior** (`register_sigma_st` > 0). A bass line keeps to its register, while
//!    a drum's body or a chord's common subharmonic pulls single hops an octave or a fifth
//!    under it. Once `register_min_hops` voiced hops have been decided, every voiced
//!    candidate's observation gets `−(c − μ)² / (2σ²)` (bins; σ = `register_sigma_st` ×
//!    `bins_per_semitone`), where `μ` is the running mean of the decided voiced bins,
//!    `μ ← μ + w·(c_h − μ)` with `w = max(1/n, hop / register_s)`: a hop observed at `t`
//!    sees the decisions up to `t − lag_hops − 1`, so the prior is causal and adds no
//!    latency (and a decoder whose lag covers the whole track never applies it). Off by
//!    default; the engine turns it on (σ = 12 semitones) for the bass of a mix, where on
//!    the tuning songs it moved bass RPA from 0.80 / 0.85 / 0.89 to 0.82 / 0.89 / 0.90
//!    (sung, chorales, timgm mixes; `benches/bass_eval.py`).
//! 9. **Attack alignment** (`attack_rise_db` > 0, harmonic sum only). A soundfont's lead
//!    or choir patch holds the old note's release over the new note's slow attack, so the
//!    decoded change comes 50–150 ms after the note starts (README, "The clean chorales'
//!    and instrumental leads' late note changes"). When hop `h` is decided (at `t = h +
//!    lag_hops`) as a voiced note `A`, the provisional path backtracked from the best state
//!    at `t` is read for the hops after `h`: if it leaves `A` for a note `B` in one step of
//!    at least a semitone, every hop up to that jump voiced and sounding, `B` held for
//!    [`ATTACK_HOLD_HOPS`] hops (within a bin), and the frame's band level (the mean
//!    power over the searched band, in dB of the input's units) rises from `h` to the
//!    jump by at least `attack_rise_db` in all and falls by no more than that from one hop
//!    to the next, hop `h` reports `B` (refined on its own salience). A cross-fade between
//!    two sung notes need not raise the band level, so with `attack_salience_ratio` = r > 0
//!    hop `h` also reports `B` (same jump and hold) when `B` already sounds there, its
//!    salience (the largest within a bin of `B`) at least r times `A`'s at `h`, and it
//!    grows towards the jump, falling by no more than [`ATTACK_SALIENCE_TOL`] from one hop
//!    to the next; the band level's fall then does not end the search. The decoded state
//!    still drives everything else (contour voicing, register, the Viterbi), and
//!    [`Shs::process_both`] gives both. No latency is added: only the lag is read. Off by
//!    default; the engine turns it on (0.5 dB, r = 0.3) for a lead that comes as its own
//!    stem.
//!
//! ## Defaults ([`ShsConfig::new`])
//! Range 35–400 Hz (the bass stem of docs/design.md); hop 10 ms; frame = the power of two nearest
//! 200 ms (1024 samples at the bass chain's 4.9 kHz: a 3 Hz semitone at 50 Hz needs the
//! length); `n_fft` = 2 × frame (4 × gains nothing measurable and costs about 4 % more CPU per render);
//! H = 6 harmonics, w = 0.8, each searched ± 1/4 semitone,
//! **only harmonics below 320 Hz** (the spectral separator's bass band ends there, so an
//! isolated stem and a separated one look alike; with the whole band a bassoon's formant
//! pulls the sum to its 2nd and 3rd harmonics: isolated-stem RPA 0.60 instead of 0.96 on the
//! tuned songs); no low tilt, no compression; 3 bins per semitone, γ = 2, r0 = 3, max jump
//! 36 bins (an octave), switch probability 0.02, lag 10 hops. Tuned on 4 chorales of the
//! corpus (`benches/bass_eval.py`), never on the held-out songs.
//!
//! ## Melody defaults ([`ShsConfig::melody`])
//! For the lead (the vocals stem, 70–1400 Hz): frame = the power of two nearest 70 ms (1024
//! samples at the vocal chain's 14.7 kHz: vibrato and sung glides move within 200 ms);
//! H = 8 harmonics up to 5 kHz (a voice's or a lead synth's upper harmonics are what
//! separate it from the chords under it), each searched ± 0.15 semitone; r0 = 6 (chords sound
//! between the lead's phrases, so voicing needs a clearer peak). Everything else as for the
//! bass. Chosen on the drum corpus's `timgm` mixes and the chorales' mono mixes against pYIN
//! (vocals RPA on the mix 0.56 → 0.86 and 0.35 → 0.77; on isolated stems 0.90 → 0.94 and
//! 0.87 → 0.91), never on the held-out families.
//!
//! ## Learned salience
//! With [`ShsConfig::learned`] the Viterbi decodes a network's log-probabilities of the
//! candidates and of "no pitch" ([`crate::bassnet`]) instead of the harmonic sum's (blended
//! with it by [`ShsConfig::learned_blend`]). Its estimates say how sure the network is of the
//! decided pitch: a voiced hop's `aperiodicity` is `1 − Σ p` over the network's probabilities
//! of the candidates within [`CONFIDENCE_BINS`] of the decided one (2 bins: ⅔ semitone), its
//! `voiced_prob` the network's `1 − p(no pitch)`. (The harmonic sum's estimates keep
//! `aperiodicity = 1 − voiced_prob`.) The engine narrows a mixture's lead's and bass's level
//! ranges to the hops it is sure of ([`crate::discretize`] module docs, "Narrowed to the sure
//! hops").
//!
//! ## Latency
//! `frame − frame / 2` (the framer) + `lag_hops × hop` samples, stated by
//! [`HopStage::latency_samples`] and checked against a step in the tests.
//! The contour voicing adds nothing: it looks ahead only along the Viterbi's own lag; the
//! register prior looks only back.
//!
//! No allocation after [`Shs::new`]: FFT plan, scratch, the harmonic-bin table, the Viterbi
//! scores and a ring of `lag_hops + 1` hops of backpointers and salience are allocated up
//! front.

use std::sync::Arc;

use realfft::num_complex::Complex;
use realfft::{RealFftPlanner, RealToComplex};

use crate::bassnet::{BassFront, BassNet};
use crate::framer::Framer;
use crate::yin::PitchEstimate;
use crate::{ConfigError, HopStage};

/// The Hann window of step 1, `n` samples, sampled at the centres `(i + 0.5) / n`.
pub(crate) fn hann(n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let x = std::f64::consts::PI * 2.0 * (i as f64 + 0.5) / n as f64;
            (0.5 - 0.5 * x.cos()) as f32
        })
        .collect()
}

/// Step 1 of the module docs before the FFT: `frame` (at most `window.len()` samples) minus
/// its mean, scaled to unit peak, times `window`, into `buf`, zero-padded; the peak before
/// scaling, or `None` (and `buf` unscaled) when the frame is silent or not finite.
pub(crate) fn prepare_frame(frame: &[f32], window: &[f32], buf: &mut [f32]) -> Option<f32> {
    let n = frame.len().min(window.len());
    let mean = frame[..n].iter().map(|&x| f64::from(x)).sum::<f64>() / n.max(1) as f64;
    let mut peak = 0.0f32;
    for (i, (b, &x)) in buf.iter_mut().zip(&frame[..n]).enumerate() {
        let v = (f64::from(x) - mean) as f32;
        peak = peak.max(v.abs());
        *b = v * window[i];
    }
    buf[n..].fill(0.0);
    if peak.is_nan() || peak <= 1e-9 {
        return None;
    }
    for b in &mut buf[..n] {
        *b /= peak;
    }
    Some(peak)
}

/// Step 1 of the module docs, planned once: a frame through [`prepare_frame`] (Hann window
/// of `frame` samples, zero-padded to `n_fft`) and a real FFT. Shared by the harmonic sum and
/// the learned salience's front end ([`crate::bassnet::BassFront`]).
pub(crate) struct FrameFft {
    fwd: Arc<dyn RealToComplex<f32>>,
    window: Vec<f32>,
    buf: Vec<f32>,
    scratch: Vec<Complex<f32>>,
    /// The last analysed frame's spectrum (`n_fft / 2 + 1` bins).
    pub(crate) spec: Vec<Complex<f32>>,
}

impl FrameFft {
    pub(crate) fn new(frame: usize, n_fft: usize) -> Self {
        let fwd = RealFftPlanner::<f32>::new().plan_fft_forward(n_fft);
        FrameFft {
            spec: fwd.make_output_vec(),
            scratch: fwd.make_scratch_vec(),
            window: hann(frame),
            buf: vec![0.0; n_fft],
            fwd,
        }
    }

    /// FFT length.
    pub(crate) fn n_fft(&self) -> usize {
        self.buf.len()
    }

    /// The spectrum of `frame` into [`FrameFft::spec`]; the frame's peak before scaling, or
    /// `None` when it is silent or not finite (the spectrum is then stale).
    pub(crate) fn analyse(&mut self, frame: &[f32]) -> Option<f32> {
        let peak = prepare_frame(frame, &self.window, &mut self.buf)?;
        self.fwd
            .process_with_scratch(&mut self.buf, &mut self.spec, &mut self.scratch)
            .ok()?;
        Some(peak)
    }
}

/// Floor for probabilities before the logarithm.
const P_FLOOR: f32 = 1e-30;

/// Parameters of [`Shs`]. Build with [`ShsConfig::new`]; [`Shs::new`] validates.
#[derive(Clone, Debug, PartialEq)]
pub struct ShsConfig {
    /// Sample rate in Hz.
    pub sample_rate: u32,
    /// Samples per analysis frame (Hann window length).
    pub frame: usize,
    /// FFT length (≥ frame; zero padding).
    pub n_fft: usize,
    /// Samples between hops.
    pub hop: usize,
    /// Lowest candidate f0, Hz.
    pub fmin_hz: f32,
    /// Highest candidate f0, Hz.
    pub fmax_hz: f32,
    /// Harmonics summed.
    pub harmonics: usize,
    /// Weight ratio between consecutive harmonics.
    pub harmonic_decay: f32,
    /// Exponent of the low-pitch preference `(f / fmin)^(−low_tilt)`.
    pub low_tilt: f32,
    /// Magnitude compression: the salience sums `|X_k|^compress` (1 = plain magnitudes;
    /// below 1 whitens the spectrum, so a weak fundamental under a strong formant counts).
    pub compress: f32,
    /// Harmonics above this frequency (Hz) are not summed: the salience sees the same band
    /// whether the stem is isolated or comes from a separator's low band.
    pub max_harmonic_hz: f32,
    /// Half-width, in semitones, of the neighbourhood searched around each harmonic.
    pub harmonic_width_st: f32,
    /// Fundamental presence: a candidate's sum is scaled by `min(1, r / fundamental_ratio)`,
    /// where `r` is its fundamental's magnitude over its strongest summed harmonic. A
    /// subharmonic that no source sounds (the `f/2` or `f/3` that explains a bass note and
    /// a chord tone together, common when a mixture's low band still holds chords) has
    /// `r ≈ 0`. 0 (the default) turns it off: on a clean bass stem it costs the weak
    /// fundamentals of low plucked notes (octave-up errors).
    pub fundamental_ratio: f32,
    /// Candidate bins per semitone.
    pub bins_per_semitone: u32,
    /// Exponent γ turning salience into candidate probabilities.
    pub sharpness: f32,
    /// Peak-to-noise ratio of the harmonic sum at which the voicing evidence is 0.5.
    pub voicing_ratio: f32,
    /// Largest pitch change between hops, in bins.
    pub max_jump_bins: usize,
    /// Probability of switching voiced ↔ unvoiced between hops.
    pub switch_prob: f32,
    /// Fixed Viterbi lag in hops.
    pub lag_hops: usize,
    /// Contour voicing: a decoded voiced hop is reported unvoiced when the mean level of
    /// its contour (dB of the harmonic sum, see the module docs) lies more than this many dB
    /// below the running mean over the track's voiced hops. 0 turns it off.
    pub contour_gate_db: f32,
    /// Largest jump between consecutive hops of one contour, in bins.
    pub contour_jump_bins: usize,
    /// Time constant of the running reference level, seconds.
    pub contour_ref_s: f32,
    /// Register prior: the width σ, in semitones, of a Gaussian around the running mean
    /// of the decided voiced pitch that weighs every candidate (see the module docs,
    /// "Register prior"). 0 turns it off.
    pub register_sigma_st: f32,
    /// Time constant of the register's running mean, seconds.
    pub register_s: f32,
    /// Decided voiced hops before the register prior applies.
    pub register_min_hops: usize,
    /// The learned salience ([`crate::bassnet`], the embedded model) in place of the
    /// harmonic sum: the Viterbi decodes the network's log-probabilities of the candidates
    /// and of "no bass" (see the module docs, "Learned salience"). Needs the model's
    /// candidate grid (35–400 Hz, 3 per semitone). Off by default.
    pub learned: bool,
    /// With [`ShsConfig::learned`]: the weight `β` of the harmonic sum's own observation
    /// log-probabilities added to the network's (a product of experts,
    /// `p_net · p_shs^β`; see the module docs, "Learned salience"). 0 = the network alone.
    pub learned_blend: f32,
    /// With [`ShsConfig::learned`]: nats taken from the network's "no pitch"
    /// log-probability before decoding, so that the tracker voices more readily than the
    /// network alone (the lead's voicing veto, [`crate::pair::VoicingPitchPair::with_veto`]).
    /// 0 = the network's own odds.
    pub learned_voicing_nats: f32,
    /// With [`ShsConfig::learned`] on the lead's grid: the candidates' probabilities are the
    /// mean of the embedded lead models' ([`BassNet::embedded_lead`] and
    /// [`BassNet::embedded_lead_others`]: three since 2026-11-28), `log(Σᵢ pᵢ / n)` per
    /// candidate and for "no pitch" ([`crate::bassnet`] module docs, "The lead models and
    /// their ensemble"). Errors on the bass grid. Off by default.
    pub learned_ensemble: bool,
    /// With [`ShsConfig::learned`]: the harmonic-view models, trained on the spectral
    /// separator's harmonic sum (vocals + bass + other). On the lead's grid
    /// [`BassNet::embedded_lead_harmonic`] (with [`ShsConfig::learned_ensemble`] also
    /// [`BassNet::embedded_lead_harmonic_others`]), and the tracker must be fed that sum
    /// ([`crate::pair::VoicingPitchPair::process_two`]); on the bass grid
    /// [`BassNet::embedded_bass_harmonic`], whose network reads the sum given as the view of
    /// [`Shs::process_view`] ([`crate::bassnet`] module docs, "The harmonic view"). Off by
    /// default.
    pub learned_harmonic: bool,
    /// Attack alignment of a clean lead's note changes (module docs, step 9): a decided
    /// voiced hop reports the note the provisional path jumps to within the lag when the
    /// frame's band level rises from the hop to the jump by at least this many dB (and
    /// falls by no more than that in any one hop). 0 turns it off. Harmonic sum only (a
    /// learned salience has no band level here).
    pub attack_rise_db: f32,
    /// With [`ShsConfig::attack_rise_db`] > 0: the attack alignment also moves a note change
    /// back to a hop where the new note's salience is at least this share of the old one's
    /// and grows towards the change (module docs, step 9). 0 turns it off.
    pub attack_salience_ratio: f32,
}

/// The power of two nearest `target` samples (rounding down when the next one up is more
/// than 1.5 times it): the analysis frame of the presets.
fn pow2_frame(target: f64) -> usize {
    let up = (target as usize).next_power_of_two();
    if (up as f64) / target > 1.5 {
        up / 2
    } else {
        up
    }
}

impl ShsConfig {
    /// The defaults of the module docs for a search range at `sample_rate`.
    pub fn new(sample_rate: u32, fmin_hz: f32, fmax_hz: f32) -> Self {
        let target = (sample_rate as f64 * 0.2).max(8.0);
        let frame = pow2_frame(target);
        ShsConfig {
            sample_rate,
            frame,
            n_fft: 2 * frame,
            hop: ((sample_rate as f64 * 0.010).round() as usize).max(1),
            fmin_hz,
            fmax_hz,
            harmonics: 6,
            harmonic_decay: 0.8,
            low_tilt: 0.0,
            compress: 1.0,
            harmonic_width_st: 0.25,
            fundamental_ratio: 0.0,
            max_harmonic_hz: 320.0,
            bins_per_semitone: 3,
            sharpness: 2.0,
            voicing_ratio: 3.0,
            max_jump_bins: 36,
            switch_prob: 0.02,
            lag_hops: 10,
            contour_gate_db: 0.0,
            contour_jump_bins: 6,
            contour_ref_s: 10.0,
            register_sigma_st: 0.0,
            register_s: 10.0,
            register_min_hops: 200,
            learned: false,
            learned_blend: 0.0,
            learned_voicing_nats: 0.0,
            learned_ensemble: false,
            learned_harmonic: false,
            attack_rise_db: 0.0,
            attack_salience_ratio: 0.0,
        }
    }

    /// The melody defaults of the module docs (a lead voice or instrument, e.g. 70–1400 Hz).
    pub fn melody(sample_rate: u32, fmin_hz: f32, fmax_hz: f32) -> Self {
        let target = (sample_rate as f64 * 0.07).max(8.0);
        let frame = pow2_frame(target);
        ShsConfig {
            frame,
            n_fft: 2 * frame,
            harmonics: 8,
            max_harmonic_hz: 5000.0,
            harmonic_width_st: 0.15,
            voicing_ratio: 6.0,
            ..ShsConfig::new(sample_rate, fmin_hz, fmax_hz)
        }
    }

    /// Number of candidates M, or why the configuration is invalid.
    pub fn n_bins(&self) -> Result<usize, ConfigError> {
        if self.sample_rate == 0 {
            return Err(ConfigError::invalid("sample_rate", "must be positive"));
        }
        if !(self.fmin_hz.is_finite() && self.fmin_hz > 0.0) {
            return Err(ConfigError::invalid("fmin_hz", "must be finite and > 0"));
        }
        if !(self.fmax_hz.is_finite()
            && self.fmax_hz > self.fmin_hz
            && (self.fmax_hz as f64) < self.sample_rate as f64 / 2.0)
        {
            return Err(ConfigError::invalid(
                "fmax_hz",
                "must be finite, > fmin_hz and below Nyquist",
            ));
        }
        if !(8..=1 << 20).contains(&self.frame) {
            return Err(ConfigError::invalid("frame", "must be in [8, 2^20]"));
        }
        if self.n_fft < self.frame || self.n_fft > 1 << 22 || !self.n_fft.is_multiple_of(2) {
            return Err(ConfigError::invalid(
                "n_fft",
                "must be even, ≥ frame and ≤ 2^22",
            ));
        }
        if self.hop == 0 {
            return Err(ConfigError::invalid("hop", "must be at least 1 sample"));
        }
        if !(1..=32).contains(&self.harmonics) {
            return Err(ConfigError::invalid("harmonics", "must be in 1..=32"));
        }
        if !(self.harmonic_decay > 0.0 && self.harmonic_decay <= 1.0) {
            return Err(ConfigError::invalid("harmonic_decay", "must be in (0, 1]"));
        }
        if !(self.low_tilt.is_finite() && self.low_tilt >= 0.0) {
            return Err(ConfigError::invalid("low_tilt", "must be finite and ≥ 0"));
        }
        if !(self.compress.is_finite() && self.compress > 0.0 && self.compress <= 2.0) {
            return Err(ConfigError::invalid("compress", "must be in (0, 2]"));
        }
        if self.max_harmonic_hz.is_nan() || self.max_harmonic_hz <= 0.0 {
            return Err(ConfigError::invalid("max_harmonic_hz", "must be > 0"));
        }
        if !(0.0..=1.0).contains(&self.fundamental_ratio) {
            return Err(ConfigError::invalid(
                "fundamental_ratio",
                "must be in [0, 1]",
            ));
        }
        if !(self.harmonic_width_st > 0.0 && self.harmonic_width_st <= 1.0) {
            return Err(ConfigError::invalid(
                "harmonic_width_st",
                "must be in (0, 1]",
            ));
        }
        if !(self.sharpness.is_finite() && self.sharpness > 0.0) {
            return Err(ConfigError::invalid("sharpness", "must be finite and > 0"));
        }
        if !(self.voicing_ratio.is_finite() && self.voicing_ratio > 0.0) {
            return Err(ConfigError::invalid(
                "voicing_ratio",
                "must be finite and > 0",
            ));
        }
        if !(self.switch_prob > 0.0 && self.switch_prob < 1.0) {
            return Err(ConfigError::invalid("switch_prob", "must be in (0, 1)"));
        }
        if !(1..=100).contains(&self.bins_per_semitone) {
            return Err(ConfigError::invalid(
                "bins_per_semitone",
                "must be in 1..=100",
            ));
        }
        let span = 12.0
            * self.bins_per_semitone as f64
            * (self.fmax_hz as f64 / self.fmin_hz as f64).log2();
        let m = span.floor() as usize + 1;
        if m + 1 > u16::MAX as usize {
            return Err(ConfigError::invalid("bins_per_semitone", "too many bins"));
        }
        if self.max_jump_bins >= m {
            return Err(ConfigError::invalid(
                "max_jump_bins",
                "must be below the number of candidates",
            ));
        }
        if !(self.contour_gate_db.is_finite() && self.contour_gate_db >= 0.0) {
            return Err(ConfigError::invalid(
                "contour_gate_db",
                "must be finite and ≥ 0",
            ));
        }
        if !(self.contour_ref_s.is_finite() && self.contour_ref_s > 0.0) {
            return Err(ConfigError::invalid(
                "contour_ref_s",
                "must be finite and > 0",
            ));
        }
        if !(self.register_sigma_st.is_finite() && self.register_sigma_st >= 0.0) {
            return Err(ConfigError::invalid(
                "register_sigma_st",
                "must be finite and ≥ 0",
            ));
        }
        if !(self.register_s.is_finite() && self.register_s > 0.0) {
            return Err(ConfigError::invalid("register_s", "must be finite and > 0"));
        }
        if !(self.learned_voicing_nats.is_finite()
            && (0.0..=20.0).contains(&self.learned_voicing_nats))
        {
            return Err(ConfigError::invalid(
                "learned_voicing_nats",
                "must be in [0, 20]",
            ));
        }
        if !(self.learned_blend.is_finite() && (0.0..=4.0).contains(&self.learned_blend)) {
            return Err(ConfigError::invalid("learned_blend", "must be in [0, 4]"));
        }
        if self.learned_harmonic && !self.learned {
            return Err(ConfigError::invalid(
                "learned_harmonic",
                "applies only to the learned salience (learned = true)",
            ));
        }
        if self.lag_hops > 1 << 20 {
            return Err(ConfigError::invalid("lag_hops", "too large"));
        }
        if !(self.attack_rise_db.is_finite() && (0.0..=40.0).contains(&self.attack_rise_db)) {
            return Err(ConfigError::invalid("attack_rise_db", "must be in [0, 40]"));
        }
        if !(self.attack_salience_ratio.is_finite()
            && (0.0..=10.0).contains(&self.attack_salience_ratio))
        {
            return Err(ConfigError::invalid(
                "attack_salience_ratio",
                "must be in [0, 10]",
            ));
        }
        Ok(m)
    }

    /// Candidate f0 of bin `c`.
    pub fn bin_hz(&self, c: usize) -> f32 {
        self.fmin_hz * (c as f32 / (12.0 * self.bins_per_semitone as f32)).exp2()
    }
}

/// Salience of one analysed frame, and the frame's voicing evidence.
struct Salience {
    fft: FrameFft,
    mag: Vec<f32>,
    /// `(k_lo, k_hi)` per (candidate, harmonic), `k_hi < k_lo` when above Nyquist.
    ranges: Vec<(u32, u32)>,
    /// `tilt(f_c) · w^{h−1}` per (candidate, harmonic).
    weights: Vec<f32>,
    /// FFT bins of the searched band, for the noise floor.
    band: (usize, usize),
    weight_sum: f32,
    harmonics: usize,
    sharp: f32,
    ln_r0: f32,
    compress: f32,
    fund_ratio: f32,
    /// Peak of the last frame before normalisation (its level).
    last_peak: f32,
    /// Mean power over the searched band of the last frame (normalised frame).
    last_band_power: f32,
}

impl std::fmt::Debug for Salience {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Salience")
            .field("n_fft", &self.fft.n_fft())
            .field("harmonics", &self.harmonics)
            .finish_non_exhaustive()
    }
}

impl Salience {
    fn new(cfg: &ShsConfig, m: usize) -> Self {
        let df = cfg.sample_rate as f64 / cfg.n_fft as f64;
        let nyq = cfg.n_fft / 2;
        let half = 2f64.powf(cfg.harmonic_width_st as f64 / 12.0);
        let h_n = cfg.harmonics;
        let mut ranges = Vec::with_capacity(m * h_n);
        let mut weights = Vec::with_capacity(m * h_n);
        for c in 0..m {
            let f = cfg.bin_hz(c) as f64;
            let tilt = (f / cfg.fmin_hz as f64).powf(-(cfg.low_tilt as f64));
            for h in 1..=h_n {
                let x = f * h as f64;
                let lo = (x / half / df).round().max(1.0) as usize;
                let hi = ((x * half / df).round() as usize).min(nyq);
                ranges.push((lo as u32, hi as u32));
                let w = if lo <= hi && x <= cfg.max_harmonic_hz as f64 {
                    tilt * (cfg.harmonic_decay as f64).powi(h as i32 - 1)
                } else {
                    0.0
                };
                weights.push(w as f32);
            }
        }
        let band_lo = ((cfg.fmin_hz as f64 / df).floor() as usize).max(1);
        let band_hi = ((cfg.fmax_hz as f64 * h_n as f64 / df).ceil() as usize)
            .min(nyq)
            .max(band_lo);
        let weight_sum = (0..h_n).map(|h| cfg.harmonic_decay.powi(h as i32)).sum();
        Salience {
            fft: FrameFft::new(cfg.frame, cfg.n_fft),
            mag: vec![0.0; nyq + 1],
            ranges,
            weights,
            band: (band_lo, band_hi),
            weight_sum,
            harmonics: h_n,
            sharp: cfg.sharpness,
            ln_r0: cfg.voicing_ratio.ln(),
            compress: cfg.compress,
            fund_ratio: cfg.fundamental_ratio,
            last_peak: 0.0,
            last_band_power: 0.0,
        }
    }

    /// Magnitude spectrum of `frame` into `mag`; false when the frame is silent.
    fn spectrum(&mut self, frame: &[f32]) -> bool {
        let Some(peak) = self.fft.analyse(frame) else {
            return false;
        };
        self.last_peak = peak;
        let e = 0.5 * self.compress;
        for (m, c) in self.mag.iter_mut().zip(&self.fft.spec) {
            let p = c.re * c.re + c.im * c.im;
            *m = if e == 0.5 { p.sqrt() } else { p.powf(e) };
        }
        let (b0, b1) = self.band;
        self.last_band_power =
            self.mag[b0..=b1].iter().map(|&a| a * a).sum::<f32>() / (b1 + 1 - b0) as f32;
        true
    }

    /// Band level of the last frame in dB, in the input's units (step 9): the mean power
    /// over the searched band (of `|X_k|^compress`). Power rather than magnitude: a frame
    /// that holds the end of one note and the start of the next has more spectral peaks but
    /// not more energy, so a change at a constant level is no rise.
    fn band_level_db(&self) -> f32 {
        let a = self.last_band_power * self.last_peak * self.last_peak;
        if a > 1e-24 {
            10.0 * a.log10()
        } else {
            SILENT_DB
        }
    }

    /// Salience per candidate into `out`; returns the voicing evidence V.
    fn salience(&self, out: &mut [f32]) -> f32 {
        let h_n = self.harmonics;
        let mut best = 0.0f32;
        for (c, s) in out.iter_mut().enumerate() {
            let mut acc = 0.0f32;
            let mut first = 0.0f32;
            let mut strongest = 0.0f32;
            for h in 0..h_n {
                let (lo, hi) = self.ranges[c * h_n + h];
                let w = self.weights[c * h_n + h];
                if lo > hi || w == 0.0 {
                    continue;
                }
                let mut mx = 0.0f32;
                for &a in &self.mag[lo as usize..=hi as usize] {
                    mx = mx.max(a);
                }
                acc += w * mx;
                if h == 0 {
                    first = mx;
                }
                strongest = strongest.max(mx);
            }
            if self.fund_ratio > 0.0 && strongest > 0.0 {
                let r = first / (strongest * self.fund_ratio);
                acc *= r.min(1.0);
            }
            *s = acc;
            best = best.max(acc);
        }
        let (b0, b1) = self.band;
        let floor = self.mag[b0..=b1].iter().sum::<f32>() / (b1 + 1 - b0) as f32 * self.weight_sum;
        if !(floor > 0.0 && best > 0.0) {
            return 0.02;
        }
        let z = ((best / floor).ln() - self.ln_r0) / 0.5;
        (1.0 / (1.0 + (-z).exp())).clamp(0.02, 0.98)
    }
}

/// The tracker's output per hop: (hop, reported estimate, decoded estimate).
type Emit<'a> = dyn FnMut(usize, PitchEstimate, PitchEstimate) + 'a;

/// Band level of a silent frame, dB.
const SILENT_DB: f32 = -240.0;

/// Hops the note a change jumps to must hold for the attack alignment (step 9).
pub const ATTACK_HOLD_HOPS: usize = 3;

/// Everything but the framer, so the framer's callback can borrow it.
#[derive(Debug)]
struct Tracker {
    sal: Salience,
    m: usize,
    lag: usize,
    ring: usize,
    max_jump: usize,
    l_stay: f32,
    l_switch: f32,
    l_enter: f32,
    /// `ln` of the triangular transition weight for a jump of `d` bins (normalised).
    l_jump: Vec<f32>,
    cfg_bin0: f32,
    bins_per_octave: f32,
    s: Vec<f32>,
    obs: Vec<f32>,
    /// Viterbi scores: `delta[..m]` voiced bins, `delta[m]` unvoiced.
    delta: Vec<f32>,
    next: Vec<f32>,
    /// Scratch of [`Tracker::step`]: per voiced bin, the best predecessor's score and index.
    best_in: Vec<f32>,
    /// The best predecessor's offset `src − k`.
    arg_in: Vec<i32>,
    /// Backpointers, `ring × (m + 1)`.
    bp: Vec<u16>,
    /// Salience per hop (ring × m), for the f0 refinement.
    sal_ring: Vec<f32>,
    silent: Vec<bool>,
    voicing: Vec<f32>,
    path: Vec<u16>,
    hops_seen: usize,
    next_emit: usize,
    /// Frame peak per hop (ring), so that the contour level is in the input's units.
    peak_ring: Vec<f32>,
    /// Band level per hop in dB (ring), for the attack alignment (step 9).
    level_ring: Vec<f32>,
    /// [`ShsConfig::attack_rise_db`].
    attack_db: f32,
    /// [`ShsConfig::attack_salience_ratio`].
    attack_ratio: f32,
    /// A jump of at least this many bins is a change of note (a semitone).
    note_jump_bins: usize,
    contour: ContourGate,
    register: Register,
    /// The learned salience's state, when [`ShsConfig::learned`].
    net: Option<Box<NetState>>,
    /// [`ShsConfig::learned`]: voiced estimates carry the network's confidence (module docs,
    /// "Learned salience"). (`net` is taken out while a batch runs, so it cannot say.)
    learned: bool,
}

impl crate::simd::ViterbiStep for Tracker {
    #[inline(always)]
    fn step(&mut self, slot: usize, l_unvoiced: f32) {
        Tracker::step(self, slot, l_unvoiced);
    }
}

/// The attack alignment's salience criterion (module docs, step 9): the new note's salience
/// may fall from one hop to the next towards the change to no less than this share.
pub const ATTACK_SALIENCE_TOL: f32 = 0.8;

/// Candidates on each side of the decided one whose probabilities a learned tracker's
/// confidence sums (module docs, "Learned salience").
pub const CONFIDENCE_BINS: usize = 2;

/// Hops the learned salience runs through its network together (see
/// [`crate::mlp::run_layers_batch`]); a block's last hops run as a smaller batch when the
/// block ends, so the outputs, and when they leave, are those of one hop at a time.
const NET_BATCH: usize = 8;

/// The learned salience's front end, context ring and scratch.
struct NetState {
    model: &'static BassNet,
    front: BassFront,
    /// Feature frames, `ring × bands`; frame `j` in slot `j % ring`.
    feats: Vec<f32>,
    silent: Vec<bool>,
    peak: Vec<f32>,
    ring: usize,
    /// Frames seen.
    frames: usize,
    /// Hops handed to the Viterbi (each `future` frames after its own).
    hops: usize,
    /// Hops whose network input is assembled (`hops..queued` wait in the batch).
    queued: usize,
    future: usize,
    /// The network's inputs for up to [`NET_BATCH`] hops, its scratch and log-probabilities
    /// per hop (`NET_BATCH` rows each).
    input: Vec<f32>,
    a: Vec<f32>,
    b: Vec<f32>,
    logp: Vec<f32>,
    /// The lead ensemble's other models ([`ShsConfig::learned_ensemble`]; empty: none) and
    /// their log-probabilities (`others.len() × NET_BATCH` rows).
    others: Vec<&'static BassNet>,
    logp2: Vec<f32>,
    /// [`ShsConfig::learned_blend`].
    blend: f32,
    /// [`ShsConfig::learned_voicing_nats`].
    voicing_nats: f32,
    /// Harmonic-sum salience per frame (ring × m, when `blend` > 0) and its voicing evidence.
    shs: Vec<f32>,
    shs_v: Vec<f32>,
}

impl std::fmt::Debug for NetState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NetState")
            .field("frames", &self.frames)
            .field("hops", &self.hops)
            .finish_non_exhaustive()
    }
}

impl NetState {
    fn new(cfg: &ShsConfig, m: usize) -> Result<NetState, ConfigError> {
        // The embedded model whose candidate grid is the tracker's: the bass model's
        // (35–400 Hz) or the lead model's (70–1400 Hz), 3 bins per semitone.
        let fits = |md: &BassNet| {
            md.candidates() == m
                && cfg.bins_per_semitone == crate::bassnet::BINS_PER_SEMITONE
                && (cfg.fmin_hz - md.cand_fmin_hz()).abs() <= 1e-3
        };
        let harmonic = cfg.learned_harmonic;
        let model = if fits(BassNet::embedded()) {
            if harmonic {
                BassNet::embedded_bass_harmonic()
            } else {
                BassNet::embedded()
            }
        } else if fits(BassNet::embedded_lead()) {
            if harmonic {
                BassNet::embedded_lead_harmonic()
            } else {
                BassNet::embedded_lead()
            }
        } else {
            return Err(ConfigError::invalid(
                "learned",
                "the learned models' candidate grids are 35-400 Hz (bass) and 70-1400 Hz \
                 (lead) at 3 bins per semitone",
            ));
        };
        let others = if !cfg.learned_ensemble {
            Vec::new()
        } else if std::ptr::eq(model, BassNet::embedded_lead()) {
            BassNet::embedded_lead_others()
        } else if std::ptr::eq(model, BassNet::embedded_lead_harmonic()) {
            BassNet::embedded_lead_harmonic_others()
        } else {
            return Err(ConfigError::invalid(
                "learned_ensemble",
                "only the lead's grid (70-1400 Hz) has a second model",
            ));
        };
        let bands = model.bands();
        // Room for the context of every hop of a batch: a hop's silence, peak and
        // harmonic sum are read when its batch runs, up to `NET_BATCH` frames later.
        let ring = model.past() + model.future() + 1 + NET_BATCH;
        let w = model.width().max(model.input_len());
        let k = m + 1;
        Ok(NetState {
            model,
            front: BassFront::with_bands(
                cfg.sample_rate,
                cfg.frame,
                cfg.n_fft,
                bands,
                model.low_hz(),
            )?,
            feats: vec![0.0; ring * bands],
            silent: vec![true; ring],
            peak: vec![0.0; ring],
            ring,
            frames: 0,
            hops: 0,
            queued: 0,
            future: model.future(),
            input: vec![0.0; NET_BATCH * model.input_len()],
            a: vec![0.0; NET_BATCH * w],
            b: vec![0.0; NET_BATCH * w],
            logp: vec![0.0; NET_BATCH * k],
            logp2: vec![0.0; others.len() * NET_BATCH * k],
            others,
            blend: cfg.learned_blend,
            voicing_nats: cfg.learned_voicing_nats,
            shs: vec![0.0; if cfg.learned_blend > 0.0 { ring * m } else { 0 }],
            shs_v: vec![0.02; ring],
        })
    }

    /// Takes the next frame's features.
    fn push(&mut self, frame: &[f32]) {
        let slot = self.frames % self.ring;
        let nb = self.model.bands();
        let f = &mut self.feats[slot * nb..(slot + 1) * nb];
        self.silent[slot] = !self.front.features(frame, f);
        self.peak[slot] = self.front.last_peak;
        self.frames += 1;
    }

    /// [`NetState::push`] from the harmonic sum's spectrum of the same frame (same frame and
    /// FFT length, so the same values), `peak = None` for a silent frame.
    fn push_spectrum(&mut self, spec: &[Complex<f32>], peak: Option<f32>) {
        let slot = self.frames % self.ring;
        let nb = self.model.bands();
        let f = &mut self.feats[slot * nb..(slot + 1) * nb];
        self.silent[slot] = !self.front.features_from_spectrum(spec, peak, f);
        self.peak[slot] = self.front.last_peak;
        self.frames += 1;
    }

    /// Hops waiting in the batch.
    fn pending(&self) -> usize {
        self.queued - self.hops
    }

    /// Assembles hop `queued`'s input (frames outside `0..frames` are zeros) into the
    /// batch's next row.
    fn queue(&mut self) {
        let h = self.queued;
        let nb = self.model.bands();
        let len = self.model.input_len();
        let row = self.pending();
        let input = &mut self.input[row * len..(row + 1) * len];
        for (k, &o) in self.model.offsets().iter().enumerate() {
            let dst = &mut input[k * nb..(k + 1) * nb];
            let j = h as i64 + i64::from(o);
            if j < 0 || j >= self.frames as i64 {
                dst.fill(0.0);
            } else {
                let slot = j as usize % self.ring;
                dst.copy_from_slice(&self.feats[slot * nb..(slot + 1) * nb]);
            }
        }
        self.queued += 1;
    }

    /// Log-probabilities of every waiting hop into `logp`, one row each.
    fn infer(&mut self) {
        let count = self.pending();
        if self.others.is_empty() {
            self.model
                .forward_batch(&self.input, count, &mut self.a, &mut self.b, &mut self.logp)
        } else {
            self.model.forward_ensemble_batch(
                &self.others,
                &self.input,
                count,
                &mut self.a,
                &mut self.b,
                &mut self.logp,
                &mut self.logp2,
            )
        }
    }

    fn reset(&mut self) {
        self.frames = 0;
        self.hops = 0;
        self.queued = 0;
        self.silent.fill(true);
    }
}

/// The register prior's state (see the module docs, "Register prior").
#[derive(Debug, Clone)]
struct Register {
    /// `1 / (2 σ²)` in bins⁻²; 0 = off.
    k: f64,
    /// Weight floor of the running mean: `hop / register_s`.
    alpha: f64,
    /// Hops of evidence before the prior applies.
    min_n: usize,
    mean: f64,
    n: usize,
}

impl Register {
    fn update(&mut self, state: usize) {
        self.n += 1;
        let w = (1.0 / self.n as f64).max(self.alpha);
        self.mean += w * (state as f64 - self.mean);
    }
}

/// The contour voicing state (see the module docs, "Contour voicing").
#[derive(Debug, Clone)]
struct ContourGate {
    gate_db: f64,
    jump: usize,
    /// Weight floor of the running mean: `hop / contour_ref_s`.
    alpha: f64,
    /// Last emitted decoded state (a bin, or `None` after an unvoiced or silent hop).
    prev: Option<usize>,
    sum: f64,
    n: usize,
    reference: f64,
    ref_n: usize,
}

impl ContourGate {
    fn reset(&mut self) {
        self.prev = None;
        self.sum = 0.0;
        self.n = 0;
        self.reference = 0.0;
        self.ref_n = 0;
    }
}

impl Tracker {
    fn new(cfg: &ShsConfig) -> Result<Self, ConfigError> {
        let m = cfg.n_bins()?;
        let ring = cfg.lag_hops + 1;
        let j = cfg.max_jump_bins;
        // Peak-normalised (staying costs nothing): the unvoiced state has no pitch to choose,
        // so a voiced state must not pay for choosing one either.
        let l_jump = (0..=j)
            .map(|d| ((j + 1 - d) as f32 / (j + 1) as f32).ln())
            .collect();
        Ok(Tracker {
            sal: Salience::new(cfg, m),
            m,
            lag: cfg.lag_hops,
            ring,
            max_jump: j,
            l_stay: (1.0 - cfg.switch_prob).ln(),
            l_switch: cfg.switch_prob.ln(),
            l_enter: cfg.switch_prob.ln(),
            l_jump,
            cfg_bin0: cfg.fmin_hz,
            bins_per_octave: 12.0 * cfg.bins_per_semitone as f32,
            s: vec![0.0; m],
            obs: vec![0.0; m],
            delta: vec![0.0; m + 1],
            next: vec![0.0; m + 1],
            best_in: vec![0.0; m],
            arg_in: vec![0; m],
            bp: vec![0; ring * (m + 1)],
            sal_ring: vec![0.0; ring * m],
            silent: vec![true; ring],
            voicing: vec![0.0; ring],
            path: vec![0; ring],
            hops_seen: 0,
            next_emit: 0,
            peak_ring: vec![0.0; ring],
            level_ring: vec![SILENT_DB; ring],
            attack_db: if cfg.learned { 0.0 } else { cfg.attack_rise_db },
            attack_ratio: cfg.attack_salience_ratio,
            note_jump_bins: cfg.bins_per_semitone as usize,
            register: Register {
                k: if cfg.register_sigma_st > 0.0 {
                    let sigma = f64::from(cfg.register_sigma_st) * f64::from(cfg.bins_per_semitone);
                    1.0 / (2.0 * sigma * sigma)
                } else {
                    0.0
                },
                alpha: (cfg.hop as f64 / cfg.sample_rate as f64 / f64::from(cfg.register_s))
                    .min(1.0),
                min_n: cfg.register_min_hops,
                mean: 0.0,
                n: 0,
            },
            contour: ContourGate {
                gate_db: cfg.contour_gate_db as f64,
                jump: cfg.contour_jump_bins,
                alpha: (cfg.hop as f64 / cfg.sample_rate as f64 / cfg.contour_ref_s as f64)
                    .min(1.0),
                prev: None,
                sum: 0.0,
                n: 0,
                reference: 0.0,
                ref_n: 0,
            },
            net: if cfg.learned {
                Some(Box::new(NetState::new(cfg, m)?))
            } else {
                None
            },
            learned: cfg.learned,
        })
    }

    fn reset(&mut self) {
        self.hops_seen = 0;
        self.next_emit = 0;
        self.contour.reset();
        self.register.mean = 0.0;
        self.register.n = 0;
        if let Some(n) = &mut self.net {
            n.reset();
        }
    }

    /// Level in dB of the harmonic sum of `state` at `hop` (in the input's units).
    fn level_db(&self, hop: usize, state: usize) -> f64 {
        let slot = hop % self.ring;
        let a = f64::from(self.sal_ring[slot * self.m + state]) * f64::from(self.peak_ring[slot]);
        if a > 1e-12 {
            20.0 * a.log10()
        } else {
            -240.0
        }
    }

    /// Contour voicing of the decoded `state` at `hop`, given the decoded states of the hops
    /// after it (`ahead`, oldest first). Updates the contour and the running reference;
    /// returns false when the hop is to be reported unvoiced.
    fn contour_voiced(&mut self, hop: usize, state: usize, ahead: &[u16]) -> bool {
        let slot = hop % self.ring;
        if self.silent[slot] || state >= self.m {
            self.contour.prev = None;
            return true;
        }
        let x = self.level_db(hop, state);
        let g = &mut self.contour;
        let same = g.prev.is_some_and(|p| p.abs_diff(state) <= g.jump);
        if !same {
            g.sum = 0.0;
            g.n = 0;
        }
        g.sum += x;
        g.n += 1;
        g.prev = Some(state);
        g.ref_n += 1;
        let w = (1.0 / g.ref_n as f64).max(g.alpha);
        g.reference += w * (x - g.reference);
        if g.gate_db <= 0.0 {
            return true;
        }
        let (jump, reference, gate_db) = (g.jump, g.reference, g.gate_db);
        let (mut sum, mut n) = (g.sum, g.n);
        let mut last = state;
        for (k, &s) in ahead.iter().enumerate() {
            let s = s as usize;
            let h = hop + 1 + k;
            if s >= self.m || self.silent[h % self.ring] || s.abs_diff(last) > jump {
                break;
            }
            sum += self.level_db(h, s);
            n += 1;
            last = s;
        }
        sum / n as f64 >= reference - gate_db
    }

    /// Step 9, the attack alignment: the state `hop` reports, given its decided `state` and
    /// the provisional path after it (`ahead`, oldest first, at most the lag). `state`
    /// itself unless the path leaves it for another note `B` in one step of at least a
    /// semitone, every hop up to that jump voiced and sounding, `B` held for
    /// [`ATTACK_HOLD_HOPS`] hops (within a bin), and the band level rising from `hop` to
    /// the jump: no hop-to-hop fall beyond `attack_db`, at least `attack_db` in all. Then
    /// `B`.
    fn aligned_state(&self, hop: usize, state: usize, ahead: &[u16]) -> usize {
        let m = self.m;
        if self.attack_db <= 0.0 || state >= m || self.silent[hop % self.ring] {
            return state;
        }
        let level = |h: usize| self.level_ring[h % self.ring];
        // The largest salience within a bin of candidate `c` at hop `h`.
        let sal = |h: usize, c: usize| {
            let row = &self.sal_ring[(h % self.ring) * m..(h % self.ring + 1) * m];
            row[c.saturating_sub(1)..(c + 2).min(m)]
                .iter()
                .fold(0.0f32, |a, &b| a.max(b))
        };
        let mut prev = state;
        // The band level has not fallen by more than `attack_db` in one hop so far.
        let mut level_ok = true;
        for (k, &s) in ahead.iter().enumerate() {
            let (s, h) = (s as usize, hop + 1 + k);
            if s >= m || self.silent[h % self.ring] {
                return state;
            }
            if level(h) < level(h - 1) - self.attack_db {
                if self.attack_ratio <= 0.0 {
                    return state;
                }
                level_ok = false;
            }
            if s.abs_diff(prev) >= self.note_jump_bins {
                let held = ahead.get(k..k + ATTACK_HOLD_HOPS).is_some_and(|run| {
                    run.iter()
                        .all(|&x| (x as usize) < m && (x as usize).abs_diff(s) <= 1)
                });
                if !held {
                    return state;
                }
                if level_ok && level(h) - level(hop) >= self.attack_db {
                    return s;
                }
                // The new note already sounds at `hop` and grows towards the jump.
                let (a, b) = (sal(hop, state), sal(hop, s));
                let grows = (hop..h).all(|x| sal(x + 1, s) >= ATTACK_SALIENCE_TOL * sal(x, s));
                return if self.attack_ratio > 0.0 && a > 0.0 && b >= self.attack_ratio * a && grows
                {
                    s
                } else {
                    state
                };
            }
            prev = s;
        }
        state
    }

    /// The register's running mean takes in the decided `state` of `hop` when it is voiced.
    fn note_register(&mut self, hop: usize, state: usize) {
        if self.register.k > 0.0 && state < self.m && !self.silent[hop % self.ring] {
            self.register.update(state);
        }
    }

    /// Observation log-probabilities of the current salience `s` with evidence `v` into `obs`;
    /// returns the unvoiced one.
    fn observe(&mut self, v: f32) -> f32 {
        let peak = self.s.iter().fold(0.0f32, |a, &b| a.max(b));
        if peak > 0.0 {
            for (o, &s) in self.obs.iter_mut().zip(&self.s) {
                *o = (v * (s.max(0.0) / peak).powf(self.sal.sharp))
                    .max(P_FLOOR)
                    .ln();
            }
        } else {
            self.obs.fill(P_FLOOR.ln());
        }
        self.apply_register();
        (1.0 - v).max(P_FLOOR).ln()
    }

    /// The register prior on the voiced observations.
    fn apply_register(&mut self) {
        let r = &self.register;
        if r.k > 0.0 && r.n >= r.min_n {
            for (c, o) in self.obs.iter_mut().enumerate() {
                let d = c as f64 - r.mean;
                *o -= (r.k * d * d) as f32;
            }
        }
    }

    /// The learned salience: frame `frames` arrives; the hop `future` frames before it
    /// goes to the Viterbi.
    fn on_net_frame(&mut self, frame: &[f32], view: Option<&[f32]>, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        if n.blend > 0.0 {
            let m = self.m;
            let slot = n.frames % n.ring;
            let dst = &mut n.shs[slot * m..(slot + 1) * m];
            let sounding = self.sal.spectrum(frame);
            n.shs_v[slot] = if sounding {
                self.sal.salience(dst)
            } else {
                dst.fill(0.0);
                0.02
            };
            let peak = sounding.then_some(self.sal.last_peak);
            match view {
                // The network on the view's frame; silence and peak stay the input's, as
                // on one stream.
                Some(v) => {
                    n.push(v);
                    n.silent[slot] = !sounding;
                    n.peak[slot] = peak.unwrap_or(0.0);
                }
                // The network's bands from the same spectrum: one FFT per frame, not two.
                None => n.push_spectrum(&self.sal.fft.spec, peak),
            }
        } else {
            n.push(view.unwrap_or(frame));
        }
        while n.queued + n.future < n.frames {
            n.queue();
            if n.pending() == NET_BATCH {
                self.run_batch(&mut n, emit);
            }
        }
        self.net = Some(n);
    }

    /// The hops still waiting for future frames (the stream has ended).
    fn drain_net(&mut self, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        while n.queued < n.frames {
            n.queue();
            if n.pending() == NET_BATCH {
                self.run_batch(&mut n, emit);
            }
        }
        self.run_batch(&mut n, emit);
        self.net = Some(n);
    }

    /// Runs the hops waiting in the batch, if any (the end of a block: whatever a block
    /// makes ready leaves with it, so batching adds no latency).
    fn flush_batch(&mut self, emit: &mut Emit) {
        let Some(mut n) = self.net.take() else {
            return;
        };
        self.run_batch(&mut n, emit);
        self.net = Some(n);
    }

    /// The waiting hops through the network together, then each through the Viterbi in
    /// order.
    fn run_batch(&mut self, n: &mut NetState, emit: &mut Emit) {
        if n.pending() == 0 {
            return;
        }
        n.infer();
        for row in 0..n.pending() {
            self.net_hop(n, row, emit);
        }
    }

    /// Hop `n.hops`, whose log-probabilities are row `row` of `n.logp`, through the Viterbi.
    fn net_hop(&mut self, n: &mut NetState, row: usize, emit: &mut Emit) {
        let slot = n.hops % n.ring;
        let (silent, peak) = (n.silent[slot], n.peak[slot]);
        n.hops += 1;
        let m = self.m;
        let logp = &n.logp[row * (m + 1)..(row + 1) * (m + 1)];
        let (v, l_unvoiced) = if silent {
            self.s.fill(0.0);
            (0.02, self.observe(0.02))
        } else {
            let floor = P_FLOOR.ln();
            for ((s, o), &lp) in self.s.iter_mut().zip(self.obs.iter_mut()).zip(&logp[..m]) {
                *s = lp.exp();
                *o = lp.max(floor);
            }
            let mut lu = logp[m].max(floor) - n.voicing_nats;
            if n.blend > 0.0 {
                let slot = (n.hops - 1) % n.ring;
                let sh = &n.shs[slot * m..(slot + 1) * m];
                let sv = n.shs_v[slot];
                let peak = sh.iter().fold(0.0f32, |a, &b| a.max(b));
                for (o, &x) in self.obs.iter_mut().zip(sh) {
                    let p = if peak > 0.0 {
                        (sv * (x.max(0.0) / peak).powf(self.sal.sharp)).max(P_FLOOR)
                    } else {
                        P_FLOOR
                    };
                    *o += n.blend * p.ln();
                }
                lu += n.blend * (1.0 - sv).max(P_FLOOR).ln();
            }
            self.apply_register();
            let lu0 = logp[m].max(floor);
            ((1.0 - lu0.exp()).clamp(0.0, 1.0), lu)
        };
        self.advance(silent, v, l_unvoiced, peak, SILENT_DB, emit);
    }

    /// [`Tracker::on_frame`] with the learned salience reading `view` (its frame of the
    /// same hop) when one is given.
    fn on_frame_view(&mut self, frame: &[f32], view: Option<&[f32]>, emit: &mut Emit) {
        if self.net.is_some() {
            self.on_net_frame(frame, view, emit);
        } else {
            self.on_frame(frame, emit);
        }
    }

    fn on_frame(&mut self, frame: &[f32], emit: &mut Emit) {
        if self.net.is_some() {
            self.on_net_frame(frame, None, emit);
            return;
        }
        let silent = !self.sal.spectrum(frame);
        let v = if silent {
            self.s.fill(0.0);
            0.02
        } else {
            let mut s = std::mem::take(&mut self.s);
            let v = self.sal.salience(&mut s);
            self.s = s;
            v
        };
        let l_unvoiced = self.observe(v);
        let peak = if silent { 0.0 } else { self.sal.last_peak };
        let level = if silent {
            SILENT_DB
        } else {
            self.sal.band_level_db()
        };
        self.advance(silent, v, l_unvoiced, peak, level, emit);
    }

    /// The current hop's salience `s` and observations `obs` (voicing evidence `v`,
    /// unvoiced log-probability `l_unvoiced`) into the rings and the Viterbi; emits the hop
    /// `lag_hops` back.
    #[allow(clippy::too_many_arguments)]
    fn advance(
        &mut self,
        silent: bool,
        v: f32,
        l_unvoiced: f32,
        peak: f32,
        level_db: f32,
        emit: &mut Emit,
    ) {
        let t = self.hops_seen;
        let slot = t % self.ring;
        let m = self.m;
        self.sal_ring[slot * m..(slot + 1) * m].copy_from_slice(&self.s);
        self.peak_ring[slot] = peak;
        self.level_ring[slot] = level_db;
        self.silent[slot] = silent;
        self.voicing[slot] = v;
        if t == 0 {
            self.delta[..m].copy_from_slice(&self.obs);
            self.delta[m] = l_unvoiced;
        } else {
            crate::simd::viterbi_step(self, slot, l_unvoiced);
        }
        self.hops_seen = t + 1;
        if t >= self.lag {
            // The provisional path from the best current state back to the hop decided now:
            // `path[k]` is the state at hop `t − lag + k`.
            let h = t - self.lag;
            let mut s = self.best_state();
            for hh in (h + 1..=t).rev() {
                self.path[hh - h] = s as u16;
                s = self.bp[(hh % self.ring) * (m + 1) + s] as usize;
            }
            self.path[0] = s as u16;
            let path = std::mem::take(&mut self.path);
            self.decide(h, s, &path[1..], emit);
            self.path = path;
            self.next_emit = h + 1;
        }
    }

    /// One Viterbi step into `next` (then swapped into `delta`), backpointers into `slot`.
    #[allow(clippy::needless_range_loop)] // k indexes delta, next, obs and bp alike
    #[inline(always)] // compiled inside `simd::viterbi_step`'s AVX2 frame
    fn step(&mut self, slot: usize, l_unvoiced: f32) {
        let m = self.m;
        let j = self.max_jump;
        let bp = &mut self.bp[slot * (m + 1)..(slot + 1) * (m + 1)];
        let du = self.delta[m];
        // The best predecessor of every voiced bin k among src = k + d, |d| ≤ j: the same
        // sums and the same first-wins comparisons as a loop over src for each k (src
        // ascending), but run one offset d at a time over every k, which vectorises.
        self.best_in.fill(f32::NEG_INFINITY);
        self.arg_in.fill(0);
        for d in -(j.min(m - 1) as isize)..=(j.min(m - 1) as isize) {
            let w = self.l_jump[d.unsigned_abs()];
            let (k_lo, k_hi) = if d < 0 {
                (d.unsigned_abs(), m)
            } else {
                (0, m - d as usize)
            };
            let src_lo = (k_lo as isize + d) as usize;
            let src = &self.delta[src_lo..src_lo + (k_hi - k_lo)];
            let bv = &mut self.best_in[k_lo..k_hi];
            let arg = &mut self.arg_in[k_lo..k_hi];
            let d32 = d as i32;
            for ((b, a), &x) in bv.iter_mut().zip(arg.iter_mut()).zip(src) {
                let v = x + w;
                let gt = v > *b;
                *b = if gt { v } else { *b };
                *a = if gt { d32 } else { *a };
            }
        }
        let mut best = f32::NEG_INFINITY;
        for k in 0..m {
            let (bv, arg) = (
                self.best_in[k],
                (k as isize + self.arg_in[k] as isize) as usize,
            );
            let stay = bv + self.l_stay;
            let enter = du + self.l_enter;
            let (sv, pv) = if stay >= enter {
                (stay, arg)
            } else {
                (enter, m)
            };
            self.next[k] = sv + self.obs[k];
            bp[k] = pv as u16;
            best = best.max(self.next[k]);
        }
        // Into the unvoiced state: from itself or from the best voiced bin.
        let mut bv = f32::NEG_INFINITY;
        let mut arg = 0;
        for (src, &d) in self.delta[..m].iter().enumerate() {
            if d > bv {
                bv = d;
                arg = src;
            }
        }
        let (su, pu) = if du + self.l_stay >= bv + self.l_switch {
            (du + self.l_stay, m)
        } else {
            (bv + self.l_switch, arg)
        };
        self.next[m] = su + l_unvoiced;
        bp[m] = pu as u16;
        best = best.max(self.next[m]);
        if best.is_finite() {
            for v in self.next.iter_mut() {
                *v -= best;
            }
        }
        std::mem::swap(&mut self.delta, &mut self.next);
    }

    /// Hop `h` is decided as state `s` with the provisional path `ahead` after it: the
    /// contour voicing (step 7), the register (step 8) and the attack alignment (step 9),
    /// then `emit(h, reported, decoded)`.
    fn decide(&mut self, h: usize, s: usize, ahead: &[u16], emit: &mut Emit) {
        let voiced = self.contour_voiced(h, s, ahead);
        let st = if voiced { s } else { self.m };
        let reported = self.aligned_state(h, st, ahead);
        self.note_register(h, st);
        let decoded = self.output(h, st);
        let out = if reported == st {
            decoded
        } else {
            self.output(h, reported)
        };
        emit(h, out, decoded);
    }

    fn best_state(&self) -> usize {
        crate::viterbi::best_state(&self.delta)
    }

    fn flush(&mut self, emit: &mut Emit) {
        let (start, end) = (self.next_emit, self.hops_seen);
        if end <= start {
            return;
        }
        let last = self.best_state();
        let states = self.m + 1;
        crate::viterbi::backtrack(
            &mut self.path,
            &self.bp,
            self.ring,
            states,
            (start, end),
            last,
        );
        let path = std::mem::take(&mut self.path);
        for h in start..end {
            let s = path[h - start] as usize;
            self.decide(h, s, &path[h - start + 1..end - start], emit);
        }
        self.path = path;
        self.next_emit = end;
    }

    fn output(&self, hop: usize, state: usize) -> PitchEstimate {
        let slot = hop % self.ring;
        let v = self.voicing[slot];
        if self.silent[slot] || state >= self.m {
            return PitchEstimate {
                f0_hz: 0.0,
                aperiodicity: 1.0 - v,
                voiced_prob: v,
            };
        }
        let s = &self.sal_ring[slot * self.m..(slot + 1) * self.m];
        let mut off = 0.0f32;
        if state > 0 && state + 1 < self.m {
            let (a, b, c) = (s[state - 1], s[state], s[state + 1]);
            let den = a - 2.0 * b + c;
            if den < 0.0 {
                off = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
            }
        }
        // The learned salience's confidence in this pitch (module docs, "Learned salience").
        let aperiodicity = if self.learned {
            let near =
                state.saturating_sub(CONFIDENCE_BINS)..(state + CONFIDENCE_BINS + 1).min(self.m);
            (1.0 - s[near].iter().sum::<f32>()).clamp(0.0, 1.0)
        } else {
            1.0 - v
        };
        PitchEstimate {
            f0_hz: self.cfg_bin0 * ((state as f32 + off) / self.bins_per_octave).exp2(),
            aperiodicity,
            voiced_prob: v,
        }
    }
}

/// Streaming bass tracker: harmonic-sum salience + fixed-lag Viterbi. See the module docs.
#[derive(Debug)]
pub struct Shs {
    cfg: ShsConfig,
    framer: Framer,
    tracker: Tracker,
    /// The view's framer and its frames, for [`Shs::process_view`] (a learned tracker only).
    view: Option<ViewFrames>,
}

/// The second stream of [`Shs::process_view`]: its framer, in step with the input's, and
/// room for the frames it emits in one step (at most one per hop of input, or the tail at
/// the end).
#[derive(Debug)]
struct ViewFrames {
    framer: Framer,
    frame: usize,
    /// Frames emitted and not yet consumed, `frame` samples each.
    buf: Vec<f32>,
    n: usize,
    next: usize,
}

impl ViewFrames {
    fn take(&mut self) -> Option<&[f32]> {
        (self.next < self.n).then(|| {
            let k = self.next;
            self.next += 1;
            &self.buf[k * self.frame..(k + 1) * self.frame]
        })
    }
}

impl Shs {
    /// Validates `cfg` and allocates every buffer the stage will ever need.
    pub fn new(cfg: ShsConfig) -> Result<Shs, ConfigError> {
        let tracker = Tracker::new(&cfg)?;
        let framer = Framer::new(cfg.frame, cfg.hop)?;
        let view = if tracker.net.is_some() {
            // The tail at the end: at most the frames the framer still holds, plus one.
            let tail = cfg.frame / cfg.hop.max(1) + 2;
            Some(ViewFrames {
                framer: Framer::new(cfg.frame, cfg.hop)?,
                frame: cfg.frame,
                buf: vec![0.0; tail * cfg.frame],
                n: 0,
                next: 0,
            })
        } else {
            None
        };
        Ok(Shs {
            cfg,
            framer,
            tracker,
            view,
        })
    }

    /// [`Shs::process_both`] where the learned salience reads `view`, another signal of the
    /// same span (as many samples, hop for hop the same instants), and the harmonic sum
    /// still reads `input`: the bass of a mix whose network was trained on the separator's
    /// harmonic sum ([`ShsConfig::learned_harmonic`]). With `view == input` it is
    /// [`Shs::process_both`] bit for bit. A tracker without the learned salience ignores
    /// `view`. Extra samples of the longer input are not read.
    pub fn process_view(
        &mut self,
        input: &[f32],
        view: &[f32],
        emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate),
    ) {
        let Some(vs) = self.view.as_mut() else {
            self.process_both(input, emit);
            return;
        };
        let n = input.len().min(view.len());
        let hop = self.cfg.hop.max(1);
        let tracker = &mut self.tracker;
        // A hop of input at a time: each framer emits at most one frame per step, and
        // both emit at the same steps.
        for (a, b) in input[..n].chunks(hop).zip(view[..n].chunks(hop)) {
            vs.n = 0;
            vs.next = 0;
            let (buf, frame, count) = (&mut vs.buf, vs.frame, &mut vs.n);
            vs.framer.push(b, |_, fr| {
                buf[*count * frame..(*count + 1) * frame].copy_from_slice(fr);
                *count += 1;
            });
            self.framer.push(a, |_, fr| {
                let v = vs.take();
                tracker.on_frame_view(fr, v, emit);
            });
        }
        self.tracker.flush_batch(emit);
    }

    /// [`Shs::finish_both`] after [`Shs::process_view`]: the tails of both streams.
    pub fn finish_view(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate)) {
        let Some(vs) = self.view.as_mut() else {
            self.finish_both(emit);
            return;
        };
        vs.n = 0;
        vs.next = 0;
        let (buf, frame, count) = (&mut vs.buf, vs.frame, &mut vs.n);
        vs.framer.finish(|_, fr| {
            if (*count + 1) * frame <= buf.len() {
                buf[*count * frame..(*count + 1) * frame].copy_from_slice(fr);
                *count += 1;
            }
        });
        let tracker = &mut self.tracker;
        self.framer.finish(|_, fr| {
            let v = vs.take();
            tracker.on_frame_view(fr, v, emit);
        });
        self.tracker.drain_net(emit);
        self.tracker.flush(emit);
    }

    /// The configuration in use.
    pub fn config(&self) -> &ShsConfig {
        &self.cfg
    }

    /// Number of candidates M.
    pub fn n_bins(&self) -> usize {
        self.tracker.m
    }

    /// [`HopStage::process`] with two estimates per hop: the reported one (after the attack
    /// alignment of step 9) and the decoded one (the Viterbi's decision, before it); the
    /// two differ only where [`ShsConfig::attack_rise_db`] moved a note change.
    pub fn process_both(
        &mut self,
        input: &[f32],
        emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate),
    ) {
        let tracker = &mut self.tracker;
        self.framer.push(input, |_, fr| tracker.on_frame(fr, emit));
        self.tracker.flush_batch(emit);
    }

    /// [`HopStage::finish`] with both estimates ([`Shs::process_both`]).
    pub fn finish_both(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate, PitchEstimate)) {
        let tracker = &mut self.tracker;
        self.framer.finish(|_, fr| tracker.on_frame(fr, emit));
        self.tracker.drain_net(emit);
        self.tracker.flush(emit);
    }

    /// Salience of one frame (`cfg.frame` samples) per candidate, and its voicing evidence,
    /// computed like the stream's hops. Allocates the returned `Vec` (tests, plots).
    pub fn frame_salience(&mut self, frame: &[f32]) -> (Vec<f32>, f32) {
        let mut out = vec![0.0; self.tracker.m];
        if frame.len() != self.cfg.frame || !self.tracker.sal.spectrum(frame) {
            return (out, 0.02);
        }
        let v = self.tracker.sal.salience(&mut out);
        (out, v)
    }
}

impl HopStage for Shs {
    type Out = PitchEstimate;

    fn process(&mut self, input: &[f32], emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.process_both(input, &mut |h, e, _| emit(h, e));
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, PitchEstimate)) {
        self.finish_both(&mut |h, e, _| emit(h, e));
    }

    fn reset(&mut self) {
        self.framer.reset();
        if let Some(v) = &mut self.view {
            v.framer.reset();
            v.n = 0;
            v.next = 0;
        }
        self.tracker.reset();
    }

    fn latency_samples(&self) -> usize {
        let future = self.tracker.net.as_ref().map_or(0, |n| n.future);
        self.framer.latency_samples() + (self.cfg.lag_hops + future) * self.cfg.hop
    }

    fn hop(&self) -> usize {
        self.cfg.hop
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Tracker::step`] written the obvious way (a loop over the sources of each voiced
    /// bin, first best wins, as it was before the offset-major form), normalised the same.
    fn step_by_hand(t: &Tracker, l_unvoiced: f32) -> (Vec<f32>, Vec<u16>) {
        let (m, j) = (t.m, t.max_jump);
        let du = t.delta[m];
        let mut next = vec![0.0f32; m + 1];
        let mut bp = vec![0u16; m + 1];
        for k in 0..m {
            let (lo, hi) = (k.saturating_sub(j), (k + j).min(m - 1));
            let (mut bv, mut arg) = (f32::NEG_INFINITY, k);
            for src in lo..=hi {
                let v = t.delta[src] + t.l_jump[src.abs_diff(k)];
                if v > bv {
                    bv = v;
                    arg = src;
                }
            }
            let (stay, enter) = (bv + t.l_stay, du + t.l_enter);
            let (sv, pv) = if stay >= enter {
                (stay, arg)
            } else {
                (enter, m)
            };
            next[k] = sv + t.obs[k];
            bp[k] = pv as u16;
        }
        let (mut bv, mut arg) = (f32::NEG_INFINITY, 0);
        for (src, &d) in t.delta[..m].iter().enumerate() {
            if d > bv {
                bv = d;
                arg = src;
            }
        }
        let (su, pu) = if du + t.l_stay >= bv + t.l_switch {
            (du + t.l_stay, m)
        } else {
            (bv + t.l_switch, arg)
        };
        next[m] = su + l_unvoiced;
        bp[m] = pu as u16;
        let best = next.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        for v in next.iter_mut() {
            *v -= best;
        }
        (next, bp)
    }

    #[test]
    fn the_offset_major_viterbi_step_equals_the_source_loop_bit_for_bit() {
        let mut seed = 0x9e37_79b9u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        for (fmin, fmax, jump) in [(35.0, 400.0, 36), (70.0, 1400.0, 36), (70.0, 1400.0, 3)] {
            let mut cfg = ShsConfig::new(14_700, fmin, fmax);
            cfg.max_jump_bins = jump;
            let mut t = Tracker::new(&cfg).unwrap();
            let m = t.m;
            for trial in 0..20 {
                // Scores with ties (quantised) so that the first-wins rule is exercised.
                for d in t.delta.iter_mut() {
                    *d = -(rnd() * 8.0).floor();
                }
                for o in t.obs.iter_mut() {
                    *o = (rnd() * 4.0).ln();
                }
                let (want, want_bp) = step_by_hand(&t, -1.0);
                let slot = trial % t.ring;
                // Both builds of the step: as compiled for the baseline CPU, and inside
                // `simd::viterbi_step`, as the tracker runs it (the same frame as the
                // first where the CPU lacks AVX2).
                let delta = t.delta.clone();
                for path in ["baseline", "viterbi_step"] {
                    t.delta.copy_from_slice(&delta);
                    if path == "baseline" {
                        t.step(slot, -1.0);
                    } else {
                        crate::simd::viterbi_step(&mut t, slot, -1.0);
                    }
                    let bp = &t.bp[slot * (m + 1)..(slot + 1) * (m + 1)];
                    assert_eq!(
                        bp,
                        &want_bp[..],
                        "{path} {fmin}-{fmax} jump {jump} trial {trial}"
                    );
                    for (k, (w, d)) in want.iter().zip(&t.delta).enumerate() {
                        assert_eq!(w.to_bits(), d.to_bits(), "{path} bin {k}");
                    }
                }
            }
        }
    }
}
