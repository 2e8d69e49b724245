//! Two-frame YIN (`tactus_dsp::twoframe`): against an oracle built from two plain YIN stages
//! run over the whole signal, for any chunking, and its latency against an impulse and a
//! tone step.

use tactus_dsp::twoframe::TwoFrameYin;
use tactus_dsp::yin::{PitchEstimate, Yin, YinConfig};
use tactus_dsp::HopStage;

/// The live bass tracker's rate (44.1 kHz decimated by 9) and range.
const RATE: u32 = 4900;
const FMIN: f32 = 41.0;
const FMAX: f32 = 400.0;

/// Two periods of `fmin` plus one lag, even (`tactus_engine::profile::pitch_frame`).
fn frame_for(fmin: f32) -> usize {
    let tau = (RATE as f64 / fmin as f64).ceil() as usize;
    (2 * (tau + 1)).next_multiple_of(2)
}

fn long_config() -> YinConfig {
    let mut c = YinConfig::new(RATE, FMIN, FMAX);
    c.frame = frame_for(FMIN);
    c
}

fn two_frame() -> TwoFrameYin {
    TwoFrameYin::new(long_config(), 2.0 * FMIN, frame_for(2.0 * FMIN)).unwrap()
}

/// A harmonic tone (5 partials, 1/k) of `f0` for `n` samples.
fn tone(f0: f32, n: usize, amp: f32) -> Vec<f32> {
    (0..n)
        .map(|j| {
            let t = j as f32 / RATE as f32;
            amp * (1..=5)
                .map(|k| (2.0 * std::f32::consts::PI * f0 * k as f32 * t).sin() / k as f32)
                .sum::<f32>()
        })
        .collect()
}

/// Notes across the range, the lowest octave included, with rests between some.
fn melody() -> Vec<f32> {
    let mut x = Vec::new();
    for (f0, ms) in [
        (0.0, 200),
        (98.0, 300),
        (49.0, 400),
        (0.0, 150),
        (61.7, 300),
        (130.8, 250),
        (246.9, 200),
        (0.0, 300),
        (43.7, 500),
        (87.3, 300),
    ] {
        let n = ms * RATE as usize / 1000;
        if f0 == 0.0 {
            x.extend(std::iter::repeat_n(0.0, n));
        } else {
            x.extend(tone(f0, n, 0.4));
        }
    }
    x
}

/// Every estimate of a stage fed `x` in blocks of the given sizes (cycled), then finished,
/// with the input position (samples fed so far) at which each was emitted.
fn run<S: HopStage<Out = PitchEstimate>>(
    s: &mut S,
    x: &[f32],
    blocks: &[usize],
) -> Vec<(usize, PitchEstimate, usize)> {
    let mut out = Vec::new();
    let mut at = 0;
    let mut k = 0;
    while at < x.len() {
        let n = blocks[k % blocks.len()].min(x.len() - at);
        k += 1;
        let fed = at + n;
        s.process(&x[at..fed], &mut |i, e| out.push((i, e, fed)));
        at = fed;
    }
    let fed = x.len();
    s.finish(&mut |i, e| out.push((i, e, fed)));
    out
}

#[test]
fn two_frame_yin_equals_its_rule_applied_to_two_plain_yins() {
    let x = melody();
    let mut long = Yin::new(long_config()).unwrap();
    let mut sc = long_config();
    sc.fmin_hz = 2.0 * FMIN;
    sc.frame = frame_for(2.0 * FMIN);
    let mut short = Yin::new(sc).unwrap();
    let long_all: Vec<PitchEstimate> = run(&mut long, &x, &[x.len()]).iter().map(|e| e.1).collect();
    let short_all: Vec<PitchEstimate> = run(&mut short, &x, &[x.len()])
        .iter()
        .map(|e| e.1)
        .collect();
    assert_eq!(long_all.len(), x.len().div_ceil(49));
    assert_eq!(short_all.len(), long_all.len());

    let mut two = two_frame();
    let lag = two.lag_hops();
    // Latencies 121 and 61 samples (frames of 242 and 122): 60 / 49, rounded up.
    assert_eq!(lag, 2);
    let oracle: Vec<PitchEstimate> = (0..short_all.len())
        .map(|i| {
            let long = |back: usize| i.checked_sub(lag + back).map(|j| long_all[j]);
            two.pick(short_all[i], long(0), long(1))
        })
        .collect();
    for blocks in [
        vec![x.len()],
        vec![1],
        vec![49],
        vec![7, 300, 1, 64, 5000, 13],
    ] {
        two.reset();
        let got = run(&mut two, &x, &blocks);
        let idx: Vec<usize> = got.iter().map(|e| e.0).collect();
        assert_eq!(
            idx,
            (0..oracle.len()).collect::<Vec<_>>(),
            "blocks {blocks:?}"
        );
        for (i, (g, o)) in got.iter().zip(&oracle).enumerate() {
            assert_eq!(g.1, *o, "hop {i}, blocks {blocks:?}");
        }
    }

    // The rule at work on this melody: the lowest-octave notes come from the long frame
    // (the short one cannot see them), the others from the short one.
    let sec = |h: usize| h as f32 * 0.01;
    let f_at = |t: f32| oracle[(t * 100.0) as usize].f0_hz;
    for (t, want) in [
        (0.35, 98.0),
        (0.7, 49.0),
        (1.2, 61.7),
        (1.5, 130.8),
        (1.7, 246.9),
        (2.35, 43.7),
        (2.75, 87.3),
    ] {
        let f = f_at(t);
        assert!((f / want - 1.0).abs() < 0.02, "at {t} s: {f} Hz for {want}");
    }
    assert!(sec(oracle.len()) > 2.8);
}

#[test]
fn the_stated_latency_is_when_a_hop_comes_out() {
    // Sample by sample: hop i is emitted when sample i·hop + latency − 1 has arrived.
    let x = tone(110.0, 4000, 0.3);
    let mut two = two_frame();
    let lat = two.latency_samples();
    assert_eq!(lat, frame_for(2.0 * FMIN) / 2);
    let got = run(&mut two, &x, &[1]);
    for &(i, _, fed) in &got {
        let due = i * 49 + lat;
        if due <= x.len() {
            assert_eq!(fed, due, "hop {i}");
        }
    }
}

/// The input position at which the first hop after `onset` showing `f0` (within 3 %) was
/// emitted, and the first voiced f0 after `onset`.
fn first_right<S: HopStage<Out = PitchEstimate>>(
    s: &mut S,
    x: &[f32],
    onset: usize,
    f0: f32,
) -> (usize, f32) {
    let out = run(s, x, &[1]);
    let after = || out.iter().filter(|e| e.0 * 49 + 49 > onset);
    let right = after()
        .find(|e| (e.1.f0_hz / f0 - 1.0).abs() < 0.03)
        .expect("never right");
    let first = after().find(|e| e.1.is_voiced()).unwrap();
    (right.2, first.1.f0_hz)
}

#[test]
fn a_note_above_the_lowest_octave_shows_a_short_frame_earlier() {
    let onset = 1500;
    for f0 in [87.3, 98.0, 196.0, 43.7, 55.0, 73.4] {
        let mut x = vec![0.0; onset];
        x.extend(tone(f0, 3000, 0.3));
        let (two_at, two_f) = first_right(&mut two_frame(), &x, onset, f0);
        let (long_at, long_f) = first_right(&mut Yin::new(long_config()).unwrap(), &x, onset, f0);
        eprintln!("{f0} Hz: right at {two_at} (first {two_f} Hz), long alone at {long_at} (first {long_f} Hz)");
        // Above the lowest octave: the long frame is 242 samples, the short one 122, so
        // the note comes out at least (242 − 122) / 2 samples sooner. In the lowest octave:
        // no later than with the long frame alone, but for the rounding of the lag to whole
        // hops (here 2 · 49 − 60 = 38 samples). Either way the first pitch shown is right.
        let bound = if f0 >= 2.0 * FMIN {
            long_at - (242 - 122) / 2
        } else {
            long_at + 38
        };
        assert!(
            two_at <= bound,
            "{f0} Hz: two-frame at {two_at}, long alone at {long_at}"
        );
        assert!((two_f / f0 - 1.0).abs() < 0.03, "{f0} Hz: {two_f}");
    }
}

#[test]
fn two_frame_yin_refuses_frames_that_cannot_work() {
    assert!(TwoFrameYin::new(long_config(), 2.0 * FMIN, frame_for(FMIN)).is_err());
    let mut c = long_config();
    c.fmax_hz = 80.0;
    assert!(TwoFrameYin::new(c, 2.0 * FMIN, frame_for(2.0 * FMIN)).is_err());
    let mut c = long_config();
    c.hop = 1;
    assert!(TwoFrameYin::new(c, 2.0 * FMIN, frame_for(2.0 * FMIN)).is_err());
}

#[test]
fn one_low_hop_of_the_long_frame_does_not_override_a_voiced_short_frame() {
    let two = two_frame();
    let e = |f0_hz: f32| PitchEstimate {
        f0_hz,
        aperiodicity: 0.05,
        voiced_prob: 0.95,
    };
    let silent = PitchEstimate::SILENT;
    // A 110 Hz note: the long frame's octave error for one hop at its start is ignored...
    assert_eq!(
        two.pick(e(110.0), Some(e(55.0)), Some(e(109.0))).f0_hz,
        110.0
    );
    assert_eq!(two.pick(e(110.0), Some(e(55.0)), Some(silent)).f0_hz, 110.0);
    // ...a low note held for two hops is taken, over a short frame hearing its octave...
    assert_eq!(two.pick(e(110.0), Some(e(55.0)), Some(e(55.5))).f0_hz, 55.0);
    // ...and at once when the short frame hears nothing, or only the edge of its range.
    assert_eq!(two.pick(silent, Some(e(55.0)), None).f0_hz, 55.0);
    assert_eq!(two.pick(e(80.5), Some(e(73.0)), None).f0_hz, 73.0);
    assert!(!two.pick(e(80.5), None, None).is_voiced());
    // Above the lowest octave the short frame answers, voiced or not.
    assert_eq!(two.pick(e(98.0), Some(e(97.0)), Some(e(97.0))).f0_hz, 98.0);
    assert!(!two.pick(silent, Some(e(98.0)), Some(e(98.0))).is_voiced());
}
