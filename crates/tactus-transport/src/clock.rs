//! The one time base of playback: [`Clock`], in ms since playback start.
//!
//! Three kinds read it:
//! - [`WallClock`]: the monotonic system clock (`--no-audio`);
//! - the audio output's position (song time audible now), implemented where the device lives
//!   (`tactus-session`, feature `device`), so touch follows the sound even if the audio device
//!   drifts; it reads `-inf` before the first output callback;
//! - [`FakeClock`]: moves only when slept on (or set), so a test runs a whole schedule as fast
//!   as the machine allows and every hand-off lands exactly on its time.
//!
//! The scheduler that reads a clock is [`crate::player::schedule`].

use std::cell::Cell;
use std::time::{Duration, Instant};

/// A playback time base in ms.
pub trait Clock {
    /// Milliseconds since playback start (non-decreasing; may be `-inf` before it starts).
    fn now_ms(&self) -> f64;
    /// Sleeps about `ms` (callers ask for at most 10 ms at a time).
    fn sleep_ms(&self, ms: f64) {
        std::thread::sleep(Duration::from_secs_f64(ms.max(0.0) / 1e3));
    }
}

/// The monotonic system clock; time 0 is its construction.
#[derive(Debug, Clone, Copy)]
pub struct WallClock {
    start: Instant,
}

impl WallClock {
    /// A clock starting now.
    pub fn new() -> WallClock {
        WallClock {
            start: Instant::now(),
        }
    }

    /// A clock whose time 0 is `start`.
    pub fn starting_at(start: Instant) -> WallClock {
        WallClock { start }
    }
}

impl Default for WallClock {
    fn default() -> WallClock {
        WallClock::new()
    }
}

impl Clock for WallClock {
    fn now_ms(&self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e3
    }
}

/// A clock for tests and simulations: it reads what it was set to, and sleeping on it moves it
/// forward by the time asked for (at least 0.01 ms, so a wait always ends) without sleeping.
///
/// ```
/// use tactus_transport::{Clock, FakeClock};
/// let c = FakeClock::new(0.0);
/// c.sleep_ms(7.5);
/// assert_eq!(c.now_ms(), 7.5);
/// c.set_ms(100.0);
/// assert_eq!(c.now_ms(), 100.0);
/// ```
#[derive(Debug, Default)]
pub struct FakeClock {
    now: Cell<f64>,
}

impl FakeClock {
    /// A clock reading `ms`.
    pub fn new(ms: f64) -> FakeClock {
        FakeClock { now: Cell::new(ms) }
    }

    /// Moves the clock to `ms`.
    pub fn set_ms(&self, ms: f64) {
        self.now.set(ms);
    }
}

impl Clock for FakeClock {
    fn now_ms(&self) -> f64 {
        self.now.get()
    }

    fn sleep_ms(&self, ms: f64) {
        self.now.set(self.now.get() + ms.max(0.01));
    }
}
