//! The whole engine is chunk-invariant: any block sizes give the same frames and features
//! as one block, in both statistics modes, and `reset()` reproduces the output. Also
//! measures how closely `streaming` (causal statistics) follows `offline` (whole track).

use proptest::prelude::*;
use tactus_engine::{Engine, EngineConfig, LevelRule, Mode, PitchMethod};
use tactus_glove::Frame;

/// A 3 s test song: a kick every 0.4 s, a stepping bass line, a melody.
fn song(n: usize) -> Vec<f32> {
    let sr = 44_100.0f32;
    let bass = [55.0f32, 73.4, 82.4, 65.4];
    let mel = [440.0f32, 494.0, 523.3, 587.3, 659.3];
    let (mut pb, mut pm) = (0.0f32, 0.0f32);
    let mut seed = 7u32;
    (0..n)
        .map(|i| {
            let t = i as f32 / sr;
            pb += std::f32::consts::TAU * bass[(t / 0.75) as usize % 4] / sr;
            pm += std::f32::consts::TAU * mel[((t + 0.05) / 0.3) as usize % 5] / sr;
            // Hits sit mid-bin (0.05 s after a bin edge), so a ms of detector difference
            // between the modes cannot move a beat across a bin boundary.
            let tk = (t + 0.35) % 0.4;
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            let noise = (seed as f32 / u32::MAX as f32 - 0.5) * (-tk * 60.0).exp();
            0.4 * (-tk * 25.0).exp() * (std::f32::consts::TAU * 60.0 * tk).sin()
                + 0.3 * noise
                + 0.25 * (pb.sin() + 0.5 * (2.0 * pb).sin())
                + 0.15 * (pm.sin() + 0.3 * (2.0 * pm).sin())
        })
        .collect()
}

struct Run {
    frames: Vec<Frame>,
    features: String,
}

fn run(engine: &mut Engine, x: &[f32], chunks: &[usize]) -> Run {
    let mut pos = 0;
    let mut k = 0;
    while pos < x.len() {
        let c = chunks[k % chunks.len()].max(1).min(x.len() - pos);
        engine.process(&x[pos..pos + c], &x[pos..pos + c], &[]);
        pos += c;
        k += 1;
    }
    engine.finish();
    Run {
        frames: engine.frames(),
        features: engine.features().to_json_string().unwrap(),
    }
}

fn config(mode: Mode) -> EngineConfig {
    EngineConfig {
        mode,
        pitch: PitchMethod::default(), // SHS for the bass, pYIN for the others
        ..EngineConfig::default()
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, .. ProptestConfig::default() })]
    #[test]
    fn any_chunking_equals_one_block(
        chunks in prop::collection::vec(1usize..40000, 1..6),
        streaming in any::<bool>(),
        pipeline in any::<bool>(),
    ) {
        let x = song(44_100 * 2);
        let mode = if streaming { Mode::Streaming } else { Mode::Offline };
        let whole = run(&mut Engine::new(config(mode)).unwrap(), &x, &[x.len()]);
        let mut e = Engine::new(EngineConfig { pipeline, ..config(mode) }).unwrap();
        let chunked = run(&mut e, &x, &chunks);
        prop_assert_eq!(&chunked.frames, &whole.frames);
        prop_assert_eq!(&chunked.features, &whole.features);
        e.reset();
        let again = run(&mut e, &x, &chunks);
        prop_assert_eq!(&again.frames, &whole.frames);
        prop_assert_eq!(&again.features, &whole.features);
    }
}

#[test]
fn streaming_follows_offline() {
    // 8 s: the streaming statistics (gate reference, range) need a few notes to warm up; on
    // 3 s the bass levels sat at the 0.6 bound (0.59 with the SHS tracker), which measured
    // the warm-up rather than the agreement this test is about.
    let x = song(44_100 * 8);
    // The paper's level rule: the default (`Follow`) pads the streaming range to a prior
    // span of 20 semitones that fades over ~30 s of voicing, so on this 3 s bass line of
    // 7 semitones its streaming levels are compressed against offline (0.47 within ±1),
    // by design; docs/results.md measures that trade-off on real lengths.
    //
    // Without the separator's kit mask: this synthetic bass is a near-pure 55–82 Hz tone
    // under a 60 Hz kick, which the mask takes for kick bodies (a known limit of the kit
    // mask's model, `docs/decisions/0020-kit-mask.md`), leaving too few bass bins to compare
    // the modes on.
    let paper = |mode| EngineConfig {
        level_rule: LevelRule::Paper,
        kit_mask: false,
        ..config(mode)
    };
    let off = Engine::new(paper(Mode::Offline)).map(|mut e| {
        run(&mut e, &x, &[4096]);
        e.features()
    });
    let st = Engine::new(paper(Mode::Streaming)).map(|mut e| {
        run(&mut e, &x, &[4096]);
        e.features()
    });
    let (off, st) = (off.unwrap(), st.unwrap());
    // Beats: bins with a beat in each band.
    for (band, a) in &off.beats {
        let b = &st.beats[band];
        let same = a.iter().zip(b).filter(|(x, y)| x == y).count() as f64 / a.len() as f64;
        eprintln!("{band}: beat bins agree {:.1}%", 100.0 * same);
        // The modes use different peak pickers (causal rising edge vs a ±15 ms local
        // maximum), so a few extra causal onsets (bass steps in the kick band) are expected.
        assert!(same >= 0.9, "{band}: only {same} of beat bins agree");
    }
    // Levels in bins voiced in both modes. The streaming range starts empty and only
    // widens, so the first notes map differently: we allow a wider margin than the
    // 95% measured on long songs (docs/results.md).
    for (stem, a) in &off.levels {
        let b = &st.levels[stem];
        let both: Vec<_> = a
            .iter()
            .zip(b)
            .filter(|(x, y)| **x > 0 && **y > 0)
            .collect();
        let same = both.iter().filter(|(x, y)| x == y).count() as f64 / both.len().max(1) as f64;
        let near = both.iter().filter(|(x, y)| x.abs_diff(**y) <= 1).count() as f64
            / both.len().max(1) as f64;
        eprintln!(
            "{stem}: {} bins voiced in both, same level {:.1}%, within 1: {:.1}%",
            both.len(),
            100.0 * same,
            100.0 * near
        );
        assert!(
            both.is_empty() || near >= 0.6,
            "{stem}: levels drift apart ({near})"
        );
    }
}

/// A frame callback that says "stop" ends the render at once: `render_with` returns
/// `Cancelled` after exactly that frame, long before the end of the file (what `play`
/// relies on after Ctrl-C). Fails if rendering ran on to the end or kept calling back.
#[test]
fn a_stopping_frame_callback_cancels_the_render() {
    use tactus_engine::render::{render_with, RenderRequest};
    use tactus_engine::EngineError;

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.wav");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 44_100,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(&path, spec).unwrap();
    let x = song(44_100 * 3);
    for _ in 0..10 {
        for &v in &x {
            w.write_sample((v * 20_000.0) as i16).unwrap();
        }
    }
    w.finalize().unwrap();
    let req = RenderRequest {
        input: path,
        stems: Vec::new(),
        config: EngineConfig {
            mode: Mode::Streaming,
            bin_ms: 25,
            ..config(Mode::Streaming)
        },
    };
    let (mut calls, mut last_progress) = (0usize, 0.0f64);
    let result = render_with(&req, &mut |p| last_progress = p, &mut |_, _| {
        calls += 1;
        calls < 20
    });
    assert!(
        matches!(result, Err(EngineError::Cancelled)),
        "expected Cancelled, got {:?}",
        result.map(|o| o.pattern.frames.len())
    );
    assert_eq!(calls, 20, "no frame may be handed over after the stop");
    // 30 s of audio, stopped after 0.5 s of frames: at most the first 2 s block was fed.
    assert!(last_progress < 0.5, "progress reached {last_progress}");
}
