//! The capture ring: from an audio callback to the engine thread, stereo kept.
//!
//! A capture callback runs on the audio thread and must never allocate, lock or block.
//! [`CaptureWriter::write`] maps each interleaved frame to stereo (mono is duplicated; more
//! than two channels keep the first two: front left and right in every common layout),
//! converts to `f32`, replaces a non-finite sample by 0 and pushes the pair into a
//! preallocated single-producer single-consumer lock-free ring ([`rtrb`]). Frames that do
//! not fit are dropped and counted as *overruns*; the callback also keeps the block's peak
//! (input level), and the time and size of the first callback, in atomics.
//! [`CaptureReader::read`] drains the ring into planar left/right vectors on the engine
//! thread.
//!
//! Keeping stereo matters: the spectral separator's centre/side cue (vocals and bass sit in
//! the centre) is lost in a mono downmix.
//!
//! The writer takes samples already converted to `f32` through a function, so the same code
//! serves cpal's callback (feature `device`) and a test that calls it directly under an
//! allocation guard.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Marks "not yet" in the time atomics.
const NONE: u64 = u64::MAX;

/// Counters shared between the writer (audio thread) and the reader.
#[derive(Debug)]
struct Shared {
    base: Instant,
    first_cb_ns: AtomicU64,
    first_cb_frames: AtomicU64,
    /// The device's `callback − capture` delay for the latest block, ns (for the live
    /// report's latency budget).
    input_delay_ns: AtomicU64,
    callbacks: AtomicU64,
    frames: AtomicU64,
    overruns: AtomicU64,
    /// Peak |sample| since the last [`CaptureReader::take_peak`], as `f32` bits
    /// (non-negative floats order like their bits, so `fetch_max` works).
    peak_bits: AtomicU32,
    error: AtomicBool,
    /// Device-side overruns (xruns) the device reported.
    xruns: AtomicU64,
}

/// The audio-thread side of a capture ring.
#[derive(Debug)]
pub struct CaptureWriter {
    ring: rtrb::Producer<f32>,
    shared: Arc<Shared>,
}

/// The engine-thread side of a capture ring.
#[derive(Debug)]
pub struct CaptureReader {
    ring: rtrb::Consumer<f32>,
    shared: Arc<Shared>,
}

/// A ring holding `frames` stereo frames; the two ends.
pub fn capture_ring(frames: usize) -> (CaptureWriter, CaptureReader) {
    let (producer, consumer) = rtrb::RingBuffer::new(frames.max(1) * 2);
    let shared = Arc::new(Shared {
        base: Instant::now(),
        first_cb_ns: AtomicU64::new(NONE),
        first_cb_frames: AtomicU64::new(0),
        input_delay_ns: AtomicU64::new(0),
        callbacks: AtomicU64::new(0),
        frames: AtomicU64::new(0),
        overruns: AtomicU64::new(0),
        peak_bits: AtomicU32::new(0),
        error: AtomicBool::new(false),
        xruns: AtomicU64::new(0),
    });
    (
        CaptureWriter {
            ring: producer,
            shared: shared.clone(),
        },
        CaptureReader {
            ring: consumer,
            shared,
        },
    )
}

impl CaptureWriter {
    /// One callback's interleaved block of `channels` channels: to stereo, into the ring.
    /// `delay` is the device's `callback − capture` time (recorded for every block: the latest is kept).
    /// No allocation, no lock, no blocking.
    pub fn write<T: Copy>(
        &mut self,
        data: &[T],
        channels: usize,
        to_f32: impl Fn(T) -> f32,
        delay: Duration,
    ) {
        let channels = channels.max(1);
        let frames = data.len() / channels;
        let shared = &*self.shared;
        // The device's own buffering, kept for every block so the report shows
        // the steady state rather than the start-up.
        shared
            .input_delay_ns
            .store(delay.as_nanos() as u64, Ordering::Relaxed);
        if shared.first_cb_ns.load(Ordering::Relaxed) == NONE {
            shared
                .first_cb_frames
                .store(frames as u64, Ordering::Relaxed);
            shared
                .first_cb_ns
                .store(shared.base.elapsed().as_nanos() as u64, Ordering::Release);
        }
        let clean = |x: f32| if x.is_finite() { x } else { 0.0 };
        let mut peak = 0.0f32;
        let mut dropped = 0u64;
        for frame in data.chunks_exact(channels) {
            let l = clean(to_f32(frame[0]));
            let r = if channels > 1 {
                clean(to_f32(frame[1]))
            } else {
                l
            };
            peak = peak.max(l.abs()).max(r.abs());
            if self.ring.slots() >= 2 {
                // Cannot fail: two slots are free and only this thread pushes.
                let _ = self.ring.push(l);
                let _ = self.ring.push(r);
            } else {
                dropped += 1;
            }
        }
        if dropped > 0 {
            shared.overruns.fetch_add(dropped, Ordering::Relaxed);
        }
        shared
            .peak_bits
            .fetch_max(peak.to_bits(), Ordering::Relaxed);
        shared.frames.fetch_add(frames as u64, Ordering::Relaxed);
        shared.callbacks.fetch_add(1, Ordering::Relaxed);
    }

    /// Stereo frames the ring can take now without dropping any.
    pub fn free_frames(&self) -> usize {
        self.ring.slots() / 2
    }

    /// Records that the device reported a stream error.
    pub fn set_error(&self) {
        self.shared.error.store(true, Ordering::Relaxed);
    }

    /// A handle that can record an error from another callback (cpal's error callback).
    pub fn error_flag(&self) -> impl Fn() + Send + 'static {
        let s = self.shared.clone();
        move || s.error.store(true, Ordering::Relaxed)
    }

    /// A handle that counts a device-side overrun (an xrun: the device's own buffer filled
    /// before the callback could take it, so audio was lost before the ring) from another
    /// callback (cpal's error callback, `ErrorKind::Xrun`). An xrun is not an error: the
    /// device recovers and capture goes on.
    pub fn xrun_counter(&self) -> impl Fn() + Send + 'static {
        let s = self.shared.clone();
        move || {
            s.xruns.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl CaptureReader {
    /// Ring capacity in stereo frames: [`CaptureReader::read`] never returns more.
    pub fn capacity(&self) -> usize {
        self.ring.buffer().capacity() / 2
    }

    /// Appends every captured frame waiting in the ring to `left` and `right`, up to their
    /// spare capacity (reserve [`CaptureReader::capacity`] to never allocate). Returns the
    /// number of frames.
    pub fn read(&mut self, left: &mut Vec<f32>, right: &mut Vec<f32>) -> usize {
        let room = (left.capacity() - left.len()).min(right.capacity() - right.len());
        let n = (self.ring.slots() / 2).min(room);
        match self.ring.read_chunk(2 * n) {
            Ok(chunk) => {
                let (a, b) = chunk.as_slices();
                let mut it = a.iter().chain(b);
                while let (Some(&l), Some(&r)) = (it.next(), it.next()) {
                    left.push(l);
                    right.push(r);
                }
                chunk.commit_all();
                n
            }
            Err(_) => 0,
        }
    }

    /// Whether the writing end is gone and every frame it wrote has been read: the input
    /// has ended.
    pub fn is_abandoned(&self) -> bool {
        self.ring.is_abandoned() && self.ring.slots() == 0
    }

    /// When the first callback ran and how many frames it brought.
    pub fn first_callback(&self) -> Option<(Instant, u64)> {
        let ns = self.shared.first_cb_ns.load(Ordering::Acquire);
        (ns != NONE).then(|| {
            (
                self.shared.base + Duration::from_nanos(ns),
                self.shared.first_cb_frames.load(Ordering::Relaxed),
            )
        })
    }

    /// The device's `callback − capture` delay of the latest block, ms.
    pub fn input_delay_ms(&self) -> f64 {
        self.shared.input_delay_ns.load(Ordering::Relaxed) as f64 / 1e6
    }

    /// Frames dropped because the ring was full.
    pub fn overruns(&self) -> u64 {
        self.shared.overruns.load(Ordering::Relaxed)
    }

    /// Callbacks so far.
    pub fn callbacks(&self) -> u64 {
        self.shared.callbacks.load(Ordering::Relaxed)
    }

    /// Frames delivered by the device so far.
    pub fn frames(&self) -> u64 {
        self.shared.frames.load(Ordering::Relaxed)
    }

    /// Device-side overruns (xruns) reported so far.
    pub fn xruns(&self) -> u64 {
        self.shared.xruns.load(Ordering::Relaxed)
    }

    /// Whether the device reported a stream error.
    pub fn had_error(&self) -> bool {
        self.shared.error.load(Ordering::Relaxed)
    }

    /// Peak |sample| since the last call.
    pub fn take_peak(&self) -> f32 {
        f32::from_bits(self.shared.peak_bits.swap(0, Ordering::Relaxed))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xruns_are_counted_apart_from_errors_and_overruns() {
        let (mut w, r) = capture_ring(16);
        let xrun = w.xrun_counter();
        xrun();
        xrun();
        assert_eq!(r.xruns(), 2);
        assert!(!r.had_error(), "an xrun is not an error");
        w.write(&[0.5f32; 64], 2, |x| x, Duration::ZERO);
        assert_eq!(r.overruns(), 32 - 16, "16 of 32 frames fit");
        assert_eq!(r.xruns(), 2);
        (w.error_flag())();
        assert!(r.had_error());
    }
}
