//! The render options as the user spells them (the CLI's flags, the Python package's
//! keyword arguments), their engine configuration, and the key a batch compares to decide
//! whether an output is up to date.
//!
//! This is the one place where options become an [`EngineConfig`]: `tactus render` (one
//! song or a library), `tactus play SONG`, `tactus live` and the Python package all go
//! through [`RenderOptions::config_for`]; only the defaults differ by [`Command`].

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use tactus_dsp::Stem;
use tactus_engine::{
    recipe, DrumMethod, EngineConfig, LevelRule, Mode, NoteRule, PitchMethod, Profile,
    SeparatorChoice,
};
use tactus_glove::GloveMap;

use crate::BatchError;

/// Render options by their CLI names (`--separator` is `separator`, `--bin-ms` is
/// `bin_ms`, ...). `None` means the CLI's default for `render`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderOptions {
    /// `spectral` (default), `htdemucs`, `spleeter` or `none`.
    pub separator: Option<String>,
    /// ONNX model for `htdemucs` / `spleeter`.
    pub model: Option<PathBuf>,
    /// Bin length in ms (default 100).
    pub bin_ms: Option<u32>,
    /// Pitch levels per melodic stem, 1..=8 (default 8).
    pub levels: Option<u8>,
    /// A built-in map name or a TOML map file (default: the paper's map).
    pub map: Option<String>,
    /// `auto` (default), `yin`, `pyin` or `shs`.
    pub pitch: Option<String>,
    /// `classes` (default; `classes-live` for `tactus live`), `classes-live`, `bands` or
    /// `adtlib`.
    pub drums: Option<String>,
    /// ONNX model for `drums = "adtlib"`.
    pub drum_model: Option<PathBuf>,
    /// `follow` (default) or `paper`.
    pub levels_rule: Option<String>,
    /// Note onsets of the melodic stems: `attack` (default: pitch and the stem's level),
    /// `legato` (the same, but the bass of a mix may change note without an attack) or
    /// `pitch` (the pitch alone, the first implementation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note_onsets: Option<String>,
    /// The spectral separator's learned kit mask, which moves kick and tom bodies out of
    /// the bass stem: `on` (default) or `off` (the median filter alone; see
    /// `docs/decisions/0020-kit-mask.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kit_mask: Option<String>,
    /// `offline` (default) or `streaming`.
    pub mode: Option<String>,
    /// Stems supplied directly, `(name, path)`: drums, bass, vocals, other (single
    /// renders only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stems: Vec<(String, PathBuf)>,
    /// ONNX Runtime intra-op threads (0 or `None`: the available cores). Does not change
    /// the result.
    pub threads: Option<u32>,
    /// Latency profile: `full` (default; `live` for [`Command::Live`]) or `live`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub profile: Option<String>,
}

/// The pitch trackers a user may name (`--pitch`), in the CLI's order.
const PITCH_CHOICES: [PitchMethod; 5] = [
    PitchMethod::Auto,
    PitchMethod::Yin,
    PitchMethod::Pyin,
    PitchMethod::Shs,
    PitchMethod::AutoShs,
];

/// The command the options are for: `live` and `play` have other defaults than `render`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Command {
    /// `tactus render` and the Python package: 100 ms bins, the full profile.
    #[default]
    Render,
    /// `tactus play SONG`: 25 ms bins.
    Play,
    /// `tactus live`: the live profile (10 ms bins, drums by the 1-hop transcriber); with `profile =
    /// "full"`, 25 ms bins and pYIN.
    Live,
}

fn choice<'a>(
    flag: &str,
    given: Option<&'a str>,
    default: &'a str,
    allowed: &[&str],
) -> Result<&'a str, BatchError> {
    let v = given.unwrap_or(default);
    if allowed.contains(&v) {
        Ok(v)
    } else {
        Err(BatchError::Options(format!(
            "invalid value '{v}' for '--{flag} <{}>' [possible values: {}]",
            flag.to_uppercase().replace('-', "_"),
            allowed.join(", ")
        )))
    }
}

/// [`choice`] for options whose values map to plain values: the value `table` pairs with
/// the name given (or `default`).
/// `v` when it is in `lo..=hi`, else clap's message for option `arg` (`--levels <LEVELS>`).
fn in_range<T>(arg: &str, v: T, lo: T, hi: T) -> Result<T, BatchError>
where
    T: PartialOrd + std::fmt::Display,
{
    if lo <= v && v <= hi {
        Ok(v)
    } else {
        Err(BatchError::Options(format!(
            "invalid value '{v}' for '{arg}': {v} is not in {lo}..={hi}"
        )))
    }
}

fn pick<T: Copy>(
    flag: &str,
    given: Option<&str>,
    default: &str,
    table: &[(&str, T)],
) -> Result<T, BatchError> {
    let names: Vec<&str> = table.iter().map(|(n, _)| *n).collect();
    let name = choice(flag, given, default, &names)?;
    Ok(table
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(table[0].1, |(_, v)| *v))
}

impl RenderOptions {
    /// The engine configuration, with the CLI's defaults and its one-line messages.
    /// `parallel`: whether the engine may start threads of its own
    /// ([`EngineConfig::parallel`]).
    pub fn to_config(
        &self,
        parallel: bool,
    ) -> Result<(EngineConfig, Vec<(Stem, PathBuf)>), BatchError> {
        self.config_for(Command::Render, parallel)
    }

    /// The engine configuration for `command`, with that command's defaults (see
    /// [`Command`]) and the CLI's one-line messages.
    pub fn config_for(
        &self,
        command: Command,
        parallel: bool,
    ) -> Result<(EngineConfig, Vec<(Stem, PathBuf)>), BatchError> {
        let live = command == Command::Live;
        let err = |s: String| BatchError::Options(s);
        let model = |name: &str| -> Result<PathBuf, BatchError> {
            self.model.clone().ok_or_else(|| {
                err(format!(
                    "--separator {name} needs --model PATH (see docs/install.md, \"ONNX models\")"
                ))
            })
        };
        let separator = match choice(
            "separator",
            self.separator.as_deref(),
            "spectral",
            &["spectral", "htdemucs", "spleeter", "none"],
        )? {
            "spectral" => SeparatorChoice::Spectral,
            "none" => SeparatorChoice::None,
            "spleeter" => SeparatorChoice::Spleeter(model("spleeter")?),
            _ => SeparatorChoice::HtDemucs(model("htdemucs")?),
        };
        let map = match &self.map {
            Some(p) => GloveMap::from_name_or_path(p).map_err(BatchError::Map)?,
            None => GloveMap::default(),
        };
        let levels = in_range("--levels <LEVELS>", self.levels.unwrap_or(8), 1, 8)?;
        let profile = pick(
            "profile",
            self.profile.as_deref(),
            if live { "live" } else { "full" },
            &[("full", Profile::Full), ("live", Profile::Live)],
        )?;
        let bin_ms = self.bin_ms.unwrap_or(match (profile, command) {
            (Profile::Live, _) => tactus_engine::profile::BIN_MS,
            (Profile::Full, Command::Render) => 100,
            (Profile::Full, _) => 25,
        });
        let bin_ms = in_range("--bin-ms <BIN_MS>", bin_ms, 1, 10_000)?;
        // The user's choice; which tracker each stem then runs is the recipe table's
        // (`tactus_engine::recipe`).
        let pitch = pick(
            "pitch",
            self.pitch.as_deref(),
            recipe::default_pitch(live, profile).name(),
            &PITCH_CHOICES.map(|m| (m.name(), m)),
        )?;
        let level_rule = pick(
            "levels-rule",
            self.levels_rule.as_deref(),
            "follow",
            &[("follow", LevelRule::Follow), ("paper", LevelRule::Paper)],
        )?;
        let note_rule = pick(
            "note-onsets",
            self.note_onsets.as_deref(),
            "attack",
            &[
                ("attack", NoteRule::Attack),
                ("legato", NoteRule::Legato),
                ("pitch", NoteRule::Pitch),
            ],
        )?;
        let kit_mask = pick(
            "kit-mask",
            self.kit_mask.as_deref(),
            "on",
            &[("on", true), ("off", false)],
        )?;
        let drums_name = choice(
            "drums",
            self.drums.as_deref(),
            // Live, and any command in the live profile, uses the per-instrument transcriber's
            // 1-hop model (held-out mix kick F 0.80 against the bands' 0.29; rhythm p95 29.1 ms
            // end to end, 12 of 12 hits of tests/live.rs;
            // docs/decisions/0015-live-drums-by-the-one-hop-model.md): the full model's
            // 61.6 ms look-ahead does not fit the live profile's budget, and `render --profile
            // live` computes what `live` does (docs/decisions/0054-live-profile-drums.md).
            if live || profile == Profile::Live {
                "classes-live"
            } else {
                "classes"
            },
            &["classes", "classes-live", "bands", "adtlib"],
        )?;
        let drums =
            match (drums_name, self.drum_model.clone()) {
                ("bands", Some(_)) => return Err(err(
                    "--drum-model is for --drums classes, classes-live (a Tactus drum model file) \
                     or adtlib (an ONNX file), not bands"
                        .into(),
                )),
                ("bands", None) => DrumMethod::Bands,
                ("adtlib", model) => DrumMethod::AdtLib(model.ok_or_else(|| {
                    err(
                    "--drums adtlib needs --drum-model PATH (see docs/install.md, \"ONNX models\")"
                        .into(),
                )
                })?),
                // A model file of models/drums/train.py or train_cnn.py in place of the embedded
                // one; its own context decides its latency.
                (_, Some(path)) => DrumMethod::ClassesFile(path),
                ("classes-live", None) => DrumMethod::ClassesLive,
                _ => DrumMethod::Classes,
            };
        let mode = pick(
            "mode",
            self.mode.as_deref(),
            if command == Command::Render {
                "offline"
            } else {
                "streaming"
            },
            &[("offline", Mode::Offline), ("streaming", Mode::Streaming)],
        )?;
        let stems = self
            .stems
            .iter()
            .map(|(name, path)| {
                Stem::from_name(name)
                    .map(|s| (s, path.clone()))
                    .ok_or_else(|| {
                        err(format!(
                            "--stem {name}={}: unknown stem {name:?} (drums, bass, vocals, other)",
                            path.display()
                        ))
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let cfg = EngineConfig {
            bin_ms,
            levels,
            mode,
            pitch,
            level_rule,
            note_rule,
            kit_mask,
            map,
            separator,
            drums,
            threads: self.threads.map_or(0, |n| n as usize),
            parallel,
            profile,
            ..EngineConfig::default()
        };
        Ok((cfg, stems))
    }

    /// What decides whether a batch output is up to date: every option that can change
    /// the result, with defaults filled in, the map as the SHA-256 of its TOML (so an
    /// edited map file renders again), and the Tactus version. `threads` is left out (it
    /// changes only the speed).
    pub fn key(&self) -> Result<serde_json::Value, BatchError> {
        let (cfg, _) = self.to_config(false)?;
        let map_sha = tactus_glove::sha256_hex(cfg.map.to_toml_string().as_bytes())
            .map_err(|e| BatchError::Options(e.to_string()))?;
        let mut key = serde_json::json!({
            "tactus": env!("CARGO_PKG_VERSION"),
            "separator": self.separator.as_deref().unwrap_or("spectral"),
            "model": self.model.as_ref().map(|p| p.display().to_string()),
            "bin_ms": cfg.bin_ms,
            "levels": cfg.levels,
            "map_sha256": map_sha,
            "pitch": self.pitch.as_deref().unwrap_or("auto"),
            "drums": self.drums.as_deref().unwrap_or("classes"),
            "drum_model": self.drum_model.as_ref().map(|p| p.display().to_string()),
            "levels_rule": self.levels_rule.as_deref().unwrap_or("follow"),
            "mode": self.mode.as_deref().unwrap_or("offline"),
        });
        // Named only when it is not the default, so that manifests written before the
        // profile was an option stay up to date.
        if cfg.profile != Profile::Full {
            key["profile"] = cfg.profile.name().into();
        }
        if cfg.note_rule != NoteRule::Attack {
            key["note_onsets"] = self.note_onsets.as_deref().unwrap_or("attack").into();
        }
        if !cfg.kit_mask {
            key["kit_mask"] = "off".into();
        }
        Ok(key)
    }
}
