//! Tukey's fences on voiced pitch, in semitones.
//!
//! **Algorithm** (Tukey 1977, *Exploratory Data Analysis*; the paper, §2: "a standard
//! interquartile range with a threshold of 1.5"). With `Q1`, `Q3` the quartiles of the voiced
//! pitch values in semitones and `IQR = Q3 − Q1`, a voiced value is an outlier when it lies
//! strictly outside `[Q1 − k·IQR, Q3 + k·IQR]`; values on a fence are kept. Outliers become
//! unvoiced (0 Hz). Working in semitones makes the fences symmetric in musical terms: an octave
//! jump up (+12) and down (−12) are judged alike, which they are not in Hz.
//!
//! **Quartiles** follow numpy's default (`np.percentile(x, [25, 75])`, method `"linear"`,
//! Hyndman & Fan type 7): sort the `n` values, take the virtual index `h = q·(n − 1)`, and
//! interpolate linearly between the two neighbours `x[⌊h⌋]` and `x[⌊h⌋ + 1]` (numpy's `_lerp`,
//! evaluated from the nearer neighbour). We interpolate in `f64`.
//!
//! **Modes.**
//! * Offline ([`reject_outliers_offline`], paper-faithful): quartiles of the whole track's voiced
//!   pitch. Exact; allocates one `Vec` of the voiced values (the engine calls it once per stem).
//! * Streaming ([`SlidingTukey`]): quartiles of the last `window_hops` voiced values, including
//!   the current one, exact over that window (a ring buffer in arrival order plus a sorted copy,
//!   O(window) per hop by `memmove`, allocation-free after construction). Until `min_count`
//!   voiced values have been seen, values pass through.
//!
//! **Defaults.** `k =` [`TUKEY_K`] = 1.5 (paper). Streaming window [`DEFAULT_WINDOW_HOPS`] =
//! 1000 hops (10 s at 10 ms) and [`DEFAULT_MIN_COUNT`] = 100 voiced hops (1 s): our choice, long
//! enough that the quartiles describe the melody's range rather than the current note.
//!
//! **Minimum IQR (our addition, off in the paper's rule).** A window of a few notes, or a bass
//! line that sits on two or three notes with the odd real leap, has an IQR of a semitone or
//! two, and then the fences cut real notes (and shrink the level range). With
//! `min_iqr_st > 0` the IQR used for the fences is `max(Q3 − Q1, min_iqr_st)`
//! ([`reject_outliers_offline_min_iqr`], [`SlidingTukey::with_min_iqr`]); 0 is the paper's
//! rule exactly.
//!
//! **Latency.** None: the streaming decision for hop `i` uses hops `..= i` only.

use crate::{hz_to_semitones, ConfigError};

/// The paper's fence multiplier.
pub const TUKEY_K: f32 = 1.5;

/// Default streaming window: 10 s of 10 ms hops (counts voiced hops only).
pub const DEFAULT_WINDOW_HOPS: usize = 1000;

/// Default number of voiced hops before the streaming fences start rejecting.
pub const DEFAULT_MIN_COUNT: usize = 100;

/// numpy's `_lerp(a, b, t)`: `a + (b − a)·t`, computed from `b` when `t ≥ 0.5`.
#[inline]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    let d = b - a;
    if t >= 0.5 {
        b - d * (1.0 - t)
    } else {
        a + d * t
    }
}

/// numpy's linear quantile of an ascending, non-empty slice. Panics on an empty slice
/// (internal; callers check).
#[inline]
fn quantile_sorted(sorted: &[f32], q: f64) -> f64 {
    let n = sorted.len();
    let h = q * (n - 1) as f64;
    let lo = (h.floor() as usize).min(n - 1);
    let hi = (lo + 1).min(n - 1);
    lerp(f64::from(sorted[lo]), f64::from(sorted[hi]), h - lo as f64)
}

/// Fences of an ascending, non-empty slice, in `f64`.
#[inline]
fn fences_sorted(sorted: &[f32], k: f64) -> (f64, f64) {
    fences_sorted_min(sorted, k, 0.0)
}

/// Fences with the IQR floored at `min_iqr`.
#[inline]
fn fences_sorted_min(sorted: &[f32], k: f64, min_iqr: f64) -> (f64, f64) {
    let q1 = quantile_sorted(sorted, 0.25);
    let q3 = quantile_sorted(sorted, 0.75);
    let iqr = (q3 - q1).max(min_iqr);
    (q1 - k * iqr, q3 + k * iqr)
}

/// Moves the finite values to the front (order not kept) and returns how many there are.
fn partition_finite(values: &mut [f32]) -> usize {
    let mut m = 0;
    for i in 0..values.len() {
        if values[i].is_finite() {
            values.swap(m, i);
            m += 1;
        }
    }
    m
}

/// First and third quartiles (numpy `percentile(x, [25, 75])`, linear method) of the finite
/// values in `values`, which this sorts in place (non-finite values are moved to the end and
/// ignored). `None` when there is no finite value. O(n log n); does not allocate.
///
/// ```
/// # use tactus_dsp::tukey::quartiles;
/// assert_eq!(quartiles(&mut [4.0, 1.0, 3.0, 2.0]), Some((1.75, 3.25)));
/// ```
pub fn quartiles(values: &mut [f32]) -> Option<(f32, f32)> {
    let m = partition_finite(values);
    if m == 0 {
        return None;
    }
    let finite = &mut values[..m];
    finite.sort_unstable_by(f32::total_cmp);
    Some((
        quantile_sorted(finite, 0.25) as f32,
        quantile_sorted(finite, 0.75) as f32,
    ))
}

/// Tukey's fences `(Q1 − k·IQR, Q3 + k·IQR)` of the finite values in `voiced_semitones`.
/// `None` when there is no finite value or `k` is not finite and ≥ 0. Allocates a copy of the
/// input (offline use).
pub fn fences(voiced_semitones: &[f32], k: f32) -> Option<(f32, f32)> {
    if !(k.is_finite() && k >= 0.0) {
        return None;
    }
    let mut v: Vec<f32> = voiced_semitones
        .iter()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f32::total_cmp);
    let (lo, hi) = fences_sorted(&v, f64::from(k));
    Some((lo as f32, hi as f32))
}

/// Whole-track outlier rejection (paper-faithful). `f0_hz` holds one pitch per hop, 0 = unvoiced.
///
/// Non-finite and non-positive entries are set to 0 (unvoiced) and not counted. Voiced values
/// whose semitone value lies strictly outside the fences of all voiced values become 0.
/// Returns how many voiced values were rejected. A `k` that is not finite and ≥ 0 rejects
/// nothing. Allocates one `Vec` of the voiced semitone values.
pub fn reject_outliers_offline(f0_hz: &mut [f32], k: f32) -> usize {
    reject_outliers_offline_min_iqr(f0_hz, k, 0.0)
}

/// [`reject_outliers_offline`] with the IQR floored at `min_iqr_st` semitones (module docs);
/// a negative or non-finite floor counts as 0.
pub fn reject_outliers_offline_min_iqr(f0_hz: &mut [f32], k: f32, min_iqr_st: f32) -> usize {
    let min_iqr = if min_iqr_st.is_finite() {
        f64::from(min_iqr_st.max(0.0))
    } else {
        0.0
    };
    let mut st = Vec::with_capacity(f0_hz.len());
    for f in f0_hz.iter_mut() {
        if is_voiced(*f) {
            st.push(hz_to_semitones(*f));
        } else {
            *f = 0.0;
        }
    }
    if st.is_empty() || !(k.is_finite() && k >= 0.0) {
        return 0;
    }
    st.sort_unstable_by(f32::total_cmp);
    let (lo, hi) = fences_sorted_min(&st, f64::from(k), min_iqr);
    let mut rejected = 0;
    for f in f0_hz.iter_mut().filter(|f| **f > 0.0) {
        let s = f64::from(hz_to_semitones(*f));
        if s < lo || s > hi {
            *f = 0.0;
            rejected += 1;
        }
    }
    rejected
}

/// A pitch value that counts as voiced: finite, positive, with a finite semitone value.
#[inline]
fn is_voiced(f0_hz: f32) -> bool {
    f0_hz.is_finite() && f0_hz > 0.0 && hz_to_semitones(f0_hz).is_finite()
}

/// Streaming Tukey fences over the last `window_hops` voiced values. See the module docs.
///
/// Unvoiced input (≤ 0 or non-finite) returns 0 and does not enter the window. A voiced value
/// always enters the window (even when it is then rejected), so the window holds exactly the last
/// `window_hops` voiced *inputs*, which keeps the statistics independent of earlier decisions.
#[derive(Debug, Clone)]
pub struct SlidingTukey {
    window: usize,
    k: f64,
    min_count: usize,
    min_iqr: f64,
    /// Semitone values in arrival order; `ring[head]` is the oldest when full.
    ring: Box<[f32]>,
    head: usize,
    len: usize,
    /// The same `len` values, ascending.
    sorted: Box<[f32]>,
}

impl SlidingTukey {
    /// Fences with multiplier `k` over the last `window_hops` voiced values, active once
    /// `min_count` voiced values are in the window.
    ///
    /// Errors unless `window_hops ≥ 1`, `min_count ≤ window_hops` and `k` is finite and ≥ 0.
    /// Allocates two buffers of `window_hops` values (aborts like any allocation if that is
    /// impossibly large).
    pub fn new(window_hops: usize, k: f32, min_count: usize) -> Result<Self, ConfigError> {
        if window_hops == 0 {
            return Err(ConfigError::invalid("window_hops", "must be at least 1"));
        }
        if min_count > window_hops {
            return Err(ConfigError::invalid(
                "min_count",
                format!("{min_count} exceeds window_hops = {window_hops}"),
            ));
        }
        if !(k.is_finite() && k >= 0.0) {
            return Err(ConfigError::invalid("k", "must be finite and >= 0"));
        }
        Ok(SlidingTukey {
            window: window_hops,
            k: f64::from(k),
            min_count,
            min_iqr: 0.0,
            ring: vec![0.0; window_hops].into_boxed_slice(),
            head: 0,
            len: 0,
            sorted: vec![0.0; window_hops].into_boxed_slice(),
        })
    }

    /// The same fences with the IQR floored at `min_iqr_st` semitones (module docs); a
    /// negative or non-finite floor counts as 0.
    pub fn with_min_iqr(mut self, min_iqr_st: f32) -> Self {
        self.min_iqr = if min_iqr_st.is_finite() {
            f64::from(min_iqr_st.max(0.0))
        } else {
            0.0
        };
        self
    }

    /// Voiced values currently in the window.
    pub fn count(&self) -> usize {
        self.len
    }

    /// Current fences in semitones, `None` while fewer than `min_count` (or no) values are in the
    /// window.
    pub fn fences(&self) -> Option<(f32, f32)> {
        if self.len == 0 || self.len < self.min_count {
            return None;
        }
        let (lo, hi) = fences_sorted_min(&self.sorted[..self.len], self.k, self.min_iqr);
        Some((lo as f32, hi as f32))
    }

    /// Feeds one hop's pitch (Hz, 0 = unvoiced); returns it, or 0 when it is unvoiced or an
    /// outlier of the current window. Allocation-free.
    pub fn process(&mut self, f0_hz: f32) -> f32 {
        if !is_voiced(f0_hz) {
            return 0.0;
        }
        let st = hz_to_semitones(f0_hz);
        if self.len == self.window {
            let old = self.ring[self.head];
            self.ring[self.head] = st;
            self.head = (self.head + 1) % self.window;
            // `old` is in `sorted` by construction, so the search finds it; the `Err` arm only
            // keeps the lengths consistent without a panic path.
            let i = match self.sorted[..self.len].binary_search_by(|v| v.total_cmp(&old)) {
                Ok(i) => i,
                Err(i) => i.min(self.len - 1),
            };
            self.sorted.copy_within(i + 1..self.len, i);
            self.len -= 1;
        } else {
            self.ring[(self.head + self.len) % self.window] = st;
        }
        let n = self.len;
        let pos = self.sorted[..n].partition_point(|v| v.total_cmp(&st).is_lt());
        self.sorted.copy_within(pos..n, pos + 1);
        self.sorted[pos] = st;
        self.len = n + 1;

        if self.len < self.min_count {
            return f0_hz;
        }
        let (lo, hi) = fences_sorted_min(&self.sorted[..self.len], self.k, self.min_iqr);
        let s = f64::from(st);
        if s < lo || s > hi {
            0.0
        } else {
            f0_hz
        }
    }

    /// Back to the just-constructed state (empty window).
    pub fn reset(&mut self) {
        self.head = 0;
        self.len = 0;
    }
}
