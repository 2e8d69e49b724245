//! The hop-filter shape (`tactus_dsp::stage`): through the trait, every per-hop stage gives
//! what its own call gives, at once and for the same hop; a binner's stated latency is the
//! longest wait of a hop for its bin, measured; `reset` reproduces the output.

use tactus_dsp::binner::{BeatBinner, LevelBinner};
use tactus_dsp::discretize::{Discretizer, PriorRange, RunningRange, Scale};
use tactus_dsp::rms::StreamingGate;
use tactus_dsp::tukey::SlidingTukey;
use tactus_dsp::HopFilter;
use tactus_testkit::Rng;

/// Pushes `xs` through `f` via the trait; each output with the index it came with.
fn run<F: HopFilter>(f: &mut F, xs: &[F::In]) -> Vec<(usize, F::Out)>
where
    F::In: Copy,
{
    let mut out = Vec::new();
    for (i, &x) in xs.iter().enumerate() {
        f.push(i, x, &mut |k, v| out.push((k, v)));
    }
    f.finish(&mut |k, v| out.push((k, v)));
    out
}

/// Pitches in Hz with unvoiced hops and octave jumps; levels in dBFS.
fn signals(n: usize) -> (Vec<f32>, Vec<f32>) {
    let mut r = Rng::new(7);
    let f0 = (0..n)
        .map(|i| {
            let u = r.next_f32();
            if u < -0.6 {
                0.0
            } else if u > 0.9 {
                880.0
            } else {
                220.0 * (1.0 + 0.2 * u)
            }
            .max(0.0)
                * if i % 97 == 0 { 0.5 } else { 1.0 }
        })
        .collect();
    let db = (0..n).map(|_| -40.0 + 30.0 * r.next_f32()).collect();
    (f0, db)
}

fn same_as_own_call<F, G>(mut f: F, xs: &[F::In], mut own: G)
where
    F: HopFilter + Clone,
    F::In: Copy,
    F::Out: PartialEq + std::fmt::Debug,
    G: FnMut(&mut F, F::In) -> F::Out,
{
    let mut g = f.clone();
    let got = run(&mut f, xs);
    let want: Vec<(usize, F::Out)> = xs
        .iter()
        .enumerate()
        .map(|(i, &x)| (i, own(&mut g, x)))
        .collect();
    assert_eq!(got, want);
    assert_eq!(f.latency_samples(), 0, "a per-hop filter adds no latency");
    // Reset reproduces the output.
    f.reset();
    assert_eq!(run(&mut f, xs), want);
}

#[test]
fn per_hop_filters_give_their_own_calls_at_once() {
    let (f0, db) = signals(3000);
    let gate = StreamingGate::new(35.0, 3.0, 0.01).unwrap();
    same_as_own_call(gate, &db, |g, x| g.process(x));
    let tukey = SlidingTukey::new(200, 1.5, 20).unwrap();
    same_as_own_call(tukey, &f0, |t, x| t.process(x));
    same_as_own_call(RunningRange::new(), &f0, |r, x| r.update(x));
    let prior = PriorRange::new(12.0, 500.0).unwrap();
    same_as_own_call(prior, &f0, |r, x| r.update(x));
    let disc = Discretizer::new(8, Scale::Semitones).unwrap();
    let mut range = RunningRange::new();
    let with_range: Vec<(f32, Option<(f32, f32)>)> =
        f0.iter().map(|&f| (f, range.update(f))).collect();
    same_as_own_call(disc, &with_range, |d, (f, r)| {
        r.map_or(0, |r| d.level(f, r))
    });
}

/// The longest wait, in samples, between a hop arriving and its bin being emitted.
fn measured_wait(hop: usize, bin: usize) -> usize {
    let mut b = BeatBinner::new(hop, bin).unwrap();
    let n = 20 * (bin / hop + 2);
    let mut wait = 0;
    for i in 0..n {
        b.push(i, true, &mut |k, _| {
            // Bin k is complete at hop i: its first hop waited longest.
            let first = (k * bin).div_ceil(hop);
            wait = wait.max((i - first) * hop);
        });
    }
    wait
}

#[test]
fn binner_latency_is_the_longest_wait_for_a_bin() {
    for (hop, bin) in [
        (441, 4410),
        (441, 1000),
        (441, 441),
        (441, 300),
        (480, 1200),
        (1, 7),
    ] {
        let b = LevelBinner::new(hop, bin).unwrap();
        assert_eq!(
            b.latency_samples(),
            measured_wait(hop, bin),
            "hop {hop}, bin {bin}"
        );
    }
}

#[test]
fn binner_through_the_trait_matches_offline_binning_and_resets() {
    let levels: Vec<u8> = (0..1234u32).map(|i| ((i * 7919) % 9) as u8).collect();
    let mut b = LevelBinner::new(441, 4410).unwrap();
    let bins: Vec<u8> = run(&mut b, &levels).into_iter().map(|(_, v)| v).collect();
    assert_eq!(bins, tactus_dsp::binner::bin_levels(&levels, 441, 4410));
    HopFilter::reset(&mut b);
    let again: Vec<u8> = run(&mut b, &levels).into_iter().map(|(_, v)| v).collect();
    assert_eq!(again, bins);
}
