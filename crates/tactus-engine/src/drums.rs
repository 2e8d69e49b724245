//! The drum stem's per-instrument track: [`tactus_dsp::drums::DrumTranscriber`] + RMS gate
//! → onsets and beats per class (kick, snare, toms, cymbals).
//!
//! Like [`crate::track::OnsetTrack`], the raw per-hop decisions are post-processed in one
//! of two statistics modes: `streaming` gates every hop as it arrives with the decaying
//! running reference, `offline` gates the whole track at the end against its maximum
//! (a hop more than 35 dB below it carries no onset). The transcriber itself is identical
//! in both modes, so streaming and offline differ only where the gate reference does.
//!
//! The gate reads, for onset hop `i`, the louder of the 20 ms RMS frames centred on hops
//! `i` and `i + 1` ([`GATE_REACH_HOPS`] = 1; 0 where the transcriber's own latency leaves no
//! room). The frame centred on the onset hop holds half a hop of the quiet before the
//! attack, and quiet hits after a loud passage read below the gate there but not in the
//! frame that starts at the hit: of 1,286 ghost snares in 24 songs of unheard kits, 180 read
//! more than 35 dB below the loudest frame in the centred frame, 62 in the next one. Adopted
//! on 48 new held-out songs (`docs/decisions/0048-drum-gate-reads-the-hit-frame.md`; a reach
//! of 2 was not). The reach adds no latency: the transcriber decides hop `i` later than the
//! RMS of hop `i + reach` exists.

use tactus_dsp::binner::{bin_beats, BeatBinner};
use tactus_dsp::drums::{DrumFrame, DrumModel, DrumTranscriber, CLASSES};
use tactus_dsp::melbank::MelConfig;
use tactus_dsp::rms::{gate_offline, Rms, StreamingGate, GATE_BELOW_DB};
use tactus_dsp::{Band, ConfigError, HopStage};

use tactus_dsp::Stem;
use tactus_glove::BinFeatures;

use crate::track::{held, Feature, Geometry, Mode, Track, TrackInput, GATE_DECAY_DB_PER_S};

/// RMS hops after an onset hop whose level its gate also reads (see the module docs).
pub const GATE_REACH_HOPS: usize = 1;

/// How the drum stem becomes the rhythm fingers' four classes.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum DrumMethod {
    /// The embedded per-instrument transcriber ([`tactus_dsp::drums`]): the default.
    #[default]
    Classes,
    /// The same transcriber with the embedded low-latency model
    /// ([`DrumModel::embedded_live`]: one hop of context, 21.6 ms), for live input.
    ClassesLive,
    /// The paper's four Butterworth bands with spectral-flux onsets (for comparison).
    Bands,
    /// ADTLib's networks converted to ONNX (`models/setup_adtlib.sh`); feature `onnx`.
    AdtLib(std::path::PathBuf),
    /// The per-instrument transcriber with a model file in place of the embedded one
    /// (`--drums classes --drum-model FILE`: a file of `models/drums/train.py` or
    /// `train_cnn.py`, read by [`DrumModel::from_bytes`]); its context sets its latency.
    ClassesFile(std::path::PathBuf),
}

impl DrumMethod {
    /// Name used on the command line and in reports.
    pub fn name(&self) -> &'static str {
        match self {
            DrumMethod::Classes => "classes",
            DrumMethod::ClassesLive => "classes-live",
            DrumMethod::Bands => "bands",
            DrumMethod::AdtLib(_) => "adtlib",
            DrumMethod::ClassesFile(_) => "classes (model file)",
        }
    }
}

/// What turns samples into per-hop class decisions.
enum Detector {
    Embedded(DrumTranscriber),
    #[cfg(feature = "onnx")]
    AdtLib(Box<AdtTrack>),
}

/// ADTLib emits onset events (with its own 255 ms look-ahead in streaming); they are laid
/// on the 10 ms hop grid here. Hop `i` is final once `i·hop + latency` samples are in.
#[cfg(feature = "onnx")]
struct AdtTrack {
    adt: tactus_separate::onnx::adtlib::AdtLib,
    hop: usize,
    sample_rate: u32,
    seen: usize,
    emitted: usize,
    /// Events not yet laid on the grid: (hop, class, strength).
    pending: Vec<(usize, usize, f32)>,
    error: Option<String>,
}

#[cfg(feature = "onnx")]
impl AdtTrack {
    fn class_index(c: tactus_separate::onnx::adtlib::DrumClass) -> usize {
        use tactus_separate::onnx::adtlib::DrumClass as D;
        match c {
            D::Kick => Band::Kick as usize,
            D::Snare => Band::Snare as usize,
            D::Cymbals => Band::Cymbals as usize,
        }
    }

    fn drain(&mut self, upto: usize, emit: &mut dyn FnMut(usize, DrumFrame)) {
        while self.emitted < upto {
            let i = self.emitted;
            let mut f = DrumFrame::default();
            for &(h, c, st) in &self.pending {
                // An event later than its stated latency is put on the next open hop.
                if h <= i {
                    f.onset[c] = true;
                    f.activation[c] = f.activation[c].max(st);
                }
            }
            self.pending.retain(|&(h, _, _)| h > i);
            emit(i, f);
            self.emitted += 1;
        }
    }

    fn process(&mut self, block: &[f32], emit: &mut dyn FnMut(usize, DrumFrame)) {
        self.seen += block.len();
        let (pending, hop, sr) = (&mut self.pending, self.hop, self.sample_rate);
        self.adt.process(block, &mut |o| {
            let h = (o.time_s * sr as f64 / hop as f64).round() as usize;
            pending.push((h, Self::class_index(o.class), o.strength));
        });
        if self.error.is_none() {
            self.error = self.adt.last_error().map(|e| e.to_string());
        }
        let lat = self.adt.latency_samples() + hop;
        let upto = self.seen.saturating_sub(lat) / hop;
        self.drain(upto, emit);
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        let (pending, hop, sr) = (&mut self.pending, self.hop, self.sample_rate);
        self.adt.finish(&mut |o| {
            let h = (o.time_s * sr as f64 / hop as f64).round() as usize;
            pending.push((h, Self::class_index(o.class), o.strength));
        });
        if self.error.is_none() {
            self.error = self.adt.last_error().map(|e| e.to_string());
        }
        let total = self.seen.div_ceil(self.hop);
        self.drain(total, emit);
    }

    fn reset(&mut self) {
        self.adt.reset();
        self.seen = 0;
        self.emitted = 0;
        self.pending.clear();
        self.error = None;
    }
}

impl Detector {
    fn process(
        &mut self,
        block: &[f32],
        backing: Option<&[f32]>,
        emit: &mut dyn FnMut(usize, DrumFrame),
    ) {
        match self {
            Detector::Embedded(d) => d.process_with(block, backing, emit),
            #[cfg(feature = "onnx")]
            Detector::AdtLib(a) => {
                let _ = backing;
                a.process(block, emit)
            }
        }
    }

    fn finish(&mut self, emit: &mut dyn FnMut(usize, DrumFrame)) {
        match self {
            Detector::Embedded(d) => d.finish(emit),
            #[cfg(feature = "onnx")]
            Detector::AdtLib(a) => a.finish(emit),
        }
    }

    fn reset(&mut self) {
        match self {
            Detector::Embedded(d) => d.reset(),
            #[cfg(feature = "onnx")]
            Detector::AdtLib(a) => a.reset(),
        }
    }

    fn latency_samples(&self) -> usize {
        match self {
            Detector::Embedded(d) => d.latency_samples(),
            #[cfg(feature = "onnx")]
            Detector::AdtLib(a) => a.adt.latency_samples() + a.hop,
        }
    }
}

/// Onsets and beats of the four drum classes from one (denoised) drum signal.
pub struct ClassTrack {
    det: Detector,
    rms: Rms,
    hop: usize,
    geo: Geometry,
    /// Raw per-hop decisions not yet consumed (streaming) or all of them (offline).
    raw: Vec<[bool; CLASSES]>,
    /// Strength (network activation) of each raw onset, kept like `raw`.
    raw_strength: Vec<[f32; CLASSES]>,
    raw_rms: Vec<f32>,
    /// RMS hops after an onset hop that its gate reads (at most [`GATE_REACH_HOPS`]).
    reach: usize,
    next: usize,
    gate: StreamingGate,
    binners: [BeatBinner; CLASSES],
    /// Gated onsets: (hop, class, strength).
    pub onsets: Vec<(usize, Band, f32)>,
    /// Beat per bin, per class ([`Band::ALL`] order).
    pub bins: [Vec<bool>; CLASSES],
    /// The classes a frame shows ([`ClassTrack::show`]; all four unless told).
    shown: Vec<Band>,
}

impl ClassTrack {
    /// A track with the embedded model.
    pub fn new(geo: Geometry) -> Result<Self, ConfigError> {
        Self::with_model(geo, DrumModel::embedded())
    }

    /// A track with the embedded low-latency model ([`DrumModel::embedded_live`]).
    pub fn live(geo: Geometry) -> Result<Self, ConfigError> {
        Self::with_model(geo, DrumModel::embedded_live())
    }

    /// A track with the model in `path` (a Tactus drum model file); the error names the file.
    pub fn from_file(geo: Geometry, path: &std::path::Path) -> Result<Self, crate::EngineError> {
        let what = |e: &dyn std::fmt::Display| {
            crate::EngineError::Config(format!("--drum-model {}: {e}", path.display()))
        };
        let bytes = std::fs::read(path).map_err(|e| what(&e))?;
        let model = DrumModel::from_bytes(&bytes).map_err(|e| what(&e))?;
        Self::with_model(geo, model).map_err(|e| what(&e))
    }

    /// A track with a given model.
    pub fn with_model(geo: Geometry, model: DrumModel) -> Result<Self, ConfigError> {
        let det = DrumTranscriber::with_model(geo.sample_rate, model)?;
        Self::with_detector(
            geo,
            Detector::Embedded(det),
            MelConfig::drums(geo.sample_rate).hop,
        )
    }

    /// A track running ADTLib (`model`: `models/adtlib.onnx`), in its streaming window
    /// layout for `Mode::Streaming` and its offline one otherwise.
    #[cfg(feature = "onnx")]
    pub fn adtlib(
        geo: Geometry,
        model: &std::path::Path,
        threads: usize,
    ) -> Result<Self, crate::EngineError> {
        use tactus_separate::onnx::adtlib::{AdtLib, AdtLibConfig};
        use tactus_separate::onnx::OnnxConfig;
        let cfg = OnnxConfig {
            threads,
            ..OnnxConfig::new(model)
        };
        let layout = match geo.mode {
            Mode::Streaming => AdtLibConfig::streaming(),
            Mode::Offline => AdtLibConfig::offline(),
        };
        let adt = AdtLib::new(&cfg, geo.sample_rate, layout).map_err(crate::EngineError::AdtLib)?;
        let hop = MelConfig::drums(geo.sample_rate).hop;
        let det = Detector::AdtLib(Box::new(AdtTrack {
            adt,
            hop,
            sample_rate: geo.sample_rate,
            seen: 0,
            emitted: 0,
            pending: Vec::new(),
            error: None,
        }));
        Ok(Self::with_detector(geo, det, hop)?)
    }

    /// The first network error of the ADTLib detector since the last call, if any (the
    /// drivers stop on it, see [`crate::Engine::take_separator_error`]).
    pub fn take_error(&mut self) -> Option<String> {
        match &mut self.det {
            Detector::Embedded(_) => None,
            #[cfg(feature = "onnx")]
            Detector::AdtLib(a) => a.error.take(),
        }
    }

    fn with_detector(geo: Geometry, det: Detector, hop: usize) -> Result<Self, ConfigError> {
        let hop_s = hop as f32 / geo.sample_rate as f32;
        let binner = BeatBinner::new(hop, geo.bin_samples)?;
        // RMS over the transcriber's own hop, a 2-hop frame centred on it.
        let rms = Rms::new(2 * hop, hop)?;
        // As far ahead as the transcriber's own latency allows, so the reach adds none.
        let room = det.latency_samples().saturating_sub(rms.latency_samples()) / hop;
        Ok(ClassTrack {
            reach: GATE_REACH_HOPS.min(room),
            rms,
            det,
            hop,
            geo,
            raw: Vec::new(),
            raw_strength: Vec::new(),
            raw_rms: Vec::new(),
            next: 0,
            gate: StreamingGate::new(GATE_BELOW_DB, GATE_DECAY_DB_PER_S, hop_s)?,
            binners: [binner.clone(), binner.clone(), binner.clone(), binner],
            onsets: Vec::new(),
            bins: Default::default(),
            shown: Band::ALL.to_vec(),
        })
    }

    /// Samples between hops.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// Input samples of look-ahead before hop `i` is final.
    pub fn latency_samples(&self) -> usize {
        self.det
            .latency_samples()
            .max(self.rms.latency_samples() + self.reach * self.hop)
    }

    /// The level the gate reads for hop `j` of `raw_rms`: the loudest of it and the `reach`
    /// hops after it that exist.
    fn gate_level(raw_rms: &[f32], j: usize, reach: usize) -> f32 {
        raw_rms[j..(j + reach + 1).min(raw_rms.len())]
            .iter()
            .copied()
            .fold(f32::NEG_INFINITY, f32::max)
    }

    /// Whether the detector reads the backing beside the drum signal (a model with the
    /// backing view, [`tactus_dsp::drums::DrumModel::backing`]).
    pub fn wants_backing(&self) -> bool {
        match &self.det {
            Detector::Embedded(d) => d.wants_backing(),
            #[cfg(feature = "onnx")]
            Detector::AdtLib(_) => false,
        }
    }

    /// Feeds a block of the drum signal and, where there is one, the same span of the
    /// backing a separator left beside it (`None`: a clean drum stem; a stream is fed
    /// either always with a backing or never).
    pub fn process(&mut self, block: &[f32], backing: Option<&[f32]>) {
        let (raw, strength) = (&mut self.raw, &mut self.raw_strength);
        self.det.process(block, backing, &mut |_, f: DrumFrame| {
            raw.push(f.onset);
            strength.push(f.activation);
        });
        let raw_rms = &mut self.raw_rms;
        self.rms.process(block, &mut |_, r| raw_rms.push(r));
        self.post_streaming(false);
    }

    /// Ends the stream (offline: gates against the whole track's reference).
    pub fn finish(&mut self) {
        let (raw, strength) = (&mut self.raw, &mut self.raw_strength);
        self.det.finish(&mut |_, f: DrumFrame| {
            raw.push(f.onset);
            strength.push(f.activation);
        });
        let raw_rms = &mut self.raw_rms;
        self.rms.finish(&mut |_, r| raw_rms.push(r));
        self.post_streaming(true);
        for (c, b) in self.binners.iter_mut().enumerate() {
            let bins = &mut self.bins[c];
            b.finish(&mut |_, x| bins.push(x));
        }
        if self.geo.mode == Mode::Offline {
            let n = self.raw.len().min(self.raw_rms.len());
            let mut open = vec![false; n];
            let levels: Vec<f32> = (0..n)
                .map(|j| Self::gate_level(&self.raw_rms, j, self.reach))
                .collect();
            gate_offline(&levels, GATE_BELOW_DB, &mut open);
            self.onsets.clear();
            let mut flags = vec![vec![false; n]; CLASSES];
            for i in 0..n {
                for (c, band) in Band::ALL.into_iter().enumerate() {
                    if open[i] && self.raw[i][c] {
                        self.onsets.push((i, band, self.raw_strength[i][c]));
                        flags[c][i] = true;
                    }
                }
            }
            for (bins, f) in self.bins.iter_mut().zip(&flags) {
                *bins = bin_beats(f, self.hop, self.geo.bin_samples);
            }
        }
    }

    /// Streaming: gates the hops whose levels are known (at the end of the stream, `end`,
    /// the last hops' gate reads the RMS hops that exist).
    fn post_streaming(&mut self, end: bool) {
        if self.geo.mode != Mode::Streaming {
            return;
        }
        let levels = if end {
            self.raw_rms.len()
        } else {
            self.raw_rms.len().saturating_sub(self.reach)
        };
        let ready = self.raw.len().min(levels);
        for j in 0..ready {
            let i = self.next;
            let open = self
                .gate
                .process(Self::gate_level(&self.raw_rms, j, self.reach));
            for (c, band) in Band::ALL.into_iter().enumerate() {
                let onset = open && self.raw[j][c];
                if onset {
                    self.onsets.push((i, band, self.raw_strength[j][c]));
                }
                let bins = &mut self.bins[c];
                self.binners[c].push(i, onset, &mut |_, b| bins.push(b));
            }
            self.next += 1;
        }
        self.raw.drain(..ready);
        self.raw_strength.drain(..ready);
        self.raw_rms.drain(..ready);
    }

    /// Bins whose beats are final for every class.
    pub fn ready_bins(&self) -> usize {
        self.bins.iter().map(Vec::len).min().unwrap_or(0)
    }

    /// Beats per bin of one class.
    pub fn bins_of(&self, band: Band) -> &[bool] {
        &self.bins[band as usize]
    }

    /// Onset times in seconds of one class (after the gate).
    pub fn onset_times(&self, band: Band) -> Vec<f64> {
        let hop_s = self.hop as f64 / self.geo.sample_rate as f64;
        self.onsets
            .iter()
            .filter(|(_, b, _)| *b == band)
            .map(|(i, _, _)| *i as f64 * hop_s)
            .collect()
    }

    /// Per-hop and per-bin values held.
    pub fn retained(&self) -> usize {
        self.bins.iter().map(Vec::len).sum::<usize>()
            + self.onsets.len()
            + self.raw.len()
            + self.raw_rms.len()
    }

    /// Shows only `bands` in a frame ([`Track::read_bin`]): the classes the map has. The
    /// transcriber computes all four either way.
    pub fn show(&mut self, bands: &[Band]) {
        self.shown = bands.to_vec();
    }

    /// The classes a frame shows.
    pub fn shown(&self) -> &[Band] {
        &self.shown
    }

    /// Back to the initial state.
    pub fn reset(&mut self) {
        self.det.reset();
        self.rms.reset();
        self.raw.clear();
        self.raw_strength.clear();
        self.raw_rms.clear();
        self.next = 0;
        self.gate.reset();
        for b in &mut self.binners {
            b.reset();
        }
        self.onsets.clear();
        for b in &mut self.bins {
            b.clear();
        }
    }
}

impl Track for ClassTrack {
    fn process(&mut self, input: &TrackInput<'_>) {
        ClassTrack::process(self, input.stem, input.side);
    }

    fn finish(&mut self, _: &TrackInput<'_>) {
        ClassTrack::finish(self);
    }

    fn reset(&mut self) {
        ClassTrack::reset(self);
    }

    fn latency_samples(&self) -> usize {
        ClassTrack::latency_samples(self)
    }

    /// Forgets the first `bins` of every class and the onsets already binned.
    fn discard_before(&mut self, bins: usize) {
        for b in &mut self.bins {
            b.drain(..bins.min(b.len()));
        }
        self.onsets.clear();
    }

    fn feature(&self) -> Feature {
        Feature::Beats
    }

    /// Bins whose beats are final for every class.
    fn ready_bins(&self) -> usize {
        ClassTrack::ready_bins(self)
    }

    fn read_bin(&self, bin: usize, hold: usize, _stem: Stem, frame: &mut BinFeatures) {
        for &band in &self.shown {
            frame.band_beat[band as usize] = held(self.bins_of(band), bin, hold);
        }
    }

    fn retained(&self) -> usize {
        ClassTrack::retained(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::Profile;
    use crate::track::LevelRule;

    fn geo(mode: Mode) -> Geometry {
        Geometry {
            sample_rate: 44_100,
            bin_samples: 4_410,
            levels: 8,
            mode,
            level_rule: LevelRule::default(),
            profile: Profile::default(),
        }
    }

    /// Noise bursts 0.25 s apart, each decaying over ~40 ms, their levels stepping down
    /// from 0 dB to −45 dB and back, so that some quiet ones sit at the 35 dB gate's edge.
    fn bursts(seconds: f32) -> Vec<f32> {
        let sr = 44_100.0f32;
        let mut seed = 12_345u32;
        let n = (seconds * sr) as usize;
        (0..n)
            .map(|i| {
                let t = i as f32 / sr;
                let k = (t / 0.25) as usize;
                let tk = t - k as f32 * 0.25;
                let db = -(((k * 7) % 46) as f32);
                seed ^= seed << 13;
                seed ^= seed >> 17;
                seed ^= seed << 5;
                let noise = seed as f32 / u32::MAX as f32 - 0.5;
                0.9 * 10f32.powf(db / 20.0) * (-tk * 25.0).exp() * noise
            })
            .collect()
    }

    /// The naive gate: hop `j` is open where the loudest of `raw_rms[j ..= j + reach]` is
    /// within 35 dB of the loudest such value of the track (f64, no shared code).
    fn oracle_open(raw_rms: &[f32], n: usize, reach: usize) -> Vec<bool> {
        let level = |j: usize| {
            (j..=j + reach)
                .filter(|&h| h < raw_rms.len())
                .map(|h| raw_rms[h] as f64)
                .fold(f64::NEG_INFINITY, f64::max)
        };
        let levels: Vec<f64> = (0..n).map(level).collect();
        let reference = levels.iter().copied().fold(-200.0f64, f64::max);
        levels
            .iter()
            .map(|&x| x > -200.0 && x >= reference - GATE_BELOW_DB as f64)
            .collect()
    }

    #[test]
    fn gate_level_is_the_loudest_of_the_hop_and_those_it_reaches() {
        let x = [-50.0f32, -20.0, -80.0, -10.0, -200.0];
        for reach in 0..4 {
            for j in 0..x.len() {
                let want = x[j..(j + reach + 1).min(x.len())]
                    .iter()
                    .fold(f32::NEG_INFINITY, |a, &b| a.max(b));
                assert_eq!(
                    ClassTrack::gate_level(&x, j, reach),
                    want,
                    "j {j} reach {reach}"
                );
            }
        }
    }

    #[test]
    fn the_offline_gate_reads_the_frame_after_the_onset_hop() {
        let x = bursts(6.0);
        let mut t = ClassTrack::new(geo(Mode::Offline)).unwrap();
        assert_eq!(t.reach, GATE_REACH_HOPS);
        // The reach adds no latency to the default model, nor to the live one (953 samples:
        // room for one hop beyond the RMS frame's 441).
        assert_eq!(t.latency_samples(), t.det.latency_samples());
        let live = ClassTrack::live(geo(Mode::Streaming)).unwrap();
        assert_eq!(
            (live.reach, live.latency_samples()),
            (1, live.det.latency_samples())
        );
        for c in x.chunks(1_000) {
            t.process(c, None);
        }
        t.finish();
        let n = t.raw.len().min(t.raw_rms.len());
        let open = oracle_open(&t.raw_rms, n, GATE_REACH_HOPS);
        let mut want = Vec::new();
        for (i, (&o, raw)) in open.iter().zip(&t.raw).enumerate() {
            for (c, band) in Band::ALL.into_iter().enumerate() {
                if o && raw[c] {
                    want.push((i, band));
                }
            }
        }
        let got: Vec<(usize, Band)> = t.onsets.iter().map(|&(i, b, _)| (i, b)).collect();
        assert_eq!(got, want);
        // The signal has raw onsets whose gate the reach decides: the centred frame alone
        // would close hops that the reach opens (so this test tells the two apart).
        let centred = oracle_open(&t.raw_rms, n, 0);
        let decided = (0..n)
            .filter(|&i| t.raw[i].iter().any(|&r| r) && open[i] != centred[i])
            .count();
        assert!(
            decided > 0,
            "no raw onset at the gate's edge; the test cannot fail"
        );
        assert!(got.len() > 10, "only {} onsets", got.len());
    }
}
