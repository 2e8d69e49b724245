//! The live loop's time per block, as a histogram that never allocates.

/// A histogram of durations on log-spaced buckets (10 per decade from 1 µs to 10 s), kept
/// in a fixed array: recording never allocates. Quantiles are read as a bucket's upper
/// edge, so they overstate by at most one bucket (26 %).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockTimes {
    counts: [u64; BlockTimes::BUCKETS],
    max_us: f64,
    n: u64,
}

impl Default for BlockTimes {
    fn default() -> Self {
        BlockTimes {
            counts: [0; BlockTimes::BUCKETS],
            max_us: 0.0,
            n: 0,
        }
    }
}

impl BlockTimes {
    const BUCKETS: usize = 71;

    /// Upper edge of bucket `i`, µs: 10^(i/10).
    fn edge(i: usize) -> f64 {
        10f64.powf(i as f64 / 10.0)
    }

    /// Records one duration, µs.
    pub fn record(&mut self, us: f64) {
        let us = if us.is_finite() { us.max(0.0) } else { 0.0 };
        let i = if us <= 1.0 {
            0
        } else {
            ((us.log10() * 10.0).ceil() as usize).min(Self::BUCKETS - 1)
        };
        self.counts[i] += 1;
        self.n += 1;
        self.max_us = self.max_us.max(us);
    }

    /// How many durations were recorded.
    pub fn count(&self) -> u64 {
        self.n
    }

    /// The largest, µs.
    pub fn max_us(&self) -> f64 {
        self.max_us
    }

    /// The `q` quantile (0..=1), µs: the upper edge of the bucket holding it (never above
    /// the maximum); 0 when empty.
    pub fn quantile_us(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let rank = ((self.n as f64 * q.clamp(0.0, 1.0)).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return Self::edge(i).min(self.max_us);
            }
        }
        self.max_us
    }

    /// Counts per range, for printing: (upper edge µs, count) of the non-empty buckets
    /// merged into the ranges ≤ 50 µs, 100, 200, 500 µs, 1, 2, 5, 10, 20, 50, 100 ms and
    /// above.
    pub fn ranges(&self) -> Vec<(f64, u64)> {
        const EDGES: [f64; 11] = [50.0, 100.0, 200.0, 500.0, 1e3, 2e3, 5e3, 1e4, 2e4, 5e4, 1e5];
        let mut out: Vec<(f64, u64)> = EDGES.iter().map(|&e| (e, 0)).collect();
        out.push((f64::INFINITY, 0));
        for (i, &c) in self.counts.iter().enumerate() {
            // Bucket i holds (edge(i-1), edge(i)]; its upper edge decides the range.
            let e = Self::edge(i);
            let k = EDGES
                .iter()
                .position(|&x| e <= x * (1.0 + 1e-9))
                .unwrap_or(EDGES.len());
            out[k].1 += c;
        }
        out
    }
}

/// `p50 158 us, p99 631 us, p99.9 3981 us, max 16057 us; histogram: <=100 us 1855, ...`:
/// the quantiles and the non-empty [`BlockTimes::ranges`], as `tactus live` prints them.
impl std::fmt::Display for BlockTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "p50 {:.0} us, p99 {:.0} us, p99.9 {:.0} us, max {:.0} us; histogram:",
            self.quantile_us(0.5),
            self.quantile_us(0.99),
            self.quantile_us(0.999),
            self.max_us()
        )?;
        let mut first = true;
        for (edge, n) in self.ranges().into_iter().filter(|r| r.1 > 0) {
            f.write_str(if first { " " } else { ", " })?;
            first = false;
            if !edge.is_finite() {
                write!(f, ">100 ms {n}")?;
            } else if edge < 1e3 {
                write!(f, "<={edge:.0} us {n}")?;
            } else {
                write!(f, "<={:.0} ms {n}", edge / 1e3)?;
            }
        }
        if first {
            f.write_str(" empty")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle: the nearest-rank quantile of the sorted values.
    fn exact(v: &mut [f64], q: f64) -> f64 {
        v.sort_by(f64::total_cmp);
        v[((v.len() as f64 * q).ceil() as usize).clamp(1, v.len()) - 1]
    }

    #[test]
    fn block_time_quantiles_are_within_one_bucket_of_the_sorted_values() {
        let mut seed = 7u32;
        let mut v = Vec::new();
        let mut h = BlockTimes::default();
        for _ in 0..20_000 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            // Log-uniform from 10 us to 100 ms.
            let us = 10f64.powf(1.0 + 4.0 * f64::from(seed >> 8) / f64::from(1u32 << 24));
            v.push(us);
            h.record(us);
        }
        for q in [0.01, 0.5, 0.9, 0.99, 0.999, 1.0] {
            let want = exact(&mut v, q);
            let got = h.quantile_us(q);
            // An upper bucket edge: never below, at most one bucket (10^0.1) above.
            assert!(
                got >= want * (1.0 - 1e-9) && got <= want * 10f64.powf(0.1) * (1.0 + 1e-9),
                "q {q}: {got} for {want}"
            );
        }
        assert_eq!(h.count(), 20_000);
        assert_eq!(h.max_us(), v.iter().cloned().fold(0.0, f64::max));
        assert_eq!(h.ranges().iter().map(|r| r.1).sum::<u64>(), 20_000);
        // Each value lands in the first range whose edge is at least its bucket's edge.
        let mut one = BlockTimes::default();
        one.record(150.0);
        one.record(150_000.0);
        let r = one.ranges();
        assert_eq!(r.iter().find(|x| x.0 == 200.0).unwrap().1, 1);
        assert_eq!(r.last().unwrap(), &(f64::INFINITY, 1));
        assert_eq!(BlockTimes::default().quantile_us(0.5), 0.0);
        assert_eq!(
            one.to_string(),
            "p50 158 us, p99 150000 us, p99.9 150000 us, max 150000 us; histogram: \
             <=200 us 1, >100 ms 1"
        );
    }
}
