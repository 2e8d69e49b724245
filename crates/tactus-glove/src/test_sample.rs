//! A shared test fixture: one pattern and features with every kind of content.

use crate::{Features, Pattern};

/// A pattern and features with every kind of content: a pitch contour with rests,
/// levels, onsets and beats.
pub(crate) fn sample() -> (Pattern, Features) {
    let frames = (0..30u8)
        .map(|k| {
            let mut f = crate::Frame::DOWN;
            f.0[usize::from(k % 10)] = k.wrapping_mul(37);
            f
        })
        .collect();
    let pattern = Pattern {
        source: crate::SourceInfo {
            path: "song.ogg".into(),
            sha256: "0".repeat(64),
            duration_s: 3.0,
            sample_rate: 44100,
        },
        bin_ms: 100,
        levels: 8,
        map: crate::GloveMap::default(),
        frames,
    };
    let mut f = Features {
        hop_s: 0.01,
        bin_s: 0.1,
        ..Features::default()
    };
    let hz = (0..300)
        .map(|i| {
            if i % 50 < 40 {
                55.0 * (1.0 + i as f32 / 300.0)
            } else {
                0.0
            }
        })
        .collect();
    f.pitch_hz.insert("bass".into(), hz);
    f.levels
        .insert("bass".into(), (0..30).map(|k| (k % 9) as u8).collect());
    f.onsets_s.insert("kick".into(), vec![0.05, 0.5, 1.25, 2.0]);
    f.beats.insert(
        "kick".into(),
        (0..30).map(|k| u8::from(k % 5 == 0)).collect(),
    );
    (pattern, f)
}
