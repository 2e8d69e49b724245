//! The separator the engine runs for the stems it does not get directly.

use tactus_separate::none::NoneSeparator;
use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
use tactus_separate::{Separator, StemSet};

use super::{EngineConfig, SeparatorChoice};
use crate::profile::{self, Profile};
use crate::EngineError;

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
            "this tactus was built without ONNX support: rebuild with `--features onnx` (see docs/install.md, \"ONNX models\")".into(),
        ))
    }
}

/// The separator that splits the mix into the `separated` stems as `cfg` says (`None` when
/// the engine needs no stem from it).
pub(super) fn separator_for(
    cfg: &EngineConfig,
    separated: StemSet,
) -> Result<Option<Box<dyn Separator>>, EngineError> {
    Ok(if separated.is_empty() {
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
    })
}
