//! How far behind the live loop is: the device's usual delay ([`DelayFloor`]) and the capture
//! clock's lag ([`ClockLag`]), which decide when to drop audio to catch up (see the `live`
//! module docs).

/// The device's usual `callback − capture` delay: the smallest seen over the last one to
/// two buckets of [`DelayFloor::READS`] reads (about 2 s each at one read per 4 ms
/// capture period; counted in reads, not time, so that a stall does not age the floor
/// out). Its excess is audio that waited in the device (or sound server) longer than
/// usual: a backlog that the ring does not show. A device whose delay rises for good stops
/// counting as behind after two buckets, so a large but steady delay (a Bluetooth
/// microphone) never drops audio.
#[derive(Debug)]
pub(super) struct DelayFloor {
    current: f64,
    previous: f64,
    reads: u32,
}

impl Default for DelayFloor {
    fn default() -> Self {
        DelayFloor {
            current: f64::INFINITY,
            previous: f64::INFINITY,
            reads: 0,
        }
    }
}

impl DelayFloor {
    const READS: u32 = 512;

    /// Records one read's `delay_ms`; returns how far it exceeds the floor, ms.
    pub(super) fn excess(&mut self, delay_ms: f64) -> f64 {
        let d = if delay_ms.is_finite() {
            delay_ms.max(0.0)
        } else {
            0.0
        };
        self.current = self.current.min(d);
        let floor = self.current.min(self.previous);
        self.reads += 1;
        if self.reads >= Self::READS {
            (self.previous, self.current, self.reads) = (self.current, f64::INFINITY, 0);
        }
        d - floor
    }
}

/// How much later than usual the newest captured sample reaches this loop, by the capture
/// clock: wall time since the first callback minus the audio received since then, over its
/// floor ([`DelayFloor`], which also follows a slow drift between the two clocks). Unlike
/// the device's delay report, it sees audio that the sound server held back (PulseAudio's
/// ALSA plugin does not always count it), and so it catches a stalled process's burst on any
/// sound server.
///
/// A late sample is worth dropping only while the loop can win the lag back: while audio
/// arrives faster than real time and the lag falls. So [`ClockLag::update`] says "catch up"
/// from the read where the lag jumps past the bound (a stall: half the bound in one read)
/// and for as long as it keeps falling (by [`ClockLag::STEP_MS`], three capture periods, at
/// least once every [`ClockLag::HOLD_MS`]). A lag that crept up and stays (a starved sound
/// server handing audio over late at the pace it makes it, or samples lost in a device xrun)
/// is never dropped for: the floor takes it in after two buckets of reads.
#[derive(Debug, Default)]
pub(super) struct ClockLag {
    floor: DelayFloor,
    /// The previous read's excess, ms.
    previous: f64,
    /// While over the bound: the lowest excess seen and when (wall ms), and whether a
    /// jump started it.
    low: Option<(f64, f64)>,
}

impl ClockLag {
    /// A fall that counts as winning the lag back, ms.
    const STEP_MS: f64 = 12.0;
    /// How long catching up goes on without such a fall, ms.
    const HOLD_MS: f64 = 200.0;

    /// One read: `wall_ms` since the first callback, `audio_ms` of audio received since
    /// then up to the newest sample, the bound `max_ms`. Returns the excess lag (ms) and
    /// whether to drop what this read brought.
    pub(super) fn update(&mut self, wall_ms: f64, audio_ms: f64, max_ms: f64) -> (f64, bool) {
        let e = self.floor.excess(wall_ms - audio_ms);
        let previous = std::mem::replace(&mut self.previous, e);
        if e <= max_ms {
            self.low = None;
            return (e, false);
        }
        match &mut self.low {
            None => {
                // Past the bound: a jump catches up at once, a creep waits for a fall.
                let since = if e - previous > max_ms / 2.0 {
                    wall_ms
                } else {
                    wall_ms - Self::HOLD_MS - 1.0
                };
                self.low = Some((e, since));
            }
            Some((low, since)) => {
                if e < *low - Self::STEP_MS {
                    (*low, *since) = (e, wall_ms);
                }
            }
        }
        let (_, since) = self.low.expect("set above");
        (e, wall_ms - since <= Self::HOLD_MS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_delay_floor_ignores_a_burst_and_follows_a_lasting_rise() {
        let mut f = DelayFloor::default();
        for _ in 0..100 {
            assert_eq!(f.excess(5.0), 0.0);
        }
        // A stall: the first block after it waited 3 s longer than usual.
        assert_eq!(f.excess(3005.0), 3000.0);
        assert_eq!(f.excess(5.0), 0.0);
        // A lasting rise to 250 ms counts as excess for at most two buckets of reads.
        let n = (0..3 * DelayFloor::READS)
            .filter(|_| f.excess(250.0) > 0.0)
            .count();
        assert!(n <= 2 * DelayFloor::READS as usize, "{n}");
        assert_eq!(f.excess(250.0), 0.0);
        assert_eq!(f.excess(f64::NAN), 0.0);
    }

    /// Per read: (excess, catch up).
    type Reads = Vec<(f64, bool)>;

    /// Reads every 4 ms of 4 ms of audio, the clock lag at 5 ms; then a 3 s stall whose
    /// audio arrives in a burst at `speed` times real time; then a lag that creeps up by
    /// 300 ms over 3 s and stays. Returns, per read, (excess, catch up).
    fn clock_lag_run(speed: f64) -> (Reads, Reads) {
        let mut c = ClockLag::default();
        let (mut wall, mut audio) = (5.0, 0.0);
        for _ in 0..200 {
            (wall, audio) = (wall + 4.0, audio + 4.0);
            assert_eq!(c.update(wall, audio, 200.0), (0.0, false));
        }
        // The stall, then the burst: each read brings 4 * speed ms until caught up.
        wall += 3000.0;
        let mut burst = Vec::new();
        while wall - audio > 5.0 + 1e-9 {
            (wall, audio) = (wall + 4.0, (audio + 4.0 * speed).min(wall + 4.0 - 5.0));
            burst.push(c.update(wall, audio, 200.0));
        }
        let mut creep = Vec::new();
        for i in 0..1500 {
            let extra = if i < 750 { 0.4 } else { 0.0 };
            (wall, audio) = (wall + 4.0, audio + 4.0 - extra);
            creep.push(c.update(wall, audio, 200.0));
        }
        (burst, creep)
    }

    #[test]
    fn the_clock_lag_catches_up_a_burst_at_any_speed_but_not_a_creep() {
        for speed in [1.5, 2.0, 5.0, 50.0] {
            let (burst, creep) = clock_lag_run(speed);
            // Every read of the burst whose audio is more than the bound late is dropped,
            // the first (the read right after the stall) included.
            for (i, &(e, drop)) in burst.iter().enumerate() {
                assert_eq!(drop, e > 200.0, "speed {speed}, read {i}: excess {e}");
            }
            assert!((burst[0].0 - (3004.0 - 4.0 * speed)).abs() < 1e-6 && burst[0].1);
            // The creep (0.4 ms per read up to 300 ms, then flat) is never dropped for,
            // though it passes the bound: reading faster cannot win it back.
            assert!(creep.iter().any(|x| x.0 > 250.0), "speed {speed}");
            assert!(creep.iter().all(|x| !x.1), "speed {speed}");
        }
        // Jitter of one capture period around a lag over the bound is no fall.
        let mut c = ClockLag::default();
        let mut wall = 0.0;
        for i in 0..300 {
            wall += 4.0;
            c.update(wall, wall - 5.0 - f64::from(i.min(60)) * 5.0, 200.0);
        }
        for i in 0..400 {
            wall += 4.0;
            let jitter = if i % 2 == 0 { 3.9 } else { 0.0 };
            let (_, drop) = c.update(wall, wall - 305.0 + jitter, 200.0);
            assert!(!drop, "read {i}");
        }
    }
}
