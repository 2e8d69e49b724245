//! The streaming engine: separator → per-stem chains → bins → glove frames.
//!
//! One [`Engine`] serves both drivers. It accepts planar stereo blocks of any size at the
//! engine rate, plus optional stems supplied directly (`render --stem`), and builds only
//! what the glove map needs: a drums-only map runs no pitch tracking and asks the
//! separator for drums alone. Chains run on their own threads when a block is large enough
//! to pay for it (offline rendering feeds 1 s blocks); results do not depend on the block
//! size or on threading, because every stage is chunk-invariant.

use std::time::{Duration, Instant};

use tactus_dsp::sos::SosFilter;
use tactus_dsp::{Band, SampleStage, Stem};
use tactus_glove::{BinFeatures, Frame, GloveMap};
use tactus_separate::none::NoneSeparator;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{SegmentStats, Separator, StemOutput, StemSet};

use crate::drums::{ClassTrack, DrumMethod};
use crate::notes::{NoteRule, NoteTrack, PitchNotes};
use crate::profile::{self, Profile};
use crate::recipe::{recipe, PitchMethod, Recipe, Role, SeparatorKind, Source};
use crate::track::{
    held, Denoise, Feature, Geometry, LevelRule, Mode, OnsetTrack, PitchTrack, Track, TrackInput,
};
use crate::EngineError;

/// The engine's default sample rate; inputs are resampled to it.
pub const ENGINE_RATE: u32 = 44_100;

/// Blocks at least this long are processed with one thread per stem chain.
const PARALLEL_MIN_BLOCK: usize = 16_384;

/// Which separator splits the mix.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum SeparatorChoice {
    /// The embedded pure-Rust spectral separator (HPSS + bass band + centre extraction).
    #[default]
    Spectral,
    /// No separation: the mix feeds every stem chain.
    None,
    /// Spleeter 2-stem ONNX model (vocals from the network, the accompaniment split
    /// spectrally). Needs the `onnx` cargo feature and ONNX Runtime at run time.
    Spleeter(std::path::PathBuf),
    /// Hybrid Transformer Demucs exported to ONNX (`models/export_htdemucs.py`).
    HtDemucs(std::path::PathBuf),
}

impl SeparatorChoice {
    /// The kind of separator, for the stems' recipes ([`crate::recipe`]).
    pub fn kind(&self) -> SeparatorKind {
        match self {
            SeparatorChoice::Spectral => SeparatorKind::Spectral,
            SeparatorChoice::None => SeparatorKind::None,
            SeparatorChoice::Spleeter(_) | SeparatorChoice::HtDemucs(_) => SeparatorKind::Onnx,
        }
    }
}

/// Everything the engine needs to know up front.
#[derive(Debug, Clone)]
pub struct EngineConfig {
    /// Sample rate of the blocks given to [`Engine::process`].
    pub sample_rate: u32,
    /// Bin length in milliseconds (100 offline, as in the paper).
    pub bin_ms: u32,
    /// Pitch levels per melodic stem (8).
    pub levels: u8,
    /// Statistics mode.
    pub mode: Mode,
    /// Pitch tracker for melodic stems.
    pub pitch: PitchMethod,
    /// How voiced pitch becomes levels ([`LevelRule::Follow`] by default; `Paper` is the
    /// paper's rule as first implemented).
    pub level_rule: LevelRule,
    /// How the melodic stems' note onsets are read from their pitch tracks
    /// ([`NoteRule::Attack`] by default; `Pitch` is the first implementation).
    pub note_rule: NoteRule,
    /// The spectral separator's learned kit mask
    /// ([`tactus_separate::spectral::SpectralConfig::low_band_drums`]): kick and tom bodies
    /// leave the bass stem for the drums (full profile; on by default).
    pub kit_mask: bool,
    /// The glove map: decides which stems, bands and features exist.
    pub map: GloveMap,
    /// Separator for the stems not supplied directly.
    pub separator: SeparatorChoice,
    /// How the drum stem becomes kick, snare, toms and cymbals.
    pub drums: DrumMethod,
    /// Stems the caller supplies directly (never separated).
    pub supplied: StemSet,
    /// Overlap separation of block `n + 1` with the stem chains of block `n` (one thread
    /// each). Delays the chains by one block; results are identical. The offline driver
    /// turns it on; a live caller with small blocks leaves it off.
    pub pipeline: bool,
    /// Intra-op threads for the ONNX separators (ONNX Runtime); 0 = the available cores
    /// ([`std::thread::available_parallelism`]). Nothing else uses it.
    pub threads: usize,
    /// Latency profile ([`crate::profile`]): `Full` by default, `Live` for the live glove.
    pub profile: Profile,
    /// Whether the engine may start threads of its own: the stem chains on one thread
    /// each, separation overlapped with the chains ([`EngineConfig::pipeline`]), the
    /// offline driver's decoder a few blocks ahead. `true` by default (one song, every
    /// core); a batch that renders one song per core turns it off so that each job runs on
    /// the calling thread alone. Results are identical either way.
    pub parallel: bool,
}

impl Default for EngineConfig {
    fn default() -> Self {
        EngineConfig {
            sample_rate: ENGINE_RATE,
            bin_ms: 100,
            levels: 8,
            mode: Mode::Offline,
            pitch: PitchMethod::default(),
            level_rule: LevelRule::default(),
            note_rule: NoteRule::default(),
            kit_mask: true,
            map: GloveMap::default(),
            separator: SeparatorChoice::default(),
            drums: DrumMethod::default(),
            supplied: StemSet::default(),
            pipeline: false,
            threads: 0,
            profile: Profile::Full,
            parallel: true,
        }
    }
}

/// Wall time spent per stage, summed over the stream.
#[derive(Debug, Clone, Default)]
pub struct StageTimes {
    /// (stage name, time) in pipeline order.
    pub stages: Vec<(String, Duration)>,
}

/// One drum band: band-pass filter then onset track.
struct BandTrack {
    band: Band,
    filter: SosFilter,
    track: OnsetTrack,
    scratch: Vec<f32>,
    t_filter: Duration,
    t_onsets: Duration,
}

impl Track for BandTrack {
    fn process(&mut self, input: &TrackInput<'_>) {
        let t = Instant::now();
        self.scratch.clear();
        self.scratch.extend_from_slice(input.stem);
        self.filter.process_inplace(&mut self.scratch);
        let t2 = Instant::now();
        self.track.process(&self.scratch);
        self.t_filter += t2 - t;
        self.t_onsets += t2.elapsed();
    }

    fn finish(&mut self, _: &TrackInput<'_>) {
        let t = Instant::now();
        self.track.finish();
        self.t_onsets += t.elapsed();
    }

    fn reset(&mut self) {
        self.filter.reset();
        self.track.reset();
    }

    fn latency_samples(&self) -> usize {
        self.track.latency_samples()
    }

    fn discard_before(&mut self, bins: usize) {
        self.track.discard(bins);
    }

    fn feature(&self) -> Feature {
        Feature::Beats
    }

    fn ready_bins(&self) -> usize {
        self.track.beats.bins.len()
    }

    fn read_bin(&self, bin: usize, hold: usize, _stem: Stem, frame: &mut BinFeatures) {
        frame.band_beat[self.band as usize] = held(&self.track.beats.bins, bin, hold);
    }

    fn retained(&self) -> usize {
        self.track.retained()
    }
}

/// Everything computed from one stem: its denoiser, then its tracks ([`Track`]).
struct StemChain {
    stem: Stem,
    denoise: Denoise,
    buf: Vec<f32>,
    pitch: Option<PitchTrack>,
    notes: Option<NoteTrack>,
    bands: Vec<BandTrack>,
    /// The per-instrument transcriber (drums with [`DrumMethod::Classes`]).
    classes: Option<ClassTrack>,
    /// The spectral separator's harmonic sum (bass + vocals + other) beside the stem, and
    /// its denoiser (the stem's): the backing of a drum transcriber that reads it
    /// ([`ClassTrack::wants_backing`]), or the harmonic view of the lead's learned pair
    /// ([`crate::recipe::Recipe::harmonic_view`]).
    backing: Option<(Denoise, Vec<f32>)>,
    samples: usize,
    t_denoise: Duration,
    t_pitch: Duration,
    t_notes: Duration,
    t_classes: Duration,
}

/// The per-instrument drum transcriber `drums` asks for, when a map shows any of `bands`.
fn class_track(
    geo: Geometry,
    bands: &[Band],
    drums: &DrumMethod,
) -> Result<Option<ClassTrack>, EngineError> {
    let mut track = match drums {
        _ if bands.is_empty() => return Ok(None),
        DrumMethod::Classes => ClassTrack::new(geo)?,
        DrumMethod::ClassesLive => ClassTrack::live(geo)?,
        DrumMethod::ClassesFile(path) => ClassTrack::from_file(geo, path)?,
        #[cfg(feature = "onnx")]
        DrumMethod::AdtLib(model) => ClassTrack::adtlib(geo, model, 0)?,
        #[cfg(not(feature = "onnx"))]
        DrumMethod::AdtLib(_) => {
            return Err(EngineError::Config(
                "--drums adtlib needs a tactus built with `--features onnx` (see README, \"ONNX models\")".into(),
            ))
        }
        DrumMethod::Bands => return Ok(None),
    };
    track.show(bands);
    Ok(Some(track))
}

/// The band tracks of `bands` (a band above Nyquist, e.g. cymbals at 8 kHz, is skipped; it
/// stays silent).
fn band_tracks(geo: Geometry, bands: &[Band]) -> Result<Vec<BandTrack>, EngineError> {
    let mut out = Vec::new();
    for &band in bands {
        let edges = tactus_dsp::sos::band_edges(band, geo.sample_rate);
        if let (Ok(filter), Some((lo, hi))) = (SosFilter::band(band, geo.sample_rate), edges) {
            out.push(BandTrack {
                band,
                filter,
                track: OnsetTrack::new(geo, Some((lo as f32, hi as f32)))?,
                scratch: Vec::with_capacity(PARALLEL_MIN_BLOCK * 4),
                t_filter: Duration::ZERO,
                t_onsets: Duration::ZERO,
            });
        }
    }
    Ok(out)
}

impl StemChain {
    /// The chain of `stem`: its pitch track and note onsets as `recipe` says (a melodic
    /// stem; the pitch track when `pitch`, note onsets by `notes`), its drum `bands` or
    /// classes by `drums`.
    fn new(
        stem: Stem,
        geo: Geometry,
        recipe: Option<&Recipe>,
        pitch: bool,
        notes: Option<NoteRule>,
        bands: &[Band],
        drums: &DrumMethod,
    ) -> Result<Self, EngineError> {
        let hp = if matches!(stem, Stem::Bass | Stem::Drums) {
            30.0
        } else {
            60.0
        };
        let pitch = match recipe {
            Some(r) if pitch => Some(PitchTrack::new(geo, r)?),
            _ => None,
        };
        let notes = match (notes, &pitch, recipe) {
            (Some(rule), Some(p), Some(r)) => {
                Some(NoteTrack::Pitch(PitchNotes::new(geo, p, rule, r.notes)?))
            }
            (Some(_), _, _) => Some(NoteTrack::Flux(OnsetTrack::new(geo, None)?)),
            (None, _, _) => None,
        };
        let harmonic_view = recipe.is_some_and(|r| r.harmonic_view);
        let classes = class_track(geo, bands, drums)?;
        let bands = if classes.is_some() { &[][..] } else { bands };
        let reads_backing = classes.as_ref().is_some_and(|c| c.wants_backing());
        let backing = if reads_backing || (harmonic_view && pitch.is_some()) {
            Some((Denoise::new(hp, geo.sample_rate)?, Vec::new()))
        } else {
            None
        };
        Ok(StemChain {
            stem,
            denoise: Denoise::new(hp, geo.sample_rate)?,
            buf: Vec::with_capacity(PARALLEL_MIN_BLOCK * 4),
            pitch,
            notes,
            bands: band_tracks(geo, bands)?,
            classes,
            backing,
            samples: 0,
            t_denoise: Duration::ZERO,
            t_pitch: Duration::ZERO,
            t_notes: Duration::ZERO,
            t_classes: Duration::ZERO,
        })
    }

    /// The chain's tracks, in the order they run: pitch, note onsets, drum classes, bands.
    fn tracks(&self) -> impl Iterator<Item = &dyn Track> {
        let pitch = self.pitch.iter().map(|t| t as &dyn Track);
        let notes = self.notes.iter().map(|t| t as &dyn Track);
        let classes = self.classes.iter().map(|t| t as &dyn Track);
        let bands = self.bands.iter().map(|t| t as &dyn Track);
        pitch.chain(notes).chain(classes).chain(bands)
    }

    /// [`StemChain::tracks`], to change.
    fn tracks_mut(&mut self) -> impl Iterator<Item = &mut dyn Track> {
        let pitch = self.pitch.iter_mut().map(|t| t as &mut dyn Track);
        let notes = self.notes.iter_mut().map(|t| t as &mut dyn Track);
        let classes = self.classes.iter_mut().map(|t| t as &mut dyn Track);
        let bands = self.bands.iter_mut().map(|t| t as &mut dyn Track);
        pitch.chain(notes).chain(classes).chain(bands)
    }

    /// Whether this chain reads the separator's harmonic sum beside its stem (a drum
    /// transcriber's backing, a lead's harmonic view).
    fn wants_backing(&self) -> bool {
        self.backing.is_some()
    }

    /// Feeds one block of the stem; `backing`: the separator's bass, vocals and other of
    /// the same span, for a chain that reads their sum ([`StemChain::wants_backing`]).
    fn process(&mut self, block: &[f32], backing: Option<[&[f32]; 3]>) {
        self.samples += block.len();
        let t = Instant::now();
        self.buf.clear();
        self.buf.extend_from_slice(block);
        self.denoise.process_inplace(&mut self.buf);
        let side = match (backing, &mut self.backing) {
            (Some([b, v, o]), Some((denoise, buf))) => {
                buf.clear();
                buf.extend(b.iter().zip(v).zip(o).map(|((b, v), o)| b + v + o));
                denoise.process_inplace(buf);
                Some(&buf[..])
            }
            _ => None,
        };
        self.t_denoise += t.elapsed();
        let input = TrackInput {
            stem: &self.buf,
            side,
            pitch: None,
        };
        if let Some(p) = &mut self.pitch {
            let t = Instant::now();
            Track::process(p, &input);
            self.t_pitch += t.elapsed();
        }
        // Note onsets read the pitch track that has just taken the block.
        let input = TrackInput {
            pitch: self.pitch.as_ref(),
            ..input
        };
        if let Some(n) = &mut self.notes {
            let t = Instant::now();
            n.process(&input);
            self.t_notes += t.elapsed();
        }
        if let Some(c) = &mut self.classes {
            let t = Instant::now();
            Track::process(c, &input);
            self.t_classes += t.elapsed();
        }
        for b in &mut self.bands {
            b.process(&input);
        }
    }

    fn finish(&mut self) {
        let t = Instant::now();
        let none = TrackInput::stem(&[]);
        if let Some(p) = &mut self.pitch {
            Track::finish(p, &none);
        }
        self.t_pitch += t.elapsed();
        let input = TrackInput {
            pitch: self.pitch.as_ref(),
            ..none
        };
        if let Some(n) = &mut self.notes {
            n.finish(&input);
        }
        if let Some(c) = &mut self.classes {
            let t = Instant::now();
            Track::finish(c, &input);
            self.t_classes += t.elapsed();
        }
        for b in &mut self.bands {
            b.finish(&input);
        }
    }

    /// Input samples after which every feature of the chain is final: its slowest track's
    /// latency after the denoiser's.
    fn latency_samples(&self) -> usize {
        self.tracks()
            .map(|t| t.latency_samples())
            .max()
            .unwrap_or(0)
            + self.denoise.latency_samples()
    }

    /// Per-hop and per-bin values the chain holds.
    fn retained(&self) -> usize {
        self.tracks().map(|t| t.retained()).sum()
    }

    /// Forgets the first `d` bins of every track and the per-hop records already binned
    /// (see [`Engine::discard_before`]).
    fn discard(&mut self, d: usize) {
        self.tracks_mut().for_each(|t| t.discard_before(d));
    }

    fn reset(&mut self) {
        self.denoise.reset();
        if let Some((d, _)) = &mut self.backing {
            d.reset();
        }
        self.samples = 0;
        self.tracks_mut().for_each(|t| t.reset());
    }
}

/// An ONNX separator (htdemucs or spleeter), or the error of a build without ONNX.
fn onnx_separator(
    demucs: bool,
    model: &std::path::Path,
    rate: u32,
    stems: StemSet,
    threads: usize,
) -> Result<Box<dyn Separator>, EngineError> {
    #[cfg(feature = "onnx")]
    {
        use tactus_separate::onnx::{
            htdemucs::HtDemucsSeparator, spleeter::SpleeterSeparator, OnnxConfig,
        };
        let cfg = OnnxConfig {
            threads: if threads == 0 {
                std::thread::available_parallelism().map_or(1, |n| n.get())
            } else {
                threads
            },
            ..OnnxConfig::new(model)
        };
        let err = EngineError::Onnx;
        Ok(if demucs {
            Box::new(HtDemucsSeparator::new(rate, stems, &cfg).map_err(err)?)
        } else {
            Box::new(SpleeterSeparator::new(rate, stems, &cfg).map_err(err)?)
        })
    }
    #[cfg(not(feature = "onnx"))]
    {
        let _ = (demucs, model, rate, stems, threads);
        Err(EngineError::Config(
            "this tactus was built without ONNX support: rebuild with `--features onnx` (see README, \"ONNX models\")".into(),
        ))
    }
}

/// Feeds one block to every chain: supplied stems where given, separated ones otherwise.
/// Chains run on their own threads when the block is large enough to pay for it.
fn feed(
    chains: &mut [StemChain],
    sep_out: &StemOutput,
    supplied: &[(Stem, &[f32])],
    parallel: bool,
) {
    type Input<'a> = (&'a mut StemChain, &'a [f32], Option<[&'a [f32]; 3]>);
    let inputs: Vec<Input> = chains
        .iter_mut()
        .map(|c| {
            let stem = c.stem;
            let given = supplied.iter().find(|(s, _)| *s == stem).map(|(_, x)| *x);
            let input = given.unwrap_or_else(|| sep_out.get(stem));
            // A separated stem comes with the harmonic sum the separator made beside it
            // when its chain reads that (a drum transcriber's backing, a lead's view).
            let backing = (given.is_none() && c.wants_backing())
                .then(|| {
                    let parts = [Stem::Bass, Stem::Vocals, Stem::Other].map(|s| sep_out.get(s));
                    parts
                        .iter()
                        .all(|p| p.len() == input.len())
                        .then_some(parts)
                })
                .flatten();
            (c, input, backing)
        })
        .collect();
    let big = inputs.iter().map(|(_, x, _)| x.len()).max().unwrap_or(0) >= PARALLEL_MIN_BLOCK;
    if parallel && big && inputs.len() > 1 {
        std::thread::scope(|s| {
            for (c, x, b) in inputs {
                s.spawn(move || c.process(x, b));
            }
        });
    } else {
        for (c, x, b) in inputs {
            c.process(x, b);
        }
    }
}

/// A separated block and copies of the supplied stems' same span, waiting for the chains.
type PendingBlock = (StemOutput, Vec<(Stem, Vec<f32>)>);

/// The streaming pipeline. See the module docs.
pub struct Engine {
    cfg: EngineConfig,
    geo: Geometry,
    separator: Option<Box<dyn Separator>>,
    sep_out: StemOutput,
    chains: Vec<StemChain>,
    n_in: usize,
    t_separate: Duration,
    /// A separated block (with copies of the supplied stems) waiting for the chains.
    pending: Option<PendingBlock>,
    /// The live profile's drums listen to the mono mix: its samples of the current block.
    mix: Vec<f32>,
    /// Whether the drum chain takes the mix rather than a separated stem.
    drums_on_mix: bool,
    /// Bins forgotten by [`Engine::discard_before`]: the tracks' bin vectors start here.
    bin_base: usize,
}

impl Engine {
    /// Builds the stages the map needs.
    pub fn new(cfg: EngineConfig) -> Result<Engine, EngineError> {
        if cfg.bin_ms == 0 {
            return Err(EngineError::Config(
                "bin length must be at least 1 ms".into(),
            ));
        }
        if cfg.levels == 0 {
            return Err(EngineError::Config("levels must be at least 1".into()));
        }
        let bin_samples = (cfg.sample_rate as u64 * cfg.bin_ms as u64 / 1000).max(1) as usize;
        let geo = Geometry {
            sample_rate: cfg.sample_rate,
            bin_samples,
            levels: cfg.levels,
            mode: cfg.mode,
            level_rule: cfg.level_rule,
            profile: cfg.profile,
        };
        let needs = cfg.map.needs();
        let mut chains = Vec::new();
        let mut separated = StemSet::default();
        for stem in cfg.map.stems() {
            let source = Source::of(cfg.supplied.contains(stem), cfg.separator.kind());
            let stem_recipe = Role::of(stem)
                .map(|role| recipe(role, source, cfg.profile, cfg.separator.kind(), cfg.pitch));
            let notes = needs.note_onsets.contains(&stem).then_some(cfg.note_rule);
            let bands: Vec<Band> = if stem == Stem::Drums {
                needs.bands.clone()
            } else {
                Vec::new()
            };
            let chain = StemChain::new(
                stem,
                geo,
                stem_recipe.as_ref(),
                needs.pitch.contains(&stem),
                notes,
                &bands,
                &cfg.drums,
            )?;
            let wants_backing = chain.wants_backing();
            chains.push(chain);
            // The live profile's drum chain listens to the mix: no separator latency.
            let on_mix = stem == Stem::Drums && cfg.profile == Profile::Live;
            if !cfg.supplied.contains(stem) && !on_mix {
                separated = separated.with(stem);
                // The drum transcriber's backing view and the lead's harmonic view: the
                // spectral separator's other stems (trained on those; other separators'
                // stems go without them, as clean stems do).
                if wants_backing && cfg.separator == SeparatorChoice::Spectral {
                    separated = separated
                        .with(Stem::Bass)
                        .with(Stem::Vocals)
                        .with(Stem::Other);
                }
            }
        }
        let separator: Option<Box<dyn Separator>> = if separated.is_empty() {
            None
        } else {
            Some(match &cfg.separator {
                SeparatorChoice::Spectral => Box::new(
                    SpectralSeparator::new(
                        cfg.sample_rate,
                        separated,
                        match cfg.profile {
                            Profile::Full => SpectralConfig {
                                low_band_drums: cfg.kit_mask,
                                ..SpectralConfig::default()
                            },
                            Profile::Live => profile::separator(),
                        },
                    )
                    .map_err(EngineError::SeparatorSetup)?,
                ),
                SeparatorChoice::Spleeter(model) => {
                    onnx_separator(false, model, cfg.sample_rate, separated, cfg.threads)?
                }
                SeparatorChoice::HtDemucs(model) => {
                    onnx_separator(true, model, cfg.sample_rate, separated, cfg.threads)?
                }
                SeparatorChoice::None => Box::new(
                    NoneSeparator::new(cfg.sample_rate, separated)
                        .map_err(EngineError::SeparatorSetup)?,
                ),
            })
        };
        let drums_on_mix = cfg.profile == Profile::Live
            && !cfg.supplied.contains(Stem::Drums)
            && chains.iter().any(|c| c.stem == Stem::Drums);
        Ok(Engine {
            mix: Vec::with_capacity(if drums_on_mix {
                PARALLEL_MIN_BLOCK * 4
            } else {
                0
            }),
            drums_on_mix,
            sep_out: StemOutput::with_capacity(separated, PARALLEL_MIN_BLOCK * 4),
            cfg,
            geo,
            separator,
            chains,
            n_in: 0,
            t_separate: Duration::ZERO,
            pending: None,
            bin_base: 0,
        })
    }

    /// The configuration the engine was built with.
    pub fn config(&self) -> &EngineConfig {
        &self.cfg
    }

    /// Stems the engine computes features for.
    pub fn stems(&self) -> Vec<Stem> {
        self.chains.iter().map(|c| c.stem).collect()
    }

    /// Name of the separator that runs, if any.
    pub fn separator_name(&self) -> Option<&'static str> {
        self.separator.as_ref().map(|s| s.name())
    }

    /// The separator's per-segment timing, if it runs a network in segments (the ONNX
    /// separators; see [`Separator::segment_stats`]).
    pub fn segment_stats(&self) -> Option<SegmentStats> {
        self.separator.as_ref().and_then(|s| s.segment_stats())
    }

    /// The separator's run-time failure since the last call, if any
    /// ([`Separator::take_error`]), or the ADTLib drum network's: drivers check after
    /// every block and after [`Engine::finish`], and stop with [`EngineError::Separator`]
    /// or [`EngineError::Drums`].
    pub fn take_separator_error(&mut self) -> Option<EngineError> {
        if let Some(e) = self.separator.as_mut().and_then(|s| s.take_error()) {
            return Some(EngineError::Separator(e));
        }
        self.chains
            .iter_mut()
            .find_map(|c| c.classes.as_mut().and_then(|t| t.take_error()))
            .map(EngineError::Drums)
    }

    /// Feeds one block of the mix (planar stereo; pass the same slice twice for mono) and
    /// the same span of every supplied stem. All slices must have the same length.
    pub fn process(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        if self.drums_on_mix {
            // The live profile: the drum chain takes the mono mix, as if it were supplied.
            let mut mix = std::mem::take(&mut self.mix);
            mix.clear();
            mix.extend(left.iter().zip(right).map(|(l, r)| 0.5 * (l + r)));
            let mut with_mix: Vec<(Stem, &[f32])> = Vec::with_capacity(supplied.len() + 1);
            with_mix.extend_from_slice(supplied);
            with_mix.push((Stem::Drums, &mix));
            self.process_inner(left, right, &with_mix);
            self.mix = mix;
        } else {
            self.process_inner(left, right, supplied);
        }
    }

    fn process_inner(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        self.n_in += left.len();
        if self.cfg.pipeline && self.cfg.parallel && self.separator.is_some() {
            self.process_pipelined(left, right, supplied);
            return;
        }
        if let Some(sep) = &mut self.separator {
            let t = Instant::now();
            self.sep_out.clear();
            sep.process(left, right, &mut self.sep_out);
            self.t_separate += t.elapsed();
        }
        feed(&mut self.chains, &self.sep_out, supplied, self.cfg.parallel);
    }

    /// Separates this block on the calling thread while the chains work on the previous one.
    fn process_pipelined(&mut self, left: &[f32], right: &[f32], supplied: &[(Stem, &[f32])]) {
        let Engine {
            separator,
            sep_out,
            chains,
            pending,
            t_separate,
            ..
        } = self;
        let Some(sep) = separator.as_mut() else {
            return;
        };
        let prev = pending.take();
        // Reuse the buffer of the block before last for this block's output.
        let mut out = std::mem::take(sep_out);
        out.clear();
        std::thread::scope(|s| {
            if let Some((p_out, p_sup)) = &prev {
                let chains = &mut *chains;
                s.spawn(move || {
                    let views: Vec<(Stem, &[f32])> =
                        p_sup.iter().map(|(st, v)| (*st, v.as_slice())).collect();
                    feed(chains, p_out, &views, true);
                });
            }
            let t = Instant::now();
            sep.process(left, right, &mut out);
            *t_separate += t.elapsed();
        });
        let copies = supplied.iter().map(|(st, x)| (*st, x.to_vec())).collect();
        *pending = Some((out, copies));
        if let Some((p_out, _)) = prev {
            *sep_out = p_out;
        }
    }

    /// Ends the stream: flushes the separator and every chain, and (offline) computes the
    /// whole-track statistics.
    pub fn finish(&mut self) {
        if let Some((p_out, p_sup)) = self.pending.take() {
            let views: Vec<(Stem, &[f32])> =
                p_sup.iter().map(|(st, v)| (*st, v.as_slice())).collect();
            feed(&mut self.chains, &p_out, &views, self.cfg.parallel);
        }
        if let Some(sep) = &mut self.separator {
            let t = Instant::now();
            self.sep_out.clear();
            sep.finish(&mut self.sep_out);
            self.t_separate += t.elapsed();
            feed(&mut self.chains, &self.sep_out, &[], self.cfg.parallel);
        }
        let parallel = self.cfg.parallel && self.chains.len() > 1 && self.cfg.mode == Mode::Offline;
        if parallel {
            std::thread::scope(|s| {
                for c in &mut self.chains {
                    s.spawn(move || c.finish());
                }
            });
        } else {
            for c in &mut self.chains {
                c.finish();
            }
        }
    }

    /// Samples fed so far.
    pub fn samples_in(&self) -> usize {
        self.n_in
    }

    /// Bin length in samples.
    pub fn bin_samples(&self) -> usize {
        self.geo.bin_samples
    }

    /// Number of bins the whole stream has (after [`Engine::finish`]).
    pub fn total_bins(&self) -> usize {
        self.n_in.div_ceil(self.geo.bin_samples)
    }

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
    /// stays on for [`Profile::pulse_bins`] bins (the minimum pin pulse).
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

    /// Input samples (engine rate) after which a feature of chain `c` is final: its own
    /// look-ahead plus the separator's where the chain takes a separated stem. `None`
    /// when the chain does not compute that feature.
    fn feature_latency(&self, c: &StemChain, what: Feature) -> Option<usize> {
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
    fn fastest_latency(&self) -> usize {
        self.chains
            .iter()
            .flat_map(|c| Feature::ALL.map(|w| self.feature_latency(c, w)))
            .flatten()
            .min()
            .unwrap_or(0)
    }

    /// Bins by which a feature of chain `c` trails the fastest feature in
    /// [`Engine::live_frame`]: its extra latency rounded up to whole bins.
    fn live_shift(&self, c: &StemChain, what: Feature, fastest: usize) -> usize {
        self.feature_latency(c, what).map_or(0, |l| {
            l.saturating_sub(fastest).div_ceil(self.geo.bin_samples)
        })
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
                format!("{} pitch (YIN frame/2, + Viterbi lag{lag})", c.stem.name()),
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

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        if let Some(s) = &mut self.separator {
            s.reset();
        }
        self.sep_out.clear();
        for c in &mut self.chains {
            c.reset();
        }
        self.n_in = 0;
        self.t_separate = Duration::ZERO;
        self.pending = None;
        self.bin_base = 0;
    }
}
