//! STFT analysis against a naive DFT, and analysis -> overlap-add perfect reconstruction.
mod common;

use common::Lcg;
use proptest::prelude::*;
use realfft::num_complex::Complex;
use tactus_separate::stft::{hann_periodic, OverlapAdd, StftAnalysis, StftConfig};

/// Feeds `x` in chunks cycling through `chunks`, resynthesises every frame unmodified,
/// and returns (output, spectra of every frame).
fn roundtrip(x: &[f32], cfg: StftConfig, chunks: &[usize]) -> (Vec<f32>, Vec<Vec<Complex<f32>>>) {
    let mut ana = StftAnalysis::new(cfg, 1).unwrap();
    let mut syn = OverlapAdd::new(cfg, 1).unwrap();
    let mut out = Vec::new();
    let mut frames = Vec::new();
    let mut spec = vec![Complex::new(0.0, 0.0); cfg.bins()];
    let mut on_frame = |i: usize, sp: &[Vec<Complex<f32>>]| {
        assert_eq!(i, frames.len());
        frames.push(sp[0].clone());
        spec.copy_from_slice(&sp[0]);
        syn.add(0, &mut spec);
        syn.advance(|_, y| out.extend_from_slice(y));
    };
    let mut pos = 0;
    let mut k = 0;
    while pos < x.len() {
        let c = chunks[k % chunks.len()].max(1);
        let end = (pos + c).min(x.len());
        ana.push(&[&x[pos..end]], &mut on_frame);
        pos = end;
        k += 1;
    }
    ana.finish(&mut on_frame);
    assert_eq!(ana.frames_emitted(), cfg.frames(x.len()));
    syn.finish(x.len(), |_, y| out.extend_from_slice(y));
    (out, frames)
}

fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut r = Lcg(seed);
    (0..n).map(|_| r.next()).collect()
}

const SHAPES: [(usize, usize); 8] = [
    (16, 4),
    (64, 16),
    (100, 30),
    (256, 64),
    (512, 128),
    (1024, 256),
    (2048, 512),
    (4096, 1024),
];

#[test]
fn perfect_reconstruction_for_many_shapes() {
    for &(n_fft, hop) in &SHAPES {
        let cfg = StftConfig { n_fft, hop };
        for n in [
            0usize,
            1,
            2,
            hop - 1,
            hop,
            n_fft / 2 + 1,
            n_fft + 3,
            3 * n_fft + 17,
            20_000,
        ] {
            let x = noise(n, n as u64 + n_fft as u64);
            let (y, _) = roundtrip(&x, cfg, &[n.max(1)]);
            assert_eq!(y.len(), n, "n_fft {n_fft} hop {hop} n {n}");
            let err = x
                .iter()
                .zip(&y)
                .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
            // f32 FFT round trip of unit-amplitude noise: ~1e-7 · log2(n_fft) per sample.
            assert!(err < 1e-5, "n_fft {n_fft} hop {hop} n {n}: max error {err}");
        }
    }
}

/// With `hop = n_fft / 2` the last samples are covered only by the tail of the last window
/// (w ≈ 6e-4 two samples before its end for n_fft 256), so f32 round-off is divided by a tiny
/// window sum there. The interior is exact to 1e-5; the last `n_fft / 4` samples to 1e-3.
#[test]
fn half_overlap_reconstructs_with_a_looser_tail() {
    for n_fft in [64usize, 256, 1024] {
        let cfg = StftConfig {
            n_fft,
            hop: n_fft / 2,
        };
        for n in [1usize, n_fft / 2 - 1, n_fft + 5, 10_000] {
            let x = noise(n, n as u64);
            let (y, _) = roundtrip(&x, cfg, &[333]);
            assert_eq!(y.len(), n);
            let tail = n.saturating_sub(n_fft / 4);
            for (j, (a, b)) in x.iter().zip(&y).enumerate() {
                let tol = if j < tail { 1e-5 } else { 1e-3 };
                assert!(
                    (a - b).abs() < tol,
                    "n_fft {n_fft} n {n} sample {j}: {a} vs {b}"
                );
            }
        }
    }
}

/// Frame `i` must be the DFT of the Hann-windowed input samples
/// `[i·hop − n_fft/2, i·hop + n_fft/2)` (zeros outside the input), computed in f64.
#[test]
fn frames_match_a_naive_dft_of_centred_windowed_frames() {
    let cfg = StftConfig { n_fft: 64, hop: 16 };
    let x = noise(200, 3);
    let (_, frames) = roundtrip(&x, cfg, &[7]);
    assert_eq!(frames.len(), 200usize.div_ceil(16));
    let w = hann_periodic(64);
    for (i, spec) in frames.iter().enumerate() {
        for (k, got) in spec.iter().enumerate() {
            let (mut re, mut im) = (0.0f64, 0.0f64);
            for (n, &wn) in w.iter().enumerate() {
                let j = (i * 16 + n) as i64 - 32;
                let s = if j >= 0 && (j as usize) < x.len() {
                    x[j as usize] as f64
                } else {
                    0.0
                };
                let ph = -std::f64::consts::TAU * (k * n) as f64 / 64.0;
                re += s * wn as f64 * ph.cos();
                im += s * wn as f64 * ph.sin();
            }
            assert!(
                (got.re as f64 - re).abs() < 1e-4 && (got.im as f64 - im).abs() < 1e-4,
                "frame {i} bin {k}"
            );
        }
    }
}

#[test]
fn invalid_shapes_are_rejected() {
    for (n_fft, hop) in [(0, 1), (3, 1), (15, 4), (64, 0), (64, 33)] {
        assert!(
            StftAnalysis::new(StftConfig { n_fft, hop }, 1).is_err(),
            "{n_fft}/{hop}"
        );
        assert!(
            OverlapAdd::new(StftConfig { n_fft, hop }, 1).is_err(),
            "{n_fft}/{hop}"
        );
    }
    assert!(StftAnalysis::new(StftConfig { n_fft: 64, hop: 16 }, 0).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]
    #[test]
    fn chunked_equals_one_block(
        shape in 0usize..SHAPES.len(),
        n in 0usize..12_000,
        chunks in prop::collection::vec(1usize..3000, 1..8),
        seed in any::<u64>(),
    ) {
        let (n_fft, hop) = SHAPES[shape];
        let cfg = StftConfig { n_fft, hop };
        let x = noise(n, seed);
        let (whole, fw) = roundtrip(&x, cfg, &[n.max(1)]);
        let (chunked, fc) = roundtrip(&x, cfg, &chunks);
        prop_assert_eq!(fw, fc);
        prop_assert_eq!(whole, chunked);
    }
}
