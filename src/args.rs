//! The engine options that `render`, `play` and `live` share, as the user spells them, and
//! their engine configuration (made by `tactus_batch`, as for a library).

use std::path::PathBuf;

use anyhow::{anyhow, Result};
use clap::ValueEnum;

use tactus_batch::{Command, RenderOptions};

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum SepArg {
    Spectral,
    Htdemucs,
    Spleeter,
    None,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum ModeArg {
    Offline,
    Streaming,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
pub(crate) enum DrumsArg {
    /// Per-instrument transcriber embedded in Tactus (default).
    Classes,
    /// The same with its low-latency model (21.6 ms instead of 61.6 ms), for live input (the
    /// default for live and --profile live).
    ClassesLive,
    /// The paper's four Butterworth bands with spectral-flux onsets.
    Bands,
    /// ADTLib's networks through ONNX (kick, snare, hi-hat; needs --drum-model).
    Adtlib,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum PitchArg {
    /// The learned salience on the spectral separator's stems (models/bassnet/README.md): for
    /// the bass times the harmonic sum; for the lead (vocals) the harmonic sum decides
    /// whether and the learned lead model which pitch. The harmonic sum for other basses and
    /// leads, pYIN for the rest.
    Auto,
    /// The default before the learned salience: the harmonic sum for every bass and the
    /// lead, pYIN for the rest.
    AutoShs,
    Yin,
    Pyin,
    /// Harmonic-sum salience + Viterbi (made for a bass line or a lead in a mix) on every stem.
    Shs,
}

/// Latency profile (`tactus_engine::profile`; `docs/decisions/0006-live-latency-profile.md`).
#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum ProfileArg {
    /// Quality first: every stage as documented (render and play).
    Full,
    /// Milliseconds first: drums on the mix, short frames, no look-ahead, 10 ms bins with
    /// 50 ms pin pulses (the default for live).
    Live,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum NoteOnsetsArg {
    Attack,
    Legato,
    Pitch,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum KitMaskArg {
    On,
    Off,
}

#[derive(Clone, Copy, ValueEnum)]
pub(crate) enum LevelRuleArg {
    Follow,
    Paper,
}

/// Settings shared by `render` and `play`: how the song becomes glove frames.
#[derive(clap::Args)]
pub(crate) struct EngineArgs {
    /// Source separator.
    #[arg(long, value_enum, default_value = "spectral")]
    pub(crate) separator: SepArg,
    /// ONNX model for --separator htdemucs|spleeter.
    #[arg(long)]
    pub(crate) model: Option<PathBuf>,
    /// Threads ONNX Runtime may use inside one network call (--separator
    /// htdemucs|spleeter) [default: the available cores].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub(crate) threads: Option<u32>,
    /// Supply a stem and skip separating it: NAME=PATH, NAME in drums, bass, vocals, other.
    #[arg(long = "stem", value_name = "NAME=PATH")]
    pub(crate) stems: Vec<String>,
    /// Bin length in milliseconds (default: 100 for render, as in the paper; 25 for play;
    /// 10 with the live profile).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub(crate) bin_ms: Option<u32>,
    /// Pitch levels per melodic stem (1..=8: a level raises one of a cell's 8 dots).
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub(crate) levels: u8,
    /// Glove map (TOML); the default is the paper's map.
    #[arg(long)]
    pub(crate) map: Option<PathBuf>,
    /// Pitch tracker.
    /// [default: auto (the live profile: the live learned models for the bass and the lead,
    /// YIN on short frames for the rest); pyin for live --profile full]
    #[arg(long, value_enum)]
    pub(crate) pitch: Option<PitchArg>,
    /// Drum transcription: classes (embedded per-instrument transcriber; the default for
    /// render and play), classes-live (the same with its 21.6 ms model; the default for live
    /// and for --profile live), bands (the paper's band-pass) or adtlib (ONNX, --drum-model
    /// models/adtlib.onnx).
    #[arg(long, value_enum)]
    pub(crate) drums: Option<DrumsArg>,
    /// Drum model file: for --drums adtlib the ONNX file of models/setup_adtlib.sh; for
    /// classes or classes-live a Tactus drum model (models/drums/train.py, train_cnn.py)
    /// in place of the embedded one.
    #[arg(long)]
    pub(crate) drum_model: Option<PathBuf>,
    /// How pitch becomes levels: follow (floored Tukey IQR, a streaming range prior) or the
    /// paper's rule.
    #[arg(long, value_enum, default_value = "follow")]
    pub(crate) levels_rule: LevelRuleArg,
    /// Note onsets of bass, vocals and other: attack (the pitch track and the stem's level:
    /// re-attacks of a held note, onsets at the attack; on a mix the bass changes note only
    /// with an attack), legato (the same, without that bass rule: legato bass lines) or
    /// pitch (the pitch track alone).
    #[arg(long, value_enum, default_value = "attack")]
    pub(crate) note_onsets: NoteOnsetsArg,
    /// The spectral separator's learned kit mask: on (kick and tom bodies leave the bass
    /// stem for the drums) or off (the median filter alone).
    #[arg(long, value_enum, default_value = "on")]
    pub(crate) kit_mask: KitMaskArg,
    /// Latency profile: full (quality first) or live (under 40 ms to the rhythm pins;
    /// 10 ms bins). [default: live for live, full for render and play]
    #[arg(long, value_enum)]
    pub(crate) profile: Option<ProfileArg>,
}

impl EngineArgs {
    /// The engine options given with other than their default values.
    pub(crate) fn given(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        let mut add = |on: bool, name| {
            if on {
                v.push(name);
            }
        };
        add(!matches!(self.separator, SepArg::Spectral), "--separator");
        add(self.model.is_some(), "--model");
        add(self.threads.is_some(), "--threads");
        add(!self.stems.is_empty(), "--stem");
        add(self.bin_ms.is_some(), "--bin-ms");
        add(self.levels != 8, "--levels");
        add(self.map.is_some(), "--map");
        add(self.pitch.is_some(), "--pitch");
        add(
            !matches!(self.levels_rule, LevelRuleArg::Follow),
            "--levels-rule",
        );
        add(
            !matches!(self.note_onsets, NoteOnsetsArg::Attack),
            "--note-onsets",
        );
        add(!matches!(self.kit_mask, KitMaskArg::On), "--kit-mask");
        add(self.drums.is_some(), "--drums");
        add(self.drum_model.is_some(), "--drum-model");
        add(self.profile.is_some(), "--profile");
        v
    }

    /// The engine configuration for `command` and the supplied stems: the options by
    /// their CLI names, turned into a configuration by `tactus_batch` as for a library.
    pub(crate) fn config(
        &self,
        command: Command,
        mode: ModeArg,
    ) -> Result<(
        tactus_engine::EngineConfig,
        Vec<(tactus_dsp::Stem, PathBuf)>,
    )> {
        let mut opts = self.options(mode);
        for s in &self.stems {
            let (name, path) = s
                .split_once('=')
                .ok_or_else(|| anyhow!("--stem {s:?}: expected NAME=PATH"))?;
            opts.stems.push((name.to_string(), path.into()));
        }
        Ok(opts.config_for(command, true)?)
    }

    /// The options by their CLI names (stems left out).
    pub(crate) fn options(&self, mode: ModeArg) -> RenderOptions {
        fn name<T: ValueEnum>(v: &T) -> Option<String> {
            v.to_possible_value().map(|p| p.get_name().to_string())
        }
        RenderOptions {
            separator: name(&self.separator),
            model: self.model.clone(),
            bin_ms: self.bin_ms,
            levels: Some(self.levels),
            map: self.map.as_ref().map(|p| p.display().to_string()),
            pitch: self.pitch.as_ref().and_then(name),
            drums: self.drums.as_ref().and_then(name),
            drum_model: self.drum_model.clone(),
            levels_rule: name(&self.levels_rule),
            note_onsets: name(&self.note_onsets),
            kit_mask: name(&self.kit_mask),
            mode: name(&mode),
            stems: Vec::new(),
            threads: self.threads,
            profile: self.profile.as_ref().and_then(name),
        }
    }
}
