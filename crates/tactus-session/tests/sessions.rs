//! The sessions with the null sink and a fake clock: a live run through a capture ring
//! sends every frame the engine makes ready; forgetting sent bins changes no frame; the
//! capture callback does not allocate; `play` of a song and of a pattern on a fake clock
//! sends every frame at its time.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use tactus_audio::resample::StreamResampler;
use tactus_audio::ring::capture_ring;
use tactus_engine::render::RenderRequest;
use tactus_engine::{Engine, ENGINE_RATE};
use tactus_session::{
    live, play_pattern, play_song, play_song_whole, Late, LiveInput, LiveOptions, PlayOptions,
};
use tactus_testkit::{allocations, Counting};
use tactus_transport::{open_sink, Clock, FakeClock, SinkOptions, SinkSpec};

mod common;

#[global_allocator]
static GLOBAL: Counting = Counting;

fn demo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/demo.ogg")
}

#[test]
fn capture_callback_does_not_allocate() {
    let (mut w, mut r) = capture_ring(4096);
    let i16_stereo: Vec<i16> = (0..2048).map(|i| (i * 37 % 2000) as i16 - 1000).collect();
    let f32_mono: Vec<f32> = (0..1024).map(|i| (i as f32 * 0.01).sin()).collect();
    let six: Vec<f32> = (0..6 * 512).map(|i| (i as f32 * 0.02).cos()).collect();
    let nan = [f32::NAN, f32::INFINITY, 0.5, -0.5];
    let before = allocations();
    for _ in 0..8 {
        // Enough to overrun the ring: the dropped frames are counted, nothing allocates.
        w.write(
            &i16_stereo,
            2,
            |x| f32::from(x) / 32768.0,
            Duration::from_millis(3),
        );
        w.write(&f32_mono, 1, |x| x, Duration::ZERO);
        w.write(&six, 6, |x| x, Duration::ZERO);
        w.write(&nan, 2, |x| x, Duration::ZERO);
    }
    assert_eq!(allocations(), before, "the capture callback allocated");
    assert!(r.overruns() > 0);
    let (mut left, mut right) = (Vec::with_capacity(8192), Vec::with_capacity(8192));
    assert_eq!(r.read(&mut left, &mut right), 4096);
    assert!(left.iter().chain(&right).all(|x| x.is_finite()));
    // The first block: stereo kept, in order.
    assert_eq!(left[0], f32::from(i16_stereo[0]) / 32768.0);
    assert_eq!(right[0], f32::from(i16_stereo[1]) / 32768.0);
    // The latest block's `callback − capture` delay (the steady state, not the first
    // block's 3 ms).
    assert_eq!(r.input_delay_ms(), 0.0);
}

#[test]
fn live_sends_every_frame_the_engine_makes_ready() {
    let rate = 48_000;
    let seconds = 12.0;
    let (w, mut reader) = capture_ring(rate as usize / 2);
    let feeder = common::feed(w, rate, seconds);
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let stop = AtomicBool::new(false);
    let input = LiveInput {
        reader: &mut reader,
        rate,
        name: "synthetic".into(),
    };
    let report = live(
        input,
        common::live_config(),
        &sink,
        &LiveOptions::default(),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    feeder.join().unwrap();
    let stats = sink.close();
    assert_eq!(report.overruns, 0);
    assert!((report.captured_s - seconds).abs() < 1e-9, "{report:?}");
    // The same audio straight into an engine, whole: the same number of ready bins
    // (streaming output does not depend on the chunking).
    let n = (seconds * f64::from(rate)) as u64;
    let (l, r): (Vec<f32>, Vec<f32>) = (0..n).map(|i| common::frame(i, rate)).unzip();
    let mut rs = StreamResampler::new(rate, ENGINE_RATE, 2).unwrap();
    let mut out = vec![Vec::new(), Vec::new()];
    rs.process(&[&l, &r], &mut out);
    let mut eng = Engine::new(common::live_config()).unwrap();
    eng.process(&out[0], &out[1], &[]);
    // live sends each finger group as soon as it is final (Engine::live_frame).
    assert_eq!(report.frames, eng.live_ready_bins());
    assert!(report.frames > 400, "{report:?}");
    // Every frame and the closing all-down reached the link (or were coalesced).
    let handed = stats.sent + stats.dropped;
    let frames = report.frames as u64;
    assert!(handed > frames && handed <= frames + 2, "{stats:?}");
    assert!(report.budget.iter().any(|(n, _)| n == "pin rise"));
}

#[test]
fn forgetting_sent_bins_changes_no_frame() {
    let rate = ENGINE_RATE;
    let n = 8 * u64::from(rate);
    let (l, r): (Vec<f32>, Vec<f32>) = (0..n).map(|i| common::frame(i, rate)).unzip();
    let mut keep = Engine::new(common::live_config()).unwrap();
    let mut forget = Engine::new(common::live_config()).unwrap();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (cl, cr) in l.chunks(3001).zip(r.chunks(3001)) {
        keep.process(cl, cr, &[]);
        forget.process(cl, cr, &[]);
        while a.len() < keep.ready_bins() {
            a.push(keep.frame(a.len()));
        }
        while b.len() < forget.ready_bins() {
            b.push(forget.frame(b.len()));
        }
        forget.discard_before(b.len());
    }
    assert_eq!(forget.discarded_bins(), b.len());
    assert!(a.len() > 200);
    assert_eq!(a, b);
}

/// The demo at 25 ms bins in `mode`.
fn demo_request(mode: tactus_engine::Mode) -> RenderRequest {
    RenderRequest {
        input: demo(),
        stems: Vec::new(),
        config: tactus_engine::EngineConfig {
            mode,
            bin_ms: 25,
            ..tactus_engine::EngineConfig::default()
        },
    }
}

#[test]
fn play_song_on_a_fake_clock_sends_every_frame() {
    let req = demo_request(tactus_engine::Mode::Streaming);
    // The frames a streaming render makes, for comparison.
    let rendered = tactus_engine::render::render(&req, &mut |_| {}).unwrap();
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let clock = FakeClock::new(0.0);
    let stop = Arc::new(AtomicBool::new(false));
    // Nothing is late on a fake clock: frames are waited for, not skipped.
    let opts = PlayOptions {
        late: Late::Wait,
        ..PlayOptions::default()
    };
    let report = play_song(req, &sink, &clock, &opts, &stop).unwrap();
    sink.close();
    assert_eq!(
        report.timing.frames_sent,
        rendered.pattern.frames.len(),
        "{report:?}"
    );
    assert_eq!(report.timing.skipped, 0);
    assert!(report.sound.is_none());
    // The session ended when the frame after the last was due: n·25 ms − lead.
    let last = report.timing.frames_sent as f64 * 25.0 - opts.lead_ms as f64;
    assert!(
        clock.now_ms() >= last && clock.now_ms() < last + 1.0,
        "{} vs {last}",
        clock.now_ms()
    );
}

#[test]
fn play_song_whole_renders_offline_then_plays_from_the_render_s_end() {
    // Asked for streaming: the whole-song session renders offline all the same.
    let req = demo_request(tactus_engine::Mode::Streaming);
    let offline = demo_request(tactus_engine::Mode::Offline);
    let rendered = tactus_engine::render::render(&offline, &mut |_| {}).unwrap();
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    // The caller's clock already reads 5 s when playback starts (the render's time, say).
    let clock = FakeClock::new(5000.0);
    let stop = Arc::new(AtomicBool::new(false));
    let opts = PlayOptions::default();
    let mut told = None;
    let report = play_song_whole(req.clone(), &sink, &clock, &opts, &stop, &mut |s| {
        told = Some(s)
    })
    .unwrap();
    sink.close();
    assert!(told.is_some_and(|s| s >= 0.0));
    assert_eq!(report.timing.frames_sent, rendered.pattern.frames.len());
    assert_eq!(report.timing.skipped, 0);
    assert!(!report.timing.stopped);
    // Every frame on time from the shifted zero: none was due before playback started.
    assert!(
        report.timing.jitter_max_ms < 1.0,
        "{:?}",
        report.timing.jitter_max_ms
    );
    let last = 5000.0 + report.timing.frames_sent as f64 * 25.0 - opts.lead_ms as f64;
    assert!(
        clock.now_ms() >= last && clock.now_ms() < last + 1.0,
        "{} vs {last}",
        clock.now_ms()
    );

    // A stop before (or during) the render: nothing played, a stopped report, no error.
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let stop = Arc::new(AtomicBool::new(true));
    let r = play_song_whole(req, &sink, &clock, &opts, &stop, &mut |_| {
        panic!("the render finished after a stop")
    })
    .unwrap();
    sink.close();
    assert!(r.timing.stopped);
    assert_eq!(r.timing.frames_sent, 0);
}

#[test]
fn play_pattern_on_a_fake_clock_sends_every_frame() {
    let frames: Vec<tactus_glove::Frame> = (0..40u8)
        .map(|i| tactus_glove::Frame([i, 0, 0, 0, 0, 0, 0, 0, 0, i]))
        .collect();
    let sink = open_sink(&SinkSpec::Null, &SinkOptions::default()).unwrap();
    let clock = FakeClock::new(0.0);
    let stop = Arc::new(AtomicBool::new(false));
    let report = play_pattern(
        &frames,
        100,
        None,
        &sink,
        &clock,
        &PlayOptions::default(),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    sink.close();
    let r = report.timing;
    assert_eq!(r.frames_sent, 40);
    assert!(r.jitter_max_ms < 1.0, "{r:?}");
    assert!(clock.now_ms() >= 40.0 * 100.0 - 50.0);
}
