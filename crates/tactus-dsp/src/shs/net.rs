//! The learned salience's driver (module docs, "Learned salience"): each frame's features
//! into a context ring, hops batched through the network ([`crate::bassnet`]), and each
//! hop's log-probabilities turned into the Viterbi's observations, blended with the harmonic
//! sum's when asked.

use realfft::num_complex::Complex;

use super::config::ShsConfig;
use super::salience::Salience;
use super::P_FLOOR;
use crate::bassnet::{BassFront, BassNet};
use crate::ConfigError;

/// Hops the learned salience runs through its network together (see
/// [`crate::nn::mlp::run_layers_batch`]); a block's last hops run as a smaller batch when the
/// block ends, so the outputs, and when they leave, are those of one hop at a time.
pub(super) const NET_BATCH: usize = 8;

/// The learned salience's front end, context ring and scratch.
pub(super) struct NetState {
    model: &'static BassNet,
    front: BassFront,
    /// Feature frames, `ring × bands`; frame `j` in slot `j % ring`.
    feats: Vec<f32>,
    pub(super) silent: Vec<bool>,
    pub(super) peak: Vec<f32>,
    pub(super) ring: usize,
    /// Frames seen.
    pub(super) frames: usize,
    /// Hops handed to the Viterbi (each `future` frames after its own).
    pub(super) hops: usize,
    /// Hops whose network input is assembled (`hops..queued` wait in the batch).
    pub(super) queued: usize,
    pub(super) future: usize,
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
    pub(super) fn new(cfg: &ShsConfig, m: usize) -> Result<NetState, ConfigError> {
        // The embedded model whose candidate grid is the tracker's: the bass model's
        // (35–400 Hz) or the lead model's (70–1400 Hz), 3 bins per semitone.
        let fits = |md: &BassNet| {
            md.candidates() == m
                && cfg.bins_per_semitone == crate::bassnet::BINS_PER_SEMITONE
                && (cfg.fmin_hz - md.cand_fmin_hz()).abs() <= 1e-3
        };
        let harmonic = cfg.learned_harmonic;
        let model = if fits(BassNet::embedded()) {
            if cfg.learned_live {
                BassNet::embedded_bass_live()
            } else if harmonic {
                BassNet::embedded_bass_harmonic()
            } else {
                BassNet::embedded()
            }
        } else if fits(BassNet::embedded_lead()) {
            if cfg.learned_live {
                BassNet::embedded_lead_live()
            } else if harmonic {
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
    pub(super) fn pending(&self) -> usize {
        self.queued - self.hops
    }

    /// Assembles hop `queued`'s input (frames outside `0..frames` are zeros) into the
    /// batch's next row.
    pub(super) fn queue(&mut self) {
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
    pub(super) fn infer(&mut self) {
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

    pub(super) fn reset(&mut self) {
        self.frames = 0;
        self.hops = 0;
        self.queued = 0;
        self.silent.fill(true);
    }

    /// The next frame: its features (`view`'s frame when one is given, the network's view
    /// of the same hop), and with a blend the harmonic sum's salience of `frame` (`m`
    /// candidates) from `sal`.
    pub(super) fn take_frame(
        &mut self,
        sal: &mut Salience,
        m: usize,
        frame: &[f32],
        view: Option<&[f32]>,
    ) {
        let n = self;
        if n.blend > 0.0 {
            let slot = n.frames % n.ring;
            let dst = &mut n.shs[slot * m..(slot + 1) * m];
            let sounding = sal.spectrum(frame);
            n.shs_v[slot] = if sounding {
                sal.salience(dst)
            } else {
                dst.fill(0.0);
                0.02
            };
            let peak = sounding.then_some(sal.last_peak);
            match view {
                // The network on the view's frame; silence and peak stay the input's, as
                // on one stream.
                Some(v) => {
                    n.push(v);
                    n.silent[slot] = !sounding;
                    n.peak[slot] = peak.unwrap_or(0.0);
                }
                // The network's bands from the same spectrum: one FFT per frame, not two.
                None => n.push_spectrum(&sal.fft.spec, peak),
            }
        } else {
            n.push(view.unwrap_or(frame));
        }
    }

    /// The observations of the hop just taken (`hops - 1`), whose log-probabilities are row
    /// `row` of `logp`: the candidates' probabilities into `s`, their log-probabilities
    /// (plus the harmonic sum's, weighted by the blend) into `obs`. Returns the voicing
    /// evidence and the unvoiced log-probability.
    pub(super) fn observe(
        &self,
        row: usize,
        sharp: f32,
        s: &mut [f32],
        obs: &mut [f32],
    ) -> (f32, f32) {
        let n = self;
        let m = s.len();
        let logp = &n.logp[row * (m + 1)..(row + 1) * (m + 1)];
        let floor = P_FLOOR.ln();
        for ((s, o), &lp) in s.iter_mut().zip(obs.iter_mut()).zip(&logp[..m]) {
            *s = lp.exp();
            *o = lp.max(floor);
        }
        let mut lu = logp[m].max(floor) - n.voicing_nats;
        if n.blend > 0.0 {
            let slot = (n.hops - 1) % n.ring;
            let sh = &n.shs[slot * m..(slot + 1) * m];
            let sv = n.shs_v[slot];
            let peak = sh.iter().fold(0.0f32, |a, &b| a.max(b));
            for (o, &x) in obs.iter_mut().zip(sh) {
                let p = if peak > 0.0 {
                    (sv * (x.max(0.0) / peak).powf(sharp)).max(P_FLOOR)
                } else {
                    P_FLOOR
                };
                *o += n.blend * p.ln();
            }
            lu += n.blend * (1.0 - sv).max(P_FLOOR).ln();
        }
        let lu0 = logp[m].max(floor);
        ((1.0 - lu0.exp()).clamp(0.0, 1.0), lu)
    }
}
