//! The drum model files: the embedded ones parse, and damaged or foreign ones are errors.

use super::*;
use crate::melbank::MelConfig;

#[test]
fn embedded_model_parses() {
    for (bytes, future) in [(EMBEDDED, 4), (EMBEDDED_LIVE, 1)] {
        let m = DrumModel::from_bytes(bytes).unwrap();
        assert_eq!(m.bands, MelConfig::drums(44_100).bands);
        assert_eq!(m.future, future);
        assert!(m.thresholds.iter().all(|t| (0.0..1.0).contains(t)));
    }
}

#[test]
fn truncated_or_foreign_models_are_errors() {
    for n in [0, 7, 8, 20, EMBEDDED.len() / 2, EMBEDDED.len() - 1] {
        assert!(DrumModel::from_bytes(&EMBEDDED[..n]).is_err(), "{n}");
    }
    let mut extra = EMBEDDED.to_vec();
    extra.push(0);
    assert!(DrumModel::from_bytes(&extra).is_err());
    let mut bad = EMBEDDED.to_vec();
    bad[0] = b'X';
    assert!(DrumModel::from_bytes(&bad).is_err());
}

fn ensemble(members: &[&[u8]], thresholds: [f32; 4]) -> Vec<u8> {
    let mut v = MAGIC_ENSEMBLE.to_vec();
    v.extend(1u32.to_le_bytes());
    v.extend((members.len() as u32).to_le_bytes());
    for m in members {
        v.extend((m.len() as u32).to_le_bytes());
        v.extend_from_slice(m);
    }
    for t in thresholds {
        v.extend(t.to_le_bytes());
    }
    v
}

#[test]
fn ensemble_files_average_their_members() {
    let net = embedded_network();
    let one = DrumModel::from_bytes(net).unwrap();
    let two = ensemble(&[net, net], [0.1, 0.2, 0.3, 0.4]);
    let m = DrumModel::from_bytes(&two).unwrap();
    assert_eq!(m.members.len(), 1);
    assert_eq!(m.thresholds, [0.1, 0.2, 0.3, 0.4]);
    // Two copies of one network: the mean is that network's activation.
    let w = m.scratch_len();
    let (mut a, mut b, mut c) = (vec![0f32; w], vec![0f32; w], vec![0f32; w]);
    let window: Vec<f32> = (0..m.window_len())
        .map(|i| -(((i * 37) % 23) as f32))
        .collect();
    let mut input = vec![0f32; m.input_len()];
    m.assemble(&window, &mut input);
    let got = m.forward(&input, &mut a, &mut b, &mut c);
    let want = one.forward(&input, &mut a, &mut b, &mut c);
    for k in 0..CLASSES {
        assert!((got[k] - want[k]).abs() < 1e-6, "{got:?} vs {want:?}");
    }
    // Members must read the same input; counts, nesting and lengths are checked.
    let e = DrumModel::from_bytes(&ensemble(&[net, network_of(EMBEDDED_LIVE)], [0.5; 4]));
    assert!(e.unwrap_err().to_string().contains("must share"));
    assert!(DrumModel::from_bytes(&ensemble(&[net], [0.5; 4])).is_err());
    assert!(DrumModel::from_bytes(&ensemble(&[&two, net], [0.5; 4])).is_err());
    // A retuned file is not a single network.
    let e = DrumModel::from_bytes(&ensemble(&[EMBEDDED, net], [0.5; 4]));
    assert!(e.unwrap_err().to_string().contains("not a single network"));
    for n in [8, 12, 16, 20, two.len() / 2, two.len() - 1] {
        assert!(DrumModel::from_bytes(&two[..n]).is_err(), "{n}");
    }
    let mut extra = two.clone();
    extra.push(0);
    assert!(DrumModel::from_bytes(&extra).is_err());
}

/// A version-2 file by hand: 2 bands, 1 past and 1 future frame, one 10 → 4 layer
/// (6 window values + 4 flux values with feature set 1, 6 with feature set 0).
fn v2(features: u32, n_in: u32) -> Vec<u8> {
    let mut v = b"TACTUSDR".to_vec();
    for x in [2u32, 2, 1, 1, 4, 1] {
        v.extend(x.to_le_bytes());
    }
    v.extend((-16f32).to_le_bytes());
    v.extend(features.to_le_bytes());
    v.extend(n_in.to_le_bytes());
    v.extend(4u32.to_le_bytes());
    for k in 0..n_in * 4 + 4 + 4 {
        v.extend((k as f32 * 0.01).to_le_bytes());
    }
    v
}

#[test]
fn version_2_carries_the_input_feature_set() {
    let m = DrumModel::from_bytes(&v2(1, 10)).unwrap();
    assert!(m.flux);
    assert_eq!((m.window_len(), m.input_len()), (6, 10));
    let m = DrumModel::from_bytes(&v2(0, 6)).unwrap();
    assert!(!m.flux);
    assert_eq!(m.input_len(), 6);
    // The layer must match the feature set's input length.
    let e = DrumModel::from_bytes(&v2(1, 6)).unwrap_err().to_string();
    assert!(e.contains("do not chain"), "{e}");
    let e = DrumModel::from_bytes(&v2(4, 10)).unwrap_err().to_string();
    assert!(e.contains("input feature set 4"), "{e}");
    // Feature set 3, the short view: 6 window + 6 short-view values, nothing else.
    let m = DrumModel::from_bytes(&v2(3, 12)).unwrap();
    assert!(m.short && !m.flux && m.backing.is_none());
    assert_eq!((m.window_len(), m.input_len()), (6, 12));
    let e = DrumModel::from_bytes(&v2(3, 6)).unwrap_err().to_string();
    assert!(e.contains("do not chain"), "{e}");
    // Feature set 2, the backing: its ceiling follows, then 6 window + 6 backing values.
    let backing = |ceil: f32, n_in: u32| {
        let mut v = v2(2, n_in);
        let at = 8 + 6 * 4 + 4 + 4;
        v.splice(at..at, ceil.to_le_bytes());
        v
    };
    let m = DrumModel::from_bytes(&backing(6.0, 12)).unwrap();
    assert_eq!((m.backing, m.flux), (Some(6.0), false));
    assert_eq!((m.window_len(), m.input_len()), (6, 12));
    let e = DrumModel::from_bytes(&backing(6.0, 6))
        .unwrap_err()
        .to_string();
    assert!(e.contains("do not chain"), "{e}");
    let e = DrumModel::from_bytes(&backing(-20.0, 12))
        .unwrap_err()
        .to_string();
    assert!(e.contains("ceiling"), "{e}");
    let mut v3 = v2(1, 10);
    v3[8] = 3;
    let e = DrumModel::from_bytes(&v3).unwrap_err().to_string();
    assert!(e.contains("version 3"), "{e}");
}

/// The retuned file inside an embedded file (bare, or inside a staged file).
fn retuned_of(file: &'static [u8]) -> &'static [u8] {
    if !file.starts_with(MAGIC_STAGED) {
        return file;
    }
    let u = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
    let mut at = 28;
    for _ in 0..u(24).count_ones() {
        at += match (u(8), u(at)) {
            (1, _) => 44,
            (_, 0) => 48,
            (_, h) => 4 + 4 * (12 * h + 2),
        };
    }
    &file[at + 4..at + 4 + u(at)]
}

/// The single network inside an embedded file (a retuned file, maybe staged).
fn network_of(file: &'static [u8]) -> &'static [u8] {
    let file = retuned_of(file);
    assert!(file.starts_with(MAGIC_RETUNED));
    let u = |at: usize| u32::from_le_bytes(file[at..at + 4].try_into().unwrap()) as usize;
    let at = 16 + 4 * u(12);
    &file[at + 4..at + 4 + u(at)]
}

fn staged_file(wait: u32, low: f32, shrink: f32, mask: u32, inner: &[u8]) -> Vec<u8> {
    let mut v = MAGIC_STAGED.to_vec();
    for x in [1u32, wait] {
        v.extend(x.to_le_bytes());
    }
    v.extend(low.to_le_bytes());
    v.extend(shrink.to_le_bytes());
    v.extend(mask.to_le_bytes());
    for c in 0..CLASSES {
        if mask & (1 << c) != 0 {
            for k in 0..=JUDGE_INPUTS {
                v.extend((k as f32 * 0.1 - c as f32).to_le_bytes());
            }
        }
    }
    v.extend((inner.len() as u32).to_le_bytes());
    v.extend_from_slice(inner);
    v
}

#[test]
fn staged_files_parse_and_bad_ones_are_errors() {
    let inner = retuned_of(EMBEDDED);
    let m = DrumModel::from_bytes(&staged_file(2, 0.3, 8.0, 0b1010, inner)).unwrap();
    let st = m.stage.as_ref().unwrap();
    assert_eq!((st.wait, st.low, st.shrink), (2, 0.3, 8.0));
    assert!(st.judges[0].is_none() && st.judges[2].is_none());
    assert_eq!(st.judges[1].as_ref().unwrap().w[3], 0.3f32 - 1.0);
    assert_eq!(
        st.judges[3].as_ref().unwrap().cut,
        JUDGE_INPUTS as f32 * 0.1 - 3.0
    );
    assert_eq!(m.retunings.len(), 3, "the inner file's retunings are kept");
    let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
    assert!(err(staged_file(9, 0.3, 8.0, 2, inner)).contains("0 to 8 hops"));
    for (low, shrink) in [(0.0, 8.0), (1.0, 8.0), (0.3, 0.0), (0.3, -1.0)] {
        assert!(err(staged_file(1, low, shrink, 2, inner)).contains("threshold in (0, 1)"));
    }
    assert!(err(staged_file(1, f32::NAN, 8.0, 2, inner)).contains("non-finite"));
    for mask in [0, 16] {
        assert!(
            err(staged_file(1, 0.3, 8.0, mask, inner)).contains("mask"),
            "{mask}"
        );
    }
    let nested = staged_file(1, 0.3, 8.0, 2, inner);
    assert!(err(staged_file(1, 0.3, 8.0, 2, &nested)).contains("another staged"));
    assert!(err(staged_file(1, 0.3, 8.0, 2, b"TACTUSXX")).contains("not a Tactus"));
    let mut v = staged_file(1, 0.3, 8.0, 2, inner);
    v[8] = 3;
    assert!(err(v).contains("version 3 is not supported (1 to 2 are)"));
    let good = staged_file(1, 0.3, 8.0, 2, inner);
    for n in [8, 12, 20, 28, 40, good.len() / 2, good.len() - 1] {
        assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
    }
    let mut extra = good.clone();
    extra.push(0);
    assert!(err(extra).contains("trailing"));
}

/// A version-2 staged file: a perceptron judge with `hidden` units for the snare (unit
/// `h`'s weight `k` is `h - k / 10`, its bias `0.5 h`, its output weight `1 - h`), a
/// linear one for the cymbals.
fn staged_v2(hidden: u32, inner: &[u8]) -> Vec<u8> {
    let mut v = MAGIC_STAGED.to_vec();
    for x in [2u32, 1] {
        v.extend(x.to_le_bytes());
    }
    v.extend(0.3f32.to_le_bytes());
    v.extend(8f32.to_le_bytes());
    v.extend(0b1010u32.to_le_bytes());
    v.extend(hidden.to_le_bytes());
    let mut f = |x: f32| v.extend(x.to_le_bytes());
    for h in 0..hidden {
        for k in 0..JUDGE_INPUTS {
            f(h as f32 - k as f32 / 10.0);
        }
        f(0.5 * h as f32);
    }
    for h in 0..hidden {
        f(1.0 - h as f32);
    }
    f(0.25);
    f(-0.5);
    v.extend(0u32.to_le_bytes());
    for k in 0..=JUDGE_INPUTS {
        v.extend((k as f32).to_le_bytes());
    }
    v.extend((inner.len() as u32).to_le_bytes());
    v.extend_from_slice(inner);
    v
}

#[test]
fn version_2_staged_files_hold_perceptron_judges() {
    let inner = retuned_of(EMBEDDED);
    let m = DrumModel::from_bytes(&staged_v2(3, inner)).unwrap();
    let st = m.stage.as_ref().unwrap();
    let snare = st.judges[1].as_ref().unwrap();
    assert_eq!(snare.hidden.len(), 3);
    assert_eq!(snare.hidden[2][4], 2.0 - 0.4);
    assert_eq!(snare.hidden[2][JUDGE_INPUTS], 1.0);
    assert_eq!(
        (snare.w.clone(), snare.bias, snare.cut),
        (vec![1.0, 0.0, -1.0], 0.25, -0.5)
    );
    let cym = st.judges[3].as_ref().unwrap();
    assert!(cym.hidden.is_empty());
    assert_eq!((cym.w[9], cym.cut, cym.bias), (9.0, 10.0, 0.0));
    // The score by hand: x = (1, 0, ..., 0): unit h gives max(0, h + 0.5 h).
    let mut x = [0f64; JUDGE_INPUTS];
    x[0] = 1.0;
    let want: f64 = 0.25
        + (0..3)
            .map(|h| (1.0 - h as f64) * 1.5 * h as f64)
            .sum::<f64>();
    assert!((snare.score(&x) - want).abs() < 1e-12);
    assert_eq!(cym.score(&x), 0.0);
    // The file inside is found whatever the judges' sizes.
    assert_eq!(
        retuned_of(Box::leak(staged_v2(5, inner).into_boxed_slice())),
        inner
    );
    let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
    assert!(err(staged_v2(JUDGE_MAX_HIDDEN as u32 + 1, inner)).contains("at most 256"));
    let good = staged_v2(3, inner);
    for n in [32, 40, 100, 200, good.len() - inner.len() - 5] {
        assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
    }
}

fn embedded_network() -> &'static [u8] {
    network_of(EMBEDDED)
}

fn retuned_file(ratios: &[f32], net: &[u8], thresholds: [f32; 4]) -> Vec<u8> {
    let mut v = MAGIC_RETUNED.to_vec();
    v.extend(1u32.to_le_bytes());
    v.extend((ratios.len() as u32).to_le_bytes());
    for r in ratios {
        v.extend(r.to_le_bytes());
    }
    v.extend((net.len() as u32).to_le_bytes());
    v.extend_from_slice(net);
    for t in thresholds {
        v.extend(t.to_le_bytes());
    }
    v
}

#[test]
fn bad_retuned_files_are_errors() {
    let net = embedded_network();
    let err = |v: Vec<u8>| DrumModel::from_bytes(&v).unwrap_err().to_string();
    assert!(err(retuned_file(&[1.0], net, [0.5; 4])).contains("2 to 8"));
    assert!(err(retuned_file(&[1.0; 9], net, [0.5; 4])).contains("2 to 8"));
    for bad in [3.0, 0.25] {
        assert!(
            err(retuned_file(&[1.0, bad], net, [0.5; 4])).contains("[0.5, 2]"),
            "{bad}"
        );
    }
    for bad in [f32::NAN, f32::INFINITY] {
        assert!(
            err(retuned_file(&[1.0, bad], net, [0.5; 4])).contains("non-finite"),
            "{bad}"
        );
    }
    // Only a perceptron on mel frames (and its short view): not a flux or backing
    // model, not a retuned file inside a retuned file.
    let mut backing = v2(2, 12);
    let at = 8 + 6 * 4 + 4 + 4;
    backing.splice(at..at, 6f32.to_le_bytes());
    for inner in [&v2(1, 10)[..], &backing[..]] {
        assert!(err(retuned_file(&[1.0, 1.3], inner, [0.5; 4])).contains("perceptron"));
    }
    let short = DrumModel::from_bytes(&retuned_file(&[1.0, 1.3], &v2(3, 12), [0.5; 4]));
    assert_eq!(short.unwrap().retunings.len(), 2);
    assert!(err(retuned_file(&[1.0, 1.3], EMBEDDED, [0.5; 4])).contains("single network"));
    let mut v = retuned_file(&[1.0, 1.3], net, [0.5; 4]);
    v[8] = 2;
    assert!(err(v).contains("version 2"));
    let good = retuned_file(&[1.0, 1.3], net, [0.5; 4]);
    for n in [8, 12, 16, 20, 24, good.len() / 2, good.len() - 1] {
        assert!(DrumModel::from_bytes(&good[..n]).is_err(), "{n}");
    }
    let mut extra = good.clone();
    extra.push(0);
    assert!(err(extra).contains("trailing"));
}

#[test]
fn embedded_models_are_retuned_by_one_and_1_3_either_way() {
    for m in [DrumModel::embedded(), DrumModel::embedded_live()] {
        let ratios: Vec<f32> = m.retunings.iter().map(|r| r.ratio).collect();
        assert_eq!(ratios, [1.0, (1.0f64 / 1.3) as f32, 1.3]);
    }
    assert!(DrumModel::embedded_live().short);
}
