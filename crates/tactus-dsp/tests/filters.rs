//! Tests for the Butterworth SOS filters (`sos`) and the running median (`median`).
//!
//! Oracles: a direct-form f64 filter built from the expanded b/a polynomials, the analytic
//! Butterworth magnitude, the FFT of long impulse responses, and a sort-the-window median.
//!
//! The allocation guard below is the one `unsafe` item in this file: `GlobalAlloc` is an
//! unsafe trait, and implementing it is the only way to observe allocations. It only counts
//! and forwards to `System`. The library itself stays `#![forbid(unsafe_code)]`.

use std::f64::consts::PI;

use proptest::prelude::*;
use realfft::RealFftPlanner;
use tactus_dsp::median::{median_centered, MedianFilter};
use tactus_dsp::sanitize::sanitize;
use tactus_dsp::sos::{band_edges, band_response, butterworth, Response, Sos, SosFilter};
use tactus_dsp::{Band, ConfigError, SampleStage};

// ---------------------------------------------------------------------------------------
// Allocation counting (per thread, since tests run on parallel threads).

#[global_allocator]
static GLOBAL: tactus_testkit::Counting = tactus_testkit::Counting;

fn allocations_during(f: impl FnOnce()) -> u64 {
    tactus_testkit::allocations_during(f) as u64
}

// ---------------------------------------------------------------------------------------
// Helpers.

/// xorshift64*: a seeded, dependency-free source of test signals.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [-1, 1).
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

fn white(seed: u64, n: usize) -> Vec<f32> {
    let mut r = Rng(seed);
    (0..n).map(|_| r.uniform() as f32).collect()
}

/// A "musical" test signal: a decaying harmonic tone at 110 Hz, a vibrato tone around
/// 440 Hz, and a click every 0.25 s (drum-like), at `fs`.
fn musical(fs: u32, n: usize) -> Vec<f32> {
    let fs = f64::from(fs);
    (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            let bass: f64 = (1..=6)
                .map(|h| (2.0 * PI * 110.0 * h as f64 * t).sin() / h as f64)
                .sum::<f64>()
                * 0.3
                * (-t % 1.0).exp();
            let vib = 0.2 * (2.0 * PI * 440.0 * t + 3.0 * (2.0 * PI * 5.0 * t).sin()).sin();
            let click = if i % (fs as usize / 4) == 0 { 0.9 } else { 0.0 };
            (bass + vib + click) as f32
        })
        .collect()
}

fn run(f: &mut impl SampleStage, x: &[f32]) -> Vec<f32> {
    let mut y = vec![0.0; x.len()];
    f.process(x, &mut y);
    y
}

fn impulse_response(f: &mut SosFilter, n: usize) -> Vec<f32> {
    let mut x = vec![0.0f32; n];
    x[0] = 1.0;
    f.reset();
    run(f, &x)
}

fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            r[i + j] += a * b;
        }
    }
    r
}

/// The slow, obvious oracle: expand the cascade into one b/a pair and run direct form I.
fn direct_form(sections: &[Sos], x: &[f32]) -> Vec<f64> {
    let mut b = vec![1.0];
    let mut a = vec![1.0];
    for s in sections {
        b = poly_mul(&b, &s.b);
        a = poly_mul(&a, &s.a);
    }
    let mut y = vec![0.0f64; x.len()];
    for n in 0..x.len() {
        let mut acc = 0.0;
        for (k, bk) in b.iter().enumerate() {
            if n >= k {
                acc += bk * f64::from(x[n - k]);
            }
        }
        for (k, ak) in a.iter().enumerate().skip(1) {
            if n >= k {
                acc -= ak * y[n - k];
            }
        }
        y[n] = acc;
    }
    y
}

/// Independent analytic Butterworth magnitude (bilinear, prewarped) at `f`.
fn analytic_magnitude(order: usize, response: Response, fs: f64, f: f64) -> f64 {
    let t = |x: f64| (PI * x / fs).tan();
    let ratio = match response {
        Response::LowPass { cutoff_hz } => t(f) / t(cutoff_hz),
        Response::HighPass { cutoff_hz } => t(cutoff_hz) / t(f),
        Response::BandPass { low_hz, high_hz } => {
            let (lo, hi, w) = (t(low_hz), t(high_hz), t(f));
            (w * w - lo * hi) / (w * (hi - lo))
        }
    };
    1.0 / (1.0 + ratio.abs().powi(2 * order as i32)).sqrt()
}

fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

const RATES: [u32; 5] = [8000, 22050, 44100, 48000, 96000];

// ---------------------------------------------------------------------------------------
// Design.

#[test]
fn design_matches_analytic_butterworth_magnitude() {
    let mut cases: Vec<(usize, Response, u32)> = Vec::new();
    for &fs in &RATES {
        let nyq = f64::from(fs) / 2.0;
        for order in 1..=8 {
            for frac in [0.001, 0.01, 0.1, 0.3, 0.6, 0.85] {
                let fc = frac * nyq;
                cases.push((order, Response::LowPass { cutoff_hz: fc }, fs));
                cases.push((order, Response::HighPass { cutoff_hz: fc }, fs));
            }
            for (lo, hi) in [(0.002, 0.01), (0.05, 0.4), (0.3, 0.35), (0.1, 0.85)] {
                let r = Response::BandPass {
                    low_hz: lo * nyq,
                    high_hz: hi * nyq,
                };
                cases.push((order, r, fs));
            }
        }
    }
    for &fs in &[44100, 48000, 192000] {
        for band in Band::ALL {
            cases.push((4, band_response(band, fs).unwrap(), fs));
        }
    }
    for (order, response, fs) in cases {
        let sections = butterworth(order, response, fs).unwrap();
        let want_sections = match response {
            Response::BandPass { .. } => order,
            _ => order.div_ceil(2),
        };
        assert_eq!(sections.len(), want_sections, "{order} {response:?}");
        let filter = SosFilter::new(sections);
        for s in filter.sections() {
            assert_eq!(s.a[0], 1.0);
        }
        // Log-spaced grid from 1 Hz (or lower) to just below Nyquist, plus the edges.
        let nyq = f64::from(fs) / 2.0;
        let mut grid: Vec<f64> = (0..400)
            .map(|i| nyq * 10f64.powf(-5.0 * (1.0 - i as f64 / 400.0)))
            .collect();
        match response {
            Response::LowPass { cutoff_hz } | Response::HighPass { cutoff_hz } => {
                grid.push(cutoff_hz)
            }
            Response::BandPass { low_hz, high_hz } => grid.extend([low_hz, high_hz]),
        }
        for f in grid {
            let (got, _) = filter.response_at(f, fs);
            let want = analytic_magnitude(order, response, f64::from(fs), f);
            // Both are exact formulas in f64; the sections' rounding (~1e-16 relative in
            // each coefficient) is amplified near poles at radius 1 - 1e-4 by at most ~1e4,
            // and the cascade of up to 8 sections multiplies that: 1e-9 leaves ample margin
            // while a wrong pole, zero or gain is off by orders of magnitude more.
            assert!(
                (got - want).abs() <= 1e-9 * want.max(1e-3),
                "{order} {response:?} at {fs} Hz, f = {f}: |H| = {got}, analytic {want}"
            );
        }
    }
}

#[test]
fn sos_matches_direct_form_oracle() {
    // Only total orders <= 4 and cutoffs >= 100 Hz: there the expanded polynomials are
    // well conditioned in f64, so the oracle itself is trustworthy.
    let fs = 44100;
    let designs = [
        (1, Response::LowPass { cutoff_hz: 1000.0 }),
        (2, Response::LowPass { cutoff_hz: 150.0 }),
        (3, Response::HighPass { cutoff_hz: 400.0 }),
        (4, Response::HighPass { cutoff_hz: 100.0 }),
        (4, Response::LowPass { cutoff_hz: 12000.0 }),
        (
            1,
            Response::BandPass {
                low_hz: 800.0,
                high_hz: 5000.0,
            },
        ),
        (
            2,
            Response::BandPass {
                low_hz: 150.0,
                high_hz: 800.0,
            },
        ),
        (
            2,
            Response::BandPass {
                low_hz: 5000.0,
                high_hz: 12000.0,
            },
        ),
    ];
    let signals = [white(1, 30000), white(2, 30000), musical(fs, 30000)];
    for (order, response) in designs {
        let mut filter = SosFilter::butterworth(order, response, fs).unwrap();
        for x in &signals {
            filter.reset();
            let got = run(&mut filter, x);
            let want = direct_form(filter.sections(), x);
            let peak = want.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                // f32 output rounding is <= 6e-8 * |y| <= 6e-8 * peak; f64 roundoff of both
                // forms is ~1e-12. A wrong state update is off by > 1e-3.
                assert!(
                    (f64::from(*g) - w).abs() <= 1e-7 * peak,
                    "{order} {response:?} sample {i}: sos {g}, direct form {w}"
                );
            }
        }
    }
}

/// Oracle for high orders: each section run on its own in direct form I (f64), one after
/// the other; no polynomial expansion, so it stays exact where `direct_form` would not.
fn cascade_direct_form(sections: &[Sos], x: &[f32]) -> Vec<f64> {
    let mut v: Vec<f64> = x.iter().map(|&s| f64::from(s)).collect();
    for s in sections {
        let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        for v in v.iter_mut() {
            let y = s.b[0] * *v + s.b[1] * x1 + s.b[2] * x2 - s.a[1] * y1 - s.a[2] * y2;
            (x2, x1, y2, y1) = (x1, *v, y1, y);
            *v = y;
        }
    }
    v
}

#[test]
fn long_cascades_match_per_section_oracle() {
    // 7 to 12 sections: the generic (non-specialised) processing path.
    let fs = 48000;
    let designs = [
        (13, Response::LowPass { cutoff_hz: 2000.0 }),
        (16, Response::HighPass { cutoff_hz: 30.0 }),
        (
            8,
            Response::BandPass {
                low_hz: 30.0,
                high_hz: 150.0,
            },
        ),
        (
            12,
            Response::BandPass {
                low_hz: 800.0,
                high_hz: 5000.0,
            },
        ),
    ];
    for (order, response) in designs {
        let mut filter = SosFilter::butterworth(order, response, fs).unwrap();
        assert!(filter.sections().len() > 6);
        for x in [white(21, 20000), musical(fs, 20000)] {
            filter.reset();
            let got = run(&mut filter, &x);
            let want = cascade_direct_form(filter.sections(), &x);
            let peak = want.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                // As above: f32 output rounding dominates; the two f64 structures agree to
                // ~1e-12 even for these resonant sections.
                assert!(
                    (f64::from(*g) - w).abs() <= 1e-7 * peak,
                    "{order} {response:?} sample {i}: sos {g}, cascade {w}"
                );
            }
        }
    }
}

#[test]
fn fft_of_impulse_response_puts_band_edges_at_minus_3_db() {
    const N: usize = 1 << 18;
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(N);
    for fs in [44100u32, 48000] {
        let mut filters: Vec<(String, SosFilter, Vec<f64>)> = Band::ALL
            .iter()
            .map(|&b| {
                let (lo, hi) = band_edges(b, fs).unwrap();
                // At 44.1 and 48 kHz every band is a true band-pass.
                assert!(hi < f64::from(fs) / 2.0, "{b:?}");
                (
                    b.name().to_string(),
                    SosFilter::band(b, fs).unwrap(),
                    vec![lo, hi],
                )
            })
            .collect();
        for hp in [30.0, 60.0] {
            filters.push((
                format!("denoise {hp} Hz"),
                SosFilter::highpass(hp, 4, fs).unwrap(),
                vec![hp],
            ));
        }
        for (name, mut filter, edges) in filters {
            let h = impulse_response(&mut filter, N);
            let mut input: Vec<f64> = h.iter().map(|&v| f64::from(v)).collect();
            let mut spectrum = fft.make_output_vec();
            fft.process(&mut input, &mut spectrum).unwrap();
            let mag: Vec<f64> = spectrum.iter().map(|c| c.norm()).collect();
            let bin_hz = f64::from(fs) / N as f64;
            for &edge in &edges {
                // Linear interpolation in dB between the two bins around the edge; the bins
                // are 0.17 Hz apart, where the skirt's curvature is negligible.
                let pos = edge / bin_hz;
                let k = pos.floor() as usize;
                let frac = pos - k as f64;
                let level = db(mag[k]) * (1.0 - frac) + db(mag[k + 1]) * frac;
                assert!(
                    (level + 3.0103).abs() <= 0.2,
                    "{name} at {fs} Hz: {level:.3} dB at the {edge} Hz edge"
                );
            }
            // The measured spectrum also follows the analytic response everywhere: what is
            // left of the impulse response after 2^18 samples and its f32 rounding is far
            // below 1e-4.
            for (k, m) in mag.iter().enumerate().step_by(7) {
                let (want, _) = filter.response_at(k as f64 * bin_hz, fs);
                assert!(
                    (m - want).abs() <= 1e-4,
                    "{name} at {fs} Hz, bin {k}: FFT {m}, analytic {want}"
                );
            }
        }
    }
}

#[test]
fn low_cutoffs_stay_stable_at_high_rates() {
    for fs in [44100u32, 96000, 192000] {
        let designs = [
            ("30 Hz high-pass", SosFilter::highpass(30.0, 4, fs).unwrap()),
            (
                "30 Hz low-pass",
                SosFilter::butterworth(4, Response::LowPass { cutoff_hz: 30.0 }, fs).unwrap(),
            ),
            ("kick", SosFilter::band(Band::Kick, fs).unwrap()),
        ];
        for (name, mut filter) in designs {
            for s in filter.sections() {
                for p in s.poles() {
                    assert!(p.norm() < 1.0, "{name} at {fs} Hz: pole {p} outside");
                }
            }
            let n = 4 * fs as usize; // 4 s: hundreds of the slowest time constants (~14 ms)
            let h = impulse_response(&mut filter, n);
            assert!(h.iter().all(|v| v.is_finite()), "{name} at {fs} Hz: NaN");
            let energy = |s: &[f32]| s.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>();
            let total = energy(&h);
            let tail = energy(&h[3 * n / 4..]);
            assert!(
                total > 0.0 && tail <= 1e-20 * total,
                "{name} at {fs} Hz: tail {tail}"
            );
            // The f64 state has decayed all the way to exact zero (flushed), not to denormals.
            assert!(filter.state().iter().flatten().all(|&v| v == 0.0));
            // The low-pass's DC gain survives the tiny cutoff: sum of the impulse response.
            if name == "30 Hz low-pass" {
                let dc: f64 = h.iter().map(|&v| f64::from(v)).sum();
                assert!((dc - 1.0).abs() < 1e-5, "{name} at {fs} Hz: DC gain {dc}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Parameters and clamping.

#[test]
fn invalid_parameters_are_rejected() {
    let bad = |r: Result<Vec<Sos>, ConfigError>| assert!(r.is_err());
    let lp = |f| Response::LowPass { cutoff_hz: f };
    bad(butterworth(0, lp(100.0), 44100));
    bad(butterworth(4, lp(100.0), 0));
    bad(butterworth(4, lp(0.0), 44100));
    bad(butterworth(4, lp(-5.0), 44100));
    bad(butterworth(4, lp(22050.0), 44100));
    bad(butterworth(4, lp(f64::NAN), 44100));
    bad(butterworth(
        4,
        Response::HighPass { cutoff_hz: 30000.0 },
        44100,
    ));
    let bp = |lo, hi| Response::BandPass {
        low_hz: lo,
        high_hz: hi,
    };
    bad(butterworth(4, bp(800.0, 150.0), 44100));
    bad(butterworth(4, bp(150.0, 150.0), 44100));
    bad(butterworth(4, bp(150.0, 23000.0), 44100));
    bad(butterworth(10_000, bp(150.0, 800.0), 44100));
    assert!(butterworth(4, bp(150.0, 800.0), 44100).is_ok());
    assert!(MedianFilter::new(0).is_err());
    assert!(MedianFilter::new(4).is_err());
    assert!(median_centered(&[1.0], 2).is_err());
}

#[test]
fn bands_clamp_near_nyquist() {
    // 0.9 x Nyquist rule: at 44.1 kHz and above, every band is a band-pass.
    for fs in [44100, 48000, 96000, 192000] {
        for b in Band::ALL {
            assert_eq!(band_edges(b, fs), Some(b.edges_hz()), "{b:?} at {fs}");
        }
    }
    // 24 and 22.05 kHz: 12 kHz is at/above Nyquist, cymbals become a 5 kHz high-pass.
    for fs in [24000u32, 22050] {
        let nyq = f64::from(fs) / 2.0;
        assert_eq!(band_edges(Band::Cymbals, fs), Some((5000.0, nyq)));
        assert_eq!(
            band_response(Band::Cymbals, fs),
            Some(Response::HighPass { cutoff_hz: 5000.0 })
        );
        assert_eq!(band_edges(Band::Toms, fs), Some((800.0, 5000.0)));
    }
    // 8 kHz: toms become an 800 Hz high-pass; cymbals are unavailable.
    assert_eq!(band_edges(Band::Toms, 8000), Some((800.0, 4000.0)));
    assert_eq!(band_edges(Band::Cymbals, 8000), None);
    assert!(SosFilter::band(Band::Cymbals, 8000).is_err());
    let toms = SosFilter::band(Band::Toms, 8000).unwrap();
    let (m, _) = toms.response_at(800.0, 8000);
    assert!((db(m) + 3.0103).abs() < 1e-6, "{}", db(m));
    let (m, _) = toms.response_at(3999.0, 8000);
    assert!((m - 1.0).abs() < 1e-6);
    assert!(SosFilter::band(Band::Kick, 0).is_err());
}

// ---------------------------------------------------------------------------------------
// Median.

fn assert_same_bits(got: &[f32], want: &[f32], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}");
    if let Some(i) = (0..got.len()).find(|&i| got[i].to_bits() != want[i].to_bits()) {
        panic!("{what}: sample {i}: got {}, want {}", got[i], want[i]);
    }
}

fn naive_streaming_median(x: &[f32], w: usize) -> Vec<f32> {
    (0..x.len())
        .map(|i| {
            let mut win: Vec<f32> = (0..w)
                .map(|k| {
                    if i + k >= w - 1 {
                        x[i + k + 1 - w]
                    } else {
                        0.0
                    }
                })
                .collect();
            win.sort_by(f32::total_cmp);
            win[w / 2]
        })
        .collect()
}

fn naive_centered_median(x: &[f32], w: usize) -> Vec<f32> {
    let h = (w - 1) / 2;
    (0..x.len())
        .map(|i| {
            let mut win: Vec<f32> = (0..w)
                .map(|k| {
                    let j = i as isize + k as isize - h as isize;
                    if j >= 0 && (j as usize) < x.len() {
                        x[j as usize]
                    } else {
                        0.0
                    }
                })
                .collect();
            win.sort_by(f32::total_cmp);
            win[w / 2]
        })
        .collect()
}

#[test]
fn median_matches_sorting_oracle() {
    for w in [1usize, 3, 5, 7, 31] {
        for seed in 1..=4u64 {
            let mut x = white(seed, 3000);
            // Ties, negative zeros and exact zeros, which stress the sorted-copy removal.
            if seed % 2 == 0 {
                for v in x.iter_mut() {
                    *v = (*v * 3.0).round() / 2.0;
                }
                x[10] = -0.0;
                x[11] = -0.0;
            }
            let mut f = MedianFilter::new(w).unwrap();
            assert_eq!(f.latency_samples(), (w - 1) / 2);
            let got = run(&mut f, &x);
            // The stage sanitizes its input first (which also turns -0.0 into +0.0); the
            // oracle sees the sanitized signal.
            let mut clean = x.clone();
            sanitize(&mut clean);
            let want = naive_streaming_median(&clean, w);
            assert_same_bits(&got, &want, &format!("window {w}, seed {seed}"));
            let centred = median_centered(&x, w).unwrap();
            let want = naive_centered_median(&clean, w);
            assert_same_bits(
                &centred,
                &want,
                &format!("centred, window {w}, seed {seed}"),
            );
        }
    }
    // scipy.signal.medfilt([1, 5, 2, 8, 3], 3), worked by hand: zero padding at both ends.
    assert_eq!(
        median_centered(&[1.0, 5.0, 2.0, 8.0, 3.0], 3).unwrap(),
        vec![1.0, 2.0, 5.0, 3.0, 3.0]
    );
    assert_eq!(median_centered(&[], 5).unwrap(), Vec::<f32>::new());
    assert_eq!(median_centered(&[4.0, 4.0], 5).unwrap(), vec![0.0, 0.0]);
}

// ---------------------------------------------------------------------------------------
// Streaming properties.

fn all_sos(fs: u32) -> Vec<SosFilter> {
    let mut v: Vec<SosFilter> = Band::ALL
        .iter()
        .map(|&b| SosFilter::band(b, fs).unwrap())
        .collect();
    v.push(SosFilter::highpass(30.0, 4, fs).unwrap());
    v.push(SosFilter::highpass(60.0, 3, fs).unwrap());
    // 8 sections: exercises the generic path beside the specialised 1-6-section ones.
    let wide = Response::BandPass {
        low_hz: 150.0,
        high_hz: 800.0,
    };
    v.push(SosFilter::butterworth(8, wide, fs).unwrap());
    v
}

fn chunked(f: &mut impl SampleStage, x: &[f32], chunks: &[usize], inplace: bool) -> Vec<f32> {
    let mut out = vec![0.0; x.len()];
    let mut at = 0;
    let mut c = chunks.iter().cycle();
    while at < x.len() {
        let n = (*c.next().unwrap()).min(x.len() - at);
        if inplace {
            out[at..at + n].copy_from_slice(&x[at..at + n]);
            f.process_inplace(&mut out[at..at + n]);
        } else {
            f.process(&x[at..at + n], &mut out[at..at + n]);
        }
        at += n;
    }
    out
}

fn check_chunking(f: &mut impl SampleStage, x: &[f32], chunks: &[usize]) {
    f.reset();
    let whole = run(f, x);
    f.reset();
    let parts = chunked(f, x, chunks, false);
    f.reset();
    let inplace = chunked(f, x, chunks, true);
    f.reset();
    let again = run(f, x);
    assert_same_bits(&parts, &whole, "chunked");
    assert_same_bits(&inplace, &whole, "chunked in place");
    assert_same_bits(&again, &whole, "after reset");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn chunking_and_reset_do_not_change_output(
        x in prop::collection::vec(-2.0f32..2.0, 0..3000),
        chunks in prop::collection::vec(0usize..400, 1..20),
    ) {
        // Chunk sizes of 0 are allowed too; make sure the loop advances.
        let mut chunks = chunks;
        if chunks.iter().all(|&c| c == 0) {
            chunks.push(1);
        }
        for mut f in all_sos(44100) {
            check_chunking(&mut f, &x, &chunks);
        }
        for w in [1, 3, 5, 31] {
            check_chunking(&mut MedianFilter::new(w).unwrap(), &x, &chunks);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Hard cases.

#[test]
fn silence_dc_and_clipping() {
    let fs = 44100;
    let n = fs as usize;
    for mut f in all_sos(fs) {
        assert_eq!(f.latency_samples(), 0);
        // Silence in, exact silence out.
        assert!(run(&mut f, &vec![0.0; n]).iter().all(|&v| v == 0.0));
        // DC: every high-pass and band-pass has a zero at DC, so 1 s later nothing is left.
        f.reset();
        let y = run(&mut f, &vec![1.0; n]);
        assert!(
            y[n - 100..].iter().all(|v| v.abs() < 1e-6),
            "{:?}",
            &y[n - 3..]
        );
        // +-8 full-scale-and-beyond square-ish noise: finite and bounded by 8 * sum |h|.
        let h = impulse_response(&mut f, 2 * n);
        let l1: f64 = h.iter().map(|&v| f64::from(v).abs()).sum();
        f.reset();
        let mut r = Rng(7);
        let x: Vec<f32> = (0..n)
            .map(|_| if r.uniform() < 0.0 { -8.0 } else { 8.0 })
            .collect();
        let y = run(&mut f, &x);
        assert!(y
            .iter()
            .all(|v| v.is_finite() && f64::from(v.abs()) <= 8.0 * l1 * (1.0 + 1e-6)));
    }
    // DC through a low-pass comes out unchanged.
    let mut lp = SosFilter::butterworth(4, Response::LowPass { cutoff_hz: 1000.0 }, fs).unwrap();
    let y = run(&mut lp, &vec![1.0; n]);
    assert!(y[n - 100..].iter().all(|v| (v - 1.0).abs() < 1e-6));
    // Median: silence stays silent, DC passes after the window fills, +-8 stays in {-8, 8}.
    let mut m = MedianFilter::new(5).unwrap();
    assert!(run(&mut m, &vec![0.0; 100]).iter().all(|&v| v == 0.0));
    m.reset();
    let y = run(&mut m, &[3.0; 10]);
    assert_eq!(y, [0.0, 0.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0, 3.0]);
    m.reset();
    let mut r = Rng(9);
    let x: Vec<f32> = (0..1000)
        .map(|_| if r.uniform() < 0.0 { -8.0 } else { 8.0 })
        .collect();
    assert!(run(&mut m, &x)[4..].iter().all(|&v| v == 8.0 || v == -8.0));
}

#[test]
fn tiny_and_non_finite_inputs_stay_sane() {
    let fs = 44100;
    let sane = |f: &SosFilter| {
        f.state()
            .iter()
            .flatten()
            .all(|&v| v == 0.0 || (v.is_normal() && v.abs() < 1e3))
    };
    for mut f in all_sos(fs) {
        // 1e-38 is below the sanitize flush (1e-30): it is silence.
        let y = run(&mut f, &vec![1e-38; 10000]);
        assert!(y.iter().all(|&v| v == 0.0));
        assert!(f.state().iter().flatten().all(|&v| v == 0.0));
        // Just above the flush: tiny but normal numbers, no denormals in state or output.
        f.reset();
        let mut r = Rng(3);
        let x: Vec<f32> = (0..10000).map(|_| 1e-29 * r.uniform() as f32).collect();
        let y = run(&mut f, &x);
        assert!(y.iter().all(|v| *v == 0.0 || v.is_normal()));
        assert!(sane(&f));
        // Then silence: the tail decays to exact zero, never through f64 denormals.
        for _ in 0..200 {
            let y = run(&mut f, &[0.0; 1000]);
            assert!(y.iter().all(|v| *v == 0.0 || v.is_normal()));
            assert!(sane(&f));
        }
        assert!(f.state().iter().flatten().all(|&v| v == 0.0));
        // NaN and infinities are processed as 0 and counted.
        f.reset();
        let mut x = white(5, 2000);
        x[100] = f32::NAN;
        x[200] = f32::INFINITY;
        x[300] = f32::NEG_INFINITY;
        let y = run(&mut f, &x);
        assert!(y.iter().all(|v| v.is_finite()));
        assert_eq!(f.non_finite_count(), 3);
        let mut clean = x.clone();
        for i in [100, 200, 300] {
            clean[i] = 0.0;
        }
        f.reset();
        assert_eq!(run(&mut f, &clean), y);
        assert_eq!(f.non_finite_count(), 0);
    }
    let mut m = MedianFilter::new(3).unwrap();
    let y = run(&mut m, &[f32::NAN, 1.0, f32::INFINITY, 1.0, 1e-38]);
    assert_eq!(y, [0.0, 0.0, 0.0, 1.0, 0.0]);
    assert_eq!(m.non_finite_count(), 2);
}

#[test]
fn empty_and_one_sample_blocks() {
    let x = musical(44100, 2000);
    for mut f in all_sos(44100) {
        let whole = run(&mut f, &x);
        f.reset();
        let mut out = vec![0.0; x.len()];
        for i in 0..x.len() {
            f.process(&[], &mut []);
            f.process_inplace(&mut []);
            f.process(&x[i..i + 1], &mut out[i..i + 1]);
        }
        assert_eq!(whole, out);
    }
    let mut m = MedianFilter::new(7).unwrap();
    let whole = run(&mut m, &x);
    m.reset();
    let mut out = vec![0.0; x.len()];
    for i in 0..x.len() {
        m.process(&[], &mut []);
        m.process(&x[i..i + 1], &mut out[i..i + 1]);
    }
    assert_eq!(whole, out);
}

#[test]
fn processing_does_not_allocate() {
    let x = white(11, 4096);
    let mut out = vec![0.0f32; x.len()];
    let mut sos = all_sos(48000);
    let mut medians: Vec<MedianFilter> = [1, 3, 5, 31]
        .iter()
        .map(|&w| MedianFilter::new(w).unwrap())
        .collect();
    let count = allocations_during(|| {
        for block in [0usize, 1, 128, 256, 512, 4096] {
            for f in sos.iter_mut() {
                f.process(&x[..block], &mut out[..block]);
                f.process_inplace(&mut out[..block]);
                f.reset();
            }
            for m in medians.iter_mut() {
                m.process(&x[..block], &mut out[..block]);
                m.process_inplace(&mut out[..block]);
                m.reset();
            }
        }
    });
    assert_eq!(count, 0);
    // The guard does see allocations (so a zero above means something).
    assert!(allocations_during(|| drop(std::hint::black_box(vec![1u8; 10]))) >= 1);
}
