//! The engine's report: the latency budget (per finger group for the live glove) and the
//! time each stage took.

use tactus_dsp::Stem;

use super::chain::StemChain;
use super::{Engine, StageTimes};
use crate::track::Feature;

impl Engine {
    /// The latency of each finger group as stages in samples at the engine rate, for the
    /// live glove (each group is shown as soon as it is final): `(group, [(stage,
    /// samples)])`. Groups: "rhythm" (drum chain), "pitch" (melodic chains; the slowest).
    pub fn latency_paths(&self) -> Vec<(String, Vec<(String, usize)>)> {
        let mut out = Vec::new();
        let sep = self
            .separator
            .as_ref()
            .map(|s| (s.name(), s.latency_samples()));
        let denoise = |c: &StemChain| c.denoise.latency_samples();
        let drums = self.chains.iter().find(|c| c.stem == Stem::Drums);
        if let Some(c) = drums {
            let mut v = Vec::new();
            if !self.drums_on_mix && !self.cfg.supplied.contains(Stem::Drums) {
                if let Some((name, l)) = sep {
                    v.push((format!("separator ({name})"), l));
                }
            } else if self.drums_on_mix {
                v.push(("separator: none, drums on the mix".into(), 0));
            }
            v.push(("denoise (high-pass + 3-median)".into(), denoise(c)));
            let det = c.latency_samples() - denoise(c);
            let what = if c.classes.is_some() {
                format!("drum transcriber ({})", self.cfg.drums.name())
            } else {
                "band onsets (causal flux)".to_string()
            };
            v.push((what, det));
            out.push(("rhythm".to_string(), v));
        }
        let slowest = self
            .chains
            .iter()
            .filter(|c| c.pitch.is_some())
            .max_by_key(|c| self.feature_latency(c, Feature::Level));
        if let Some(c) = slowest {
            let mut v = Vec::new();
            if !self.cfg.supplied.contains(c.stem) {
                if let Some((name, l)) = sep {
                    v.push((format!("separator ({name})"), l));
                }
            }
            v.push(("denoise (high-pass + 3-median)".into(), denoise(c)));
            let lag = match c.pitch.as_ref().map_or(0, |p| p.advance_hops()) {
                0 => "",
                _ => " + the separator's note lag",
            };
            v.push((
                format!("{} pitch (frame/2 + Viterbi lag{lag})", c.stem.name()),
                c.pitch.as_ref().map_or(0, |p| p.latency_samples()),
            ));
            out.push(("pitch".to_string(), v));
        }
        for (_, v) in &mut out {
            v.push((
                format!("bin ({} ms)", self.cfg.bin_ms),
                self.geo.bin_samples,
            ));
        }
        out
    }

    /// The latency budget: (stage, milliseconds), summed along the longest path.
    pub fn latency_budget(&self) -> Vec<(String, f64)> {
        let ms = |n: usize| n as f64 * 1000.0 / self.geo.sample_rate as f64;
        let mut v = Vec::new();
        if let Some(s) = &self.separator {
            v.push((format!("separator ({})", s.name()), ms(s.latency_samples())));
        }
        let feat = self
            .chains
            .iter()
            .map(|c| c.latency_samples())
            .max()
            .unwrap_or(0);
        v.push((
            "features (denoise, pitch/onset look-ahead)".into(),
            ms(feat),
        ));
        v.push((
            format!("bin ({} ms)", self.cfg.bin_ms),
            ms(self.geo.bin_samples),
        ));
        v
    }

    /// Wall time per stage so far.
    pub fn stage_times(&self) -> StageTimes {
        let mut st = StageTimes::default();
        if let Some(s) = &self.separator {
            st.stages
                .push((format!("separate ({})", s.name()), self.t_separate));
        }
        for c in &self.chains {
            let n = c.stem.name();
            st.stages.push((format!("{n}: denoise"), c.t_denoise));
            if c.pitch.is_some() {
                st.stages
                    .push((format!("{n}: pitch + gate + levels"), c.t_pitch));
            }
            if c.notes.is_some() {
                st.stages.push((format!("{n}: note onsets"), c.t_notes));
            }
            if c.classes.is_some() {
                st.stages
                    .push((format!("{n}: drum transcriber (4 classes)"), c.t_classes));
            }
            for b in &c.bands {
                st.stages
                    .push((format!("{n}/{}: band-pass", b.band.name()), b.t_filter));
                st.stages
                    .push((format!("{n}/{}: onsets", b.band.name()), b.t_onsets));
            }
        }
        st
    }
}
