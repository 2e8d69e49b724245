//! What the engine is told up front: the rate, bins, levels, modes, trackers, map,
//! separator and stems.

use std::time::Duration;

use tactus_glove::GloveMap;
use tactus_separate::StemSet;

use crate::drums::DrumMethod;
use crate::notes::NoteRule;
use crate::profile::Profile;
use crate::recipe::{PitchMethod, SeparatorKind};
use crate::track::{LevelRule, Mode};

/// The engine's default sample rate; inputs are resampled to it.
pub const ENGINE_RATE: u32 = 44_100;

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
    /// Sample rate of the blocks given to [`super::Engine::process`].
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
    /// each; offline, each chain keeps its thread for the whole song and takes blocks from
    /// a queue, docs/decisions/0056-offline-chains-on-their-own-threads.md). Delays the
    /// chains by a block or two; results are identical. The offline driver turns it on; a
    /// live caller with small blocks leaves it off.
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
