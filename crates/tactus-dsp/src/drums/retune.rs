//! Test-time retuning of the mel axis (step 4 of the module docs): the network is asked
//! about each hit as if the kit were tuned a little lower and higher.

use crate::melbank::MelConfig;

/// The sample rate whose drum front end ([`MelConfig::drums`]: 20 Hz to 16 kHz) the
/// retunings are computed for: the models are trained at it (`models/drums/train.py`'s
/// `F_LO`, `F_HI`).
const RETUNE_RATE: u32 = 44_100;

/// One test-time retuning of the mel axis (see the module docs, step 4): band `b` of the
/// retuned window interpolates the bands around the one whose centre is `centre_b / ratio`
/// on the drum front end's mel scale (clamped to the first and last band).
#[derive(Clone, Debug, PartialEq)]
pub struct Retuning {
    /// The frequency ratio (1: the window as it is).
    pub ratio: f32,
    /// Per band: the lower source band.
    lower: Vec<usize>,
    /// Per band: the weight of the band above `lower`.
    frac: Vec<f32>,
}

impl Retuning {
    /// The retuning by `ratio` of `bands` mel bands between 20 Hz and 16 kHz.
    pub fn new(ratio: f32, bands: usize) -> Retuning {
        let (mel, hz) = (crate::melbank::hz_to_mel, crate::melbank::mel_to_hz);
        let cfg = MelConfig::drums(RETUNE_RATE);
        let f_hi = cfg.f_hi.min(0.45 * RETUNE_RATE as f32);
        let (lo, hi) = (mel(cfg.f_lo as f64), mel(f_hi as f64));
        let step = (hi - lo) / (bands + 1) as f64;
        let centres: Vec<f64> = (1..=bands).map(|j| lo + step * j as f64).collect();
        let r = ratio as f64;
        let last = bands.saturating_sub(1);
        let (mut lower, mut frac) = (Vec::with_capacity(bands), Vec::with_capacity(bands));
        for &c in &centres {
            let x = mel(hz(c) / r);
            // Fractional band index of x among the centres, clamped to the ends.
            let pos = if bands < 2 || x <= centres[0] {
                0.0
            } else if x >= centres[last] {
                last as f64
            } else {
                let j = centres.partition_point(|&m| m <= x) - 1;
                j as f64 + (x - centres[j]) / (centres[j + 1] - centres[j])
            };
            let i0 = (pos.floor() as usize).min(last);
            lower.push(i0);
            frac.push((pos - i0 as f64) as f32);
        }
        Retuning { ratio, lower, frac }
    }

    /// Whether this retuning leaves the window as it is.
    pub fn is_identity(&self) -> bool {
        self.ratio == 1.0
    }

    /// Retunes a normalised window (`frames × bands`, band inside) into `out` and normalises
    /// it again: its maximum subtracted, clipped at `floor`.
    pub fn apply(&self, window: &[f32], floor: f32, out: &mut [f32]) {
        let bands = self.lower.len();
        let Some(last) = bands.checked_sub(1) else {
            return;
        };
        let mut m = f32::NEG_INFINITY;
        for (src, dst) in window.chunks_exact(bands).zip(out.chunks_exact_mut(bands)) {
            for ((o, &i0), &f) in dst.iter_mut().zip(&self.lower).zip(&self.frac) {
                let a = src[i0];
                let b = src[(i0 + 1).min(last)];
                *o = a + (b - a) * f;
                m = m.max(*o);
            }
        }
        for o in out[..window.len()].iter_mut() {
            *o = (*o - m).max(floor);
        }
    }
}
