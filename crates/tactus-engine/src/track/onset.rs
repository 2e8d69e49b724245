//! Onset tracks: a drum band's or a stem's spectral-flux onsets, and the beats per bin.

use super::{Geometry, Mode, GATE_DECAY_DB_PER_S};
use tactus_dsp::binner::{bin_beats, BeatBinner};
use tactus_dsp::flux::{OnsetConfig, OnsetDetector, OnsetFrame};
use tactus_dsp::rms::{gate_offline, Rms, StreamingGate, GATE_BELOW_DB};
use tactus_dsp::{ConfigError, HopStage};

/// Onset feature track: a drum band, or note onsets of a melodic stem.
pub struct OnsetTrack {
    det: OnsetDetector,
    rms: Rms,
    hop: usize,
    geo: Geometry,
    /// Raw onset flag per hop: every hop offline, only the hops not yet consumed in
    /// streaming mode.
    pub raw_onset: Vec<bool>,
    /// RMS per hop in dBFS (kept like `raw_onset`).
    pub raw_rms: Vec<f32>,
    next: usize,
    gate: StreamingGate,
    /// The live profile's rise test: the levels of the last [`RISE_HOPS`] hops (dBFS).
    recent_rms: [f32; RISE_HOPS],
    /// Gated onset flags per hop and beats per bin.
    pub beats: Beats,
}

impl OnsetTrack {
    /// An onset track with the causal (streaming) or look-ahead (offline) detector, its
    /// flux restricted to `band_hz` when given (a drum band's own bins).
    pub fn new(geo: Geometry, band_hz: Option<(f32, f32)>) -> Result<Self, ConfigError> {
        let mut cfg = match geo.mode {
            Mode::Streaming => OnsetConfig::causal(geo.sample_rate),
            Mode::Offline => OnsetConfig::lookahead(geo.sample_rate),
        };
        cfg.band_hz = band_hz;
        let hop = cfg.hop;
        let frame = cfg.frame;
        let hop_s = hop as f32 / geo.sample_rate as f32;
        // The gate's level: over the flux frame, or in the live profile over two hops
        // centred on the hop (latency one hop, 5 ms, instead of half the frame, 11.6 ms;
        // the hop after an onset still holds the hit's energy).
        let rms_frame = match geo.profile {
            crate::profile::Profile::Full => frame.max(hop),
            crate::profile::Profile::Live => 2 * hop,
        };
        Ok(OnsetTrack {
            det: OnsetDetector::new(cfg)?,
            rms: Rms::new(rms_frame, hop)?,
            hop,
            geo,
            raw_onset: Vec::new(),
            raw_rms: Vec::new(),
            next: 0,
            gate: StreamingGate::new(GATE_BELOW_DB, GATE_DECAY_DB_PER_S, hop_s)?,
            recent_rms: [tactus_dsp::rms::SILENCE_DB; RISE_HOPS],
            beats: Beats::new(hop, geo.bin_samples)?,
        })
    }

    /// Samples between hops.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Input samples of look-ahead this track needs.
    pub fn latency_samples(&self) -> usize {
        self.det.latency_samples().max(self.rms.latency_samples())
    }

    /// Feeds a block.
    pub fn process(&mut self, block: &[f32]) {
        let raw = &mut self.raw_onset;
        self.det
            .process(block, &mut |_, f: OnsetFrame| raw.push(f.onset));
        let raw_rms = &mut self.raw_rms;
        self.rms.process(block, &mut |_, r| raw_rms.push(r));
        self.post_streaming();
    }

    /// Ends the stream.
    pub fn finish(&mut self) {
        let raw = &mut self.raw_onset;
        self.det.finish(&mut |_, f: OnsetFrame| raw.push(f.onset));
        let raw_rms = &mut self.raw_rms;
        self.rms.finish(&mut |_, r| raw_rms.push(r));
        self.post_streaming();
        self.beats.finish();
        if self.geo.mode == Mode::Offline {
            let n = self.raw_onset.len().min(self.raw_rms.len());
            let mut open = vec![false; n];
            gate_offline(&self.raw_rms[..n], GATE_BELOW_DB, &mut open);
            let onsets = (0..n).map(|i| self.raw_onset[i] && open[i]).collect();
            self.beats
                .set_offline(onsets, self.hop, self.geo.bin_samples);
        }
    }

    fn post_streaming(&mut self) {
        if self.geo.mode != Mode::Streaming {
            return;
        }
        // As in `PitchTrack`: only unconsumed raw hops are kept; `raw_*[j]` is hop `next + j`.
        let ready = self.raw_onset.len().min(self.raw_rms.len());
        let live = self.geo.profile == crate::profile::Profile::Live;
        for j in 0..ready {
            let i = self.next;
            let level = self.raw_rms[j];
            let open = self.gate.process(level);
            // The live profile's rise test: an onset is where the level rises, at least
            // RISE_DB above the quietest of the last RISE_HOPS hops. Its short gate level
            // (two hops) lets the causal picker fire again in a hit's decaying tail (the
            // flux threshold's 100 ms mean forgets the hit); the tail never rises.
            let rises = !live
                || level - self.recent_rms.iter().fold(f32::INFINITY, |a, &b| a.min(b)) >= RISE_DB;
            self.recent_rms[i % RISE_HOPS] = level;
            self.beats.push(i, open && self.raw_onset[j] && rises);
            self.next += 1;
        }
        self.raw_onset.drain(..ready);
        self.raw_rms.drain(..ready);
    }

    /// Onset times in seconds (after the gate).
    pub fn onset_times(&self) -> Vec<f64> {
        onset_times(&self.beats.onsets, self.hop, self.geo.sample_rate)
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.beats.retained() + self.raw_onset.len() + self.raw_rms.len()
    }

    /// Streaming: forgets the first `d` bins and the per-hop onsets already binned.
    pub fn discard(&mut self, d: usize) {
        self.beats.discard(d);
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.det.reset();
        self.rms.reset();
        self.raw_onset.clear();
        self.raw_rms.clear();
        self.next = 0;
        self.gate.reset();
        self.recent_rms = [tactus_dsp::rms::SILENCE_DB; RISE_HOPS];
        self.beats.reset();
    }
}

/// Onset flags per hop and the beats they make per bin (a bin is a beat when one of its
/// hops is an onset): what an onset track and a stem's note onsets keep.
pub struct Beats {
    binner: BeatBinner,
    /// Onset flag per hop (streaming: the hops not yet discarded).
    pub onsets: Vec<bool>,
    /// Beat per bin.
    pub bins: Vec<bool>,
}

impl Beats {
    /// Hops of `hop` samples into bins of `bin_samples`.
    pub fn new(hop: usize, bin_samples: usize) -> Result<Self, ConfigError> {
        Ok(Beats {
            binner: BeatBinner::new(hop, bin_samples)?,
            onsets: Vec::new(),
            bins: Vec::new(),
        })
    }

    /// Streaming: hop `i`'s onset flag; a bin it completes is added.
    pub fn push(&mut self, i: usize, onset: bool) {
        self.onsets.push(onset);
        let bins = &mut self.bins;
        self.binner.push(i, onset, &mut |_, b| bins.push(b));
    }

    /// Streaming: adds the last, partial bin.
    pub fn finish(&mut self) {
        let bins = &mut self.bins;
        self.binner.finish(&mut |_, b| bins.push(b));
    }

    /// Offline: every hop's flag at once, binned in one go.
    pub fn set_offline(&mut self, onsets: Vec<bool>, hop: usize, bin_samples: usize) {
        self.bins = bin_beats(&onsets, hop, bin_samples);
        self.onsets = onsets;
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.bins.len() + self.onsets.len()
    }

    /// Streaming: forgets the first `d` bins and the onsets already binned.
    pub fn discard(&mut self, d: usize) {
        self.bins.drain(..d.min(self.bins.len()));
        self.onsets.clear();
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        self.binner.reset();
        self.onsets.clear();
        self.bins.clear();
    }
}

/// Hops the live profile's onset rise test looks back (4 × 5 ms).
const RISE_HOPS: usize = 4;
/// Level rise (dB) over the quietest of the last [`RISE_HOPS`] hops that the live
/// profile's onsets need.
const RISE_DB: f32 = 3.0;

/// The times, in seconds, of the hops flagged in `onsets` (hops of `hop` samples at `rate`).
pub(crate) fn onset_times(onsets: &[bool], hop: usize, rate: u32) -> Vec<f64> {
    let hop_s = hop as f64 / rate as f64;
    onsets
        .iter()
        .enumerate()
        .filter(|(_, &o)| o)
        .map(|(i, _)| i as f64 * hop_s)
        .collect()
}
