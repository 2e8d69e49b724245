//! The voicing/pitch pair ([`tactus_dsp::pair::VoicingPitchPair`]) against the obvious
//! oracle: both trackers run on their own over the whole input and merged hop by hop by the
//! module's rule written out here; the pair's output equals it for any chunking, its
//! latency is the larger one, it does not allocate once warm, and it refuses trackers whose
//! hops differ.

use tactus_dsp::pair::VoicingPitchPair;
use tactus_dsp::shs::{Shs, ShsConfig};
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::HopStage;

#[global_allocator]
static A: tactus_testkit::Counting = tactus_testkit::Counting;

const SR: u32 = 8000;

/// A melody of 0.3 s notes with rests, a few notes with a weak fundamental (the harmonic
/// sum and YIN then disagree on their octave), and a little noise.
fn melody() -> Vec<f32> {
    let sr = SR as f32;
    let mut x = Vec::new();
    let mut ph = 0.0f32;
    let mut seed = 0x1234_5678u32;
    let mut noise = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        (seed as f32 / u32::MAX as f32) - 0.5
    };
    for (k, st) in [57.0f32, 60.0, 64.0, 0.0, 62.0, 67.0, 0.0, 55.0, 69.0, 64.0]
        .into_iter()
        .cycle()
        .take(30)
        .enumerate()
    {
        let n = (0.3 * sr) as usize;
        let f = 440.0 * ((st - 69.0) / 12.0).exp2();
        let weak = if k % 3 == 0 { 0.1 } else { 1.0 };
        for _ in 0..n {
            let s = if st > 0.0 {
                ph += std::f32::consts::TAU * f / sr;
                0.3 * (weak * ph.sin() + 0.7 * (2.0 * ph).sin() + 0.5 * (3.0 * ph).sin())
            } else {
                0.0
            };
            x.push(s + 0.003 * noise());
        }
    }
    x
}

fn yin() -> Yin {
    Yin::new(YinConfig::new(SR, 100.0, 1000.0)).unwrap()
}

fn shs() -> Shs {
    let mut c = ShsConfig::melody(SR, 100.0, 1000.0);
    c.hop = YinConfig::new(SR, 100.0, 1000.0).hop;
    Shs::new(c).unwrap()
}

fn run(
    t: &mut dyn HopStage<Out = PitchEstimate>,
    x: &[f32],
    chunk: usize,
) -> Vec<(usize, PitchEstimate)> {
    let mut out = Vec::new();
    for b in x.chunks(chunk) {
        t.process(b, &mut |i, e| out.push((i, e)));
    }
    t.finish(&mut |i, e| out.push((i, e)));
    out
}

/// The module's rule, written out: the voicing tracker's estimate, with the pitch tracker's
/// f0 and aperiodicity (how sure it is of that pitch) where both are voiced.
fn merged_by_hand(
    v: &[(usize, PitchEstimate)],
    p: &[(usize, PitchEstimate)],
) -> Vec<(usize, PitchEstimate)> {
    assert_eq!(v.len(), p.len());
    v.iter()
        .zip(p)
        .map(|(&(i, a), &(j, b))| {
            assert_eq!(i, j);
            let mut e = a;
            if a.f0_hz > 0.0 && b.f0_hz > 0.0 {
                e.f0_hz = b.f0_hz;
                e.aperiodicity = b.aperiodicity;
            }
            (i, e)
        })
        .collect()
}

#[test]
fn the_pair_is_the_voicing_trackers_decisions_with_the_pitch_trackers_pitch() {
    let x = melody();
    let v = run(&mut shs(), &x, x.len());
    let p = run(&mut yin(), &x, x.len());
    let want = merged_by_hand(&v, &p);
    // The oracle is not trivial: the trackers disagree on some voiced hops, and the voicing
    // differs on others.
    let differ = v
        .iter()
        .zip(&p)
        .filter(|((_, a), (_, b))| {
            a.f0_hz > 0.0 && b.f0_hz > 0.0 && (a.f0_hz / b.f0_hz - 1.0).abs() > 0.03
        })
        .count();
    let voicing = v
        .iter()
        .zip(&p)
        .filter(|((_, a), (_, b))| (a.f0_hz > 0.0) != (b.f0_hz > 0.0))
        .count();
    assert!(
        differ >= 5 && voicing >= 5,
        "differ {differ}, voicing {voicing}"
    );
    for chunk in [1usize, 7, 80, 1000, x.len()] {
        let mut pair = VoicingPitchPair::new(Box::new(shs()), Box::new(yin())).unwrap();
        let got = run(&mut pair, &x, chunk);
        assert_eq!(got.len(), want.len(), "chunk {chunk}");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.0, w.0, "chunk {chunk}");
            assert_eq!(
                g.1.f0_hz.to_bits(),
                w.1.f0_hz.to_bits(),
                "chunk {chunk} hop {}",
                g.0
            );
            assert_eq!(g.1.voiced_prob.to_bits(), w.1.voiced_prob.to_bits());
            assert_eq!(g.1.aperiodicity.to_bits(), w.1.aperiodicity.to_bits());
        }
        // Reset gives the same again.
        pair.reset();
        let again = run(&mut pair, &x, chunk);
        assert_eq!(again.len(), got.len());
        assert!(again
            .iter()
            .zip(&got)
            .all(|(a, b)| a.0 == b.0 && a.1.f0_hz.to_bits() == b.1.f0_hz.to_bits()));
    }
}

#[test]
fn the_pairs_latency_is_the_larger_and_it_streams_without_allocating() {
    let (s, y) = (shs(), yin());
    let want = s.latency_samples().max(y.latency_samples());
    assert_ne!(s.latency_samples(), y.latency_samples());
    let mut pair = VoicingPitchPair::new(Box::new(s), Box::new(y)).unwrap();
    assert_eq!(pair.latency_samples(), want);
    assert_eq!(pair.hop(), yin().hop());
    let x = melody();
    let (warm, rest) = x.split_at(x.len() / 3);
    let mut n = 0usize;
    pair.process(warm, &mut |_, _| n += 1);
    let allocs = tactus_testkit::allocations_during(|| {
        for b in rest.chunks(64) {
            pair.process(b, &mut |_, _| n += 1);
        }
    });
    assert_eq!(allocs, 0);
    assert!(n > 100);
    // Trackers with different hops are refused.
    let mut c = YinConfig::new(SR, 100.0, 1000.0);
    c.hop += 1;
    assert!(VoicingPitchPair::new(Box::new(shs()), Box::new(Yin::new(c).unwrap())).is_err());
}

/// The veto written out: where the pitch tracker is unvoiced, both estimates are unvoiced
/// (the voicing tracker's with `f0_hz = 0`); elsewhere the plain rule.
fn vetoed_by_hand(
    v: &[(usize, PitchEstimate)],
    p: &[(usize, PitchEstimate)],
) -> Vec<(usize, PitchEstimate, PitchEstimate)> {
    v.iter()
        .zip(p)
        .map(|(&(i, a), &(_, b))| {
            if b.f0_hz > 0.0 {
                let mut e = a;
                if a.f0_hz > 0.0 {
                    e.f0_hz = b.f0_hz;
                    e.aperiodicity = b.aperiodicity;
                }
                (i, e, a)
            } else {
                let mut e = a;
                e.f0_hz = 0.0;
                (i, e, e)
            }
        })
        .collect()
}

#[test]
fn with_a_veto_the_pitch_trackers_rests_unvoice_both_estimates() {
    let x = melody();
    let v = run(&mut shs(), &x, x.len());
    let p = run(&mut yin(), &x, x.len());
    let want = vetoed_by_hand(&v, &p);
    let vetoed = want
        .iter()
        .zip(&v)
        .filter(|(w, (_, a))| a.f0_hz > 0.0 && w.1.f0_hz == 0.0)
        .count();
    assert!(vetoed >= 3, "the veto is exercised: {vetoed} hops");
    for chunk in [1usize, 80, x.len()] {
        let mut pair = VoicingPitchPair::new(Box::new(shs()), Box::new(yin()))
            .unwrap()
            .with_veto()
            .with_voicing();
        let mut got = Vec::new();
        for b in x.chunks(chunk) {
            pair.process(b, &mut |i, (e, n)| got.push((i, e, n)));
        }
        pair.finish(&mut |i, (e, n)| got.push((i, e, n)));
        assert_both_eq(&got, &want, chunk);
    }
}

type Both = (usize, PitchEstimate, PitchEstimate);

/// Both estimates of every hop, bit for bit.
fn assert_both_eq(got: &[Both], want: &[Both], chunk: usize) {
    assert_eq!(got.len(), want.len(), "chunk {chunk}");
    for (g, w) in got.iter().zip(want) {
        assert_eq!(g.0, w.0);
        assert_eq!(
            g.1.f0_hz.to_bits(),
            w.1.f0_hz.to_bits(),
            "chunk {chunk} hop {}",
            g.0
        );
        assert_eq!(
            g.2.f0_hz.to_bits(),
            w.2.f0_hz.to_bits(),
            "chunk {chunk} hop {}",
            g.0
        );
        assert_eq!(g.1.aperiodicity.to_bits(), w.1.aperiodicity.to_bits());
    }
}

/// A second view of the same span: the melody read a fourth faster (its notes a fourth
/// up, wrapping round) over a quiet pad, so that a tracker reading it reports other
/// pitches than one reading `melody()`.
fn other_view() -> Vec<f32> {
    let sr = SR as f32;
    let x = melody();
    let k = (5.0f32 / 12.0).exp2();
    (0..x.len())
        .map(|i| {
            let pad = (std::f32::consts::TAU * 196.0 * i as f32 / sr).sin();
            0.7 * x[(i as f32 * k) as usize % x.len()] + 0.05 * pad
        })
        .collect()
}

#[test]
fn two_views_the_voicing_tracker_reads_one_the_pitch_tracker_the_other() {
    // `process_with(a, Some(b))`: the voicing tracker run on `a` alone and the pitch
    // tracker on `b` alone, merged (with the veto) by the rule written out above, for any
    // chunking; `process_with(a, Some(a))` is `process(a)` bit for bit.
    let (a, b) = (melody(), other_view());
    assert_eq!(a.len(), b.len());
    let v = run(&mut shs(), &a, a.len());
    let p_own = run(&mut yin(), &a, a.len());
    let p = run(&mut yin(), &b, b.len());
    let want = vetoed_by_hand(&v, &p);
    let moved = p
        .iter()
        .zip(&p_own)
        .filter(|((_, x), (_, y))| {
            x.f0_hz > 0.0 && y.f0_hz > 0.0 && (x.f0_hz / y.f0_hz - 1.0).abs() > 0.03
        })
        .count();
    assert!(
        moved >= 20,
        "the second view changes the pitch tracker's pitch: {moved} hops"
    );
    for chunk in [1usize, 7, 80, 1000, a.len()] {
        let mut pair = VoicingPitchPair::new(Box::new(shs()), Box::new(yin()))
            .unwrap()
            .with_veto()
            .with_voicing();
        let mut got = Vec::new();
        for (x, y) in a.chunks(chunk).zip(b.chunks(chunk)) {
            pair.process_with(x, Some(y), &mut |i, (e, n)| got.push((i, e, n)));
        }
        pair.finish(&mut |i, (e, n)| got.push((i, e, n)));
        assert_both_eq(&got, &want, chunk);
        // One view for both is the plain pair.
        let mut one = VoicingPitchPair::new(Box::new(shs()), Box::new(yin()))
            .unwrap()
            .with_veto()
            .with_voicing();
        let mut two = VoicingPitchPair::new(Box::new(shs()), Box::new(yin()))
            .unwrap()
            .with_veto()
            .with_voicing();
        let (mut x1, mut x2) = (Vec::new(), Vec::new());
        for c in a.chunks(chunk) {
            one.process(c, &mut |i, (e, n)| {
                x1.push((i, e.f0_hz.to_bits(), n.f0_hz.to_bits()))
            });
            two.process_with(c, Some(c), &mut |i, (e, n)| {
                x2.push((i, e.f0_hz.to_bits(), n.f0_hz.to_bits()))
            });
        }
        assert_eq!(x1, x2, "chunk {chunk}");
    }
}
