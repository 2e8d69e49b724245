//! Reading the engine's output: the bins every track has finished, frames (as rendered,
//! or as the live glove shows each feature as soon as it is final), the features file,
//! and forgetting what a live driver has sent.

use tactus_dsp::Stem;
use tactus_glove::{BinFeatures, Frame};

use super::chain::StemChain;
use super::Engine;
use crate::track::{Feature, Mode};

impl Engine {
    /// Bins for which every feature the map uses is final (streaming mode).
    pub fn ready_bins(&self) -> usize {
        self.ready_shifted(&|_, _| 0)
    }

    /// Bins ready when each feature of chain `c` is read `shift(c, feature)` bins late: the
    /// fewest over the tracks of the bins each has finished plus its shift.
    fn ready_shifted(&self, shift: &dyn Fn(&StemChain, Feature) -> usize) -> usize {
        let ready = self
            .chains
            .iter()
            .flat_map(|c| {
                c.tracks()
                    .map(move |t| t.ready_bins() + shift(c, t.feature()))
            })
            .min();
        match ready {
            Some(ready) => self.bin_base + ready,
            None => self.n_in / self.geo.bin_samples,
        }
    }

    /// The features of bin `k` (missing values, and bins forgotten by
    /// [`Engine::discard_before`], count as silent). In the live profile a beat or onset
    /// stays on for [`crate::Profile::pulse_bins`] bins (the minimum pin pulse).
    pub fn bin_features(&self, k: usize) -> BinFeatures {
        self.features_shifted(k, &|_, _| 0)
    }

    /// Bin `k` with each feature of chain `c` taken from its bin `k − shift(c, feature)`
    /// (silent before bin 0).
    fn features_shifted(
        &self,
        k: usize,
        shift: &dyn Fn(&StemChain, Feature) -> usize,
    ) -> BinFeatures {
        let hold = self.cfg.profile.pulse_bins(self.cfg.bin_ms);
        let mut f = BinFeatures::default();
        let Some(k) = k.checked_sub(self.bin_base) else {
            return f;
        };
        for c in &self.chains {
            for t in c.tracks() {
                if let Some(kb) = k.checked_sub(shift(c, t.feature())) {
                    t.read_bin(kb, hold, c.stem, &mut f);
                }
            }
        }
        f
    }

    /// The glove frame of bin `k`.
    pub fn frame(&self, k: usize) -> Frame {
        self.cfg.map.render(&self.bin_features(k), self.cfg.levels)
    }

    /// Bins ready for [`Engine::live_frame`]: frame `k` exists once the fastest chain has
    /// finished bin `k` and every slower chain bin `k − shift`.
    pub fn live_ready_bins(&self) -> usize {
        let fastest = self.fastest_latency();
        self.ready_shifted(&|c, w| self.live_shift(c, w, fastest))
    }

    /// The frame the live glove shows when bin `k` of the fastest chain is final: every
    /// chain contributes the newest bin it has finished by then, `k − shift` (see
    /// [`crate::profile`]). A pure function of the bins, so it does not depend on how the
    /// input was cut into blocks. With every chain equally fast it is [`Engine::frame`].
    pub fn live_frame(&self, k: usize) -> Frame {
        let fastest = self.fastest_latency();
        let f = self.features_shifted(k, &|c, w| self.live_shift(c, w, fastest));
        self.cfg.map.render(&f, self.cfg.levels)
    }

    /// Bins before the newest that [`Engine::live_frame`] still reads (the slowest
    /// feature's shift plus the pin pulse): a live driver discards only bins older than
    /// that ([`Engine::discard_before`]).
    pub fn live_history_bins(&self) -> usize {
        let fastest = self.fastest_latency();
        let shift = self
            .chains
            .iter()
            .flat_map(|c| Feature::ALL.map(|w| self.live_shift(c, w, fastest)))
            .max()
            .unwrap_or(0);
        shift + self.cfg.profile.pulse_bins(self.cfg.bin_ms)
    }

    /// All frames of a finished stream, one per bin.
    pub fn frames(&self) -> Vec<Frame> {
        (0..self.total_bins()).map(|k| self.frame(k)).collect()
    }

    /// Forgets everything about bins before `k` (at most [`Engine::ready_bins`]): their
    /// levels and beats and the per-hop records behind them. A live driver calls this after
    /// sending each frame, so memory stays flat however long it runs; [`Engine::frame`] of a
    /// forgotten bin is all-down, and [`Engine::features`] then covers only what is kept.
    /// Offline mode needs the whole track and ignores it.
    pub fn discard_before(&mut self, k: usize) {
        if self.cfg.mode != Mode::Streaming {
            return;
        }
        let k = k.min(self.ready_bins());
        if k <= self.bin_base {
            return;
        }
        let d = k - self.bin_base;
        for c in &mut self.chains {
            c.discard(d);
        }
        self.bin_base = k;
    }

    /// Per-hop and per-bin feature values the engine holds now: grows with the stream unless
    /// the driver calls [`Engine::discard_before`] (the bounded-memory tests watch it).
    pub fn retained_values(&self) -> usize {
        self.chains.iter().map(|c| c.retained()).sum()
    }

    /// Bins forgotten so far by [`Engine::discard_before`].
    pub fn discarded_bins(&self) -> usize {
        self.bin_base
    }

    /// Builds the features file contents (docs/design.md "Files") of a finished stream.
    pub fn features(&self) -> tactus_glove::Features {
        let mut out = tactus_glove::Features {
            hop_s: 0.01,
            bin_s: self.geo.bin_samples as f64 / self.geo.sample_rate as f64,
            ..Default::default()
        };
        let bins = self.total_bins();
        for c in &self.chains {
            let name = c.stem.name().to_string();
            if let Some(p) = &c.pitch {
                out.hop_s = p.hop() as f64 / self.geo.sample_rate as f64;
                out.pitch_hz.insert(name.clone(), p.f0.clone());
                let mut lv = p.bins.clone();
                lv.resize(bins, 0);
                out.levels.insert(name.clone(), lv);
            }
            if let Some(n) = &c.notes {
                out.onsets_s.insert(name.clone(), n.onset_times());
            }
            for b in &c.bands {
                let bn = b.band.name().to_string();
                out.onsets_s.insert(bn.clone(), b.track.onset_times());
                let mut beats: Vec<u8> = b.track.beats.bins.iter().map(|&x| x as u8).collect();
                beats.resize(bins, 0);
                out.beats.insert(bn, beats);
            }
            if let Some(t) = &c.classes {
                for &band in t.shown() {
                    let bn = band.name().to_string();
                    out.onsets_s.insert(bn.clone(), t.onset_times(band));
                    let mut beats: Vec<u8> = t.bins_of(band).iter().map(|&x| x as u8).collect();
                    beats.resize(bins, 0);
                    out.beats.insert(bn, beats);
                }
            }
        }
        out
    }

    /// Input samples (engine rate) after which a feature of chain `c` is final: its own
    /// look-ahead plus the separator's where the chain takes a separated stem. `None`
    /// when the chain does not compute that feature.
    pub(super) fn feature_latency(&self, c: &StemChain, what: Feature) -> Option<usize> {
        let separated =
            !(self.cfg.supplied.contains(c.stem) || self.drums_on_mix && c.stem == Stem::Drums);
        let sep = match (&self.separator, separated) {
            (Some(s), true) => s.latency_samples(),
            _ => 0,
        };
        let d = c.denoise.latency_samples() + sep;
        c.tracks()
            .filter(|t| t.feature() == what)
            .map(|t| t.latency_samples())
            .max()
            .map(|l| l + d)
    }

    /// The smallest latency of any feature the engine computes, samples.
    pub(super) fn fastest_latency(&self) -> usize {
        self.chains
            .iter()
            .flat_map(|c| Feature::ALL.map(|w| self.feature_latency(c, w)))
            .flatten()
            .min()
            .unwrap_or(0)
    }

    /// Bins by which a feature of chain `c` trails the fastest feature in
    /// [`Engine::live_frame`]: its extra latency rounded up to whole bins.
    pub(super) fn live_shift(&self, c: &StemChain, what: Feature, fastest: usize) -> usize {
        self.feature_latency(c, what).map_or(0, |l| {
            l.saturating_sub(fastest).div_ceil(self.geo.bin_samples)
        })
    }
}
