//! The tracker's parameters ([`ShsConfig`]): the bass and melody presets of the module docs,
//! and their validation.

use crate::ConfigError;

/// Parameters of [`Shs`]. Build with [`ShsConfig::new`]; [`Shs::new`] validates.
///
/// [`Shs`]: super::Shs
/// [`Shs::new`]: super::Shs::new
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
    /// [`BassNet::embedded_lead_others`]: three models), `log(Σᵢ pᵢ / n)` per
    /// candidate and for "no pitch" ([`crate::bassnet`] module docs, "The lead models and
    /// their ensemble"). Errors on the bass grid. Off by default.
    ///
    /// [`BassNet::embedded_lead`]: crate::bassnet::BassNet::embedded_lead
    /// [`BassNet::embedded_lead_others`]: crate::bassnet::BassNet::embedded_lead_others
    pub learned_ensemble: bool,
    /// With [`ShsConfig::learned`]: the harmonic-view models, trained on the spectral
    /// separator's harmonic sum (vocals + bass + other). On the lead's grid
    /// [`BassNet::embedded_lead_harmonic`] (with [`ShsConfig::learned_ensemble`] also
    /// [`BassNet::embedded_lead_harmonic_others`]), and the tracker must be fed that sum
    /// (the side input of a [`crate::pair::VoicingPitchPair`]); on the bass grid
    /// [`BassNet::embedded_bass_harmonic`], whose network reads the sum given as the side
    /// input of [`Shs`] ([`HopStage::process_with`]; [`crate::bassnet`] module docs, "The
    /// harmonic view"). Off by default.
    ///
    /// [`BassNet::embedded_lead_harmonic`]: crate::bassnet::BassNet::embedded_lead_harmonic
    /// [`BassNet::embedded_lead_harmonic_others`]:
    ///     crate::bassnet::BassNet::embedded_lead_harmonic_others
    /// [`BassNet::embedded_bass_harmonic`]: crate::bassnet::BassNet::embedded_bass_harmonic
    /// [`Shs`]: super::Shs
    /// [`HopStage::process_with`]: crate::HopStage::process_with
    pub learned_harmonic: bool,
    /// With [`ShsConfig::learned`]: the live models ([`BassNet::embedded_bass_live`],
    /// [`BassNet::embedded_lead_live`]), trained on short frames ([`crate::bassnet`] module
    /// docs, "The live models"); the frame must be theirs. Off by default.
    ///
    /// [`BassNet::embedded_bass_live`]: crate::bassnet::BassNet::embedded_bass_live
    /// [`BassNet::embedded_lead_live`]: crate::bassnet::BassNet::embedded_lead_live
    pub learned_live: bool,
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
            learned_live: false,
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
        if self.learned_live && !self.learned {
            return Err(ConfigError::invalid(
                "learned_live",
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
