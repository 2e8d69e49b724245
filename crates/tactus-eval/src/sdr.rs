//! Plain signal-to-distortion ratio of a separated stem ([`tactus_dsp::sdr`]), checked:
//! empty or non-finite input is an error here.
use crate::EvalError;

/// Plain SDR in dB of `estimate` against `reference`.
pub fn sdr_db(reference: &[f32], estimate: &[f32]) -> Result<f64, EvalError> {
    let n = reference.len().max(estimate.len());
    if n == 0 {
        return Err(EvalError::Empty("sdr"));
    }
    if !reference.iter().chain(estimate).all(|x| x.is_finite()) {
        return Err(EvalError::NonFinite("sdr"));
    }
    Ok(tactus_dsp::sdr::sdr_db(reference, estimate))
}
