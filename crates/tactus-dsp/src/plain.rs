//! The plain-signal guard: a learned pitch tracker's fallback to YIN where the stem is a
//! plain periodic tone (a sine, a square, a saw, an 808 note, a flute, a whistle).
//!
//! A learned salience only knows the timbres it was trained on; on a pure tone it may see
//! nothing (and the finger goes silent) or an octave (docs/decisions/0051-plain-guard.md).
//! YIN ([`crate::yin`]) is exact on such a signal, and it says so: the cumulative mean
//! normalised difference at the period (the aperiodicity) is near 0 for a waveform that
//! repeats, and well above it for a stem with other instruments, drums or noise in it. The
//! guard reads it at the interpolated lag ([`Yin::with_vertex_aperiodicity`]), so that a
//! period of a fractional number of samples (a high tone at a decimated rate) counts.
//!
//! [`PlainGuard`] runs YIN beside the learned tracker on the same samples and hops and keeps
//! its estimates until the tracker reports the same hop. A hop is *plain* when YIN's
//! aperiodicity is at most [`MAX_APERIODICITY`] and its f0 lies between the tracker's fmin
//! and the guard's ceiling (the tracker's fmax, or above it where the stem may hold higher
//! tones than its tracker searches). YIN searches up to a quarter of the rate (lags from 4
//! samples), so that a tone above the ceiling is found at its own period and not at a
//! multiple of it inside the range (a 1 kHz sine is not a 100 Hz bass).
//!
//! ## Which estimate a hop keeps ([`PlainGuard::resolve`])
//! A band of a mix can look plain at a period that is not its note's: the notes of a chord
//! of sampled instruments share a longer period (a corpus chorale's lead read 73–110 Hz
//! under a soprano at 500 Hz, aperiodicity 0.02–0.04), and a bass with a weak
//! fundamental repeats at half its period. Letting YIN overrule the tracker on every plain
//! hop cost the held-out mixes' bass 0.04 RPA. So YIN wins a plain hop only where
//! * the tracker is silent;
//! * or the hop is strictly plain: aperiodicity at most [`STRICT_APERIODICITY`], or
//!   [`LOWER_APERIODICITY`] where YIN reads lower than the tracker (a common period of two
//!   notes reads lower than either: the held-out jazz bass had YIN an octave or two under
//!   the note at 0.012–0.015);
//! * or YIN took the hop before at the same pitch (within half a semitone) and this hop is
//!   nearly plain (aperiodicity at most [`HELD_APERIODICITY`]): a note YIN has overruled the
//!   tracker on stays YIN's, so that a held tone does not alternate between two readings,
//!   and a note YIN filled stays filled while the tracker stays silent (a saw near 2 kHz
//!   gliding at 14.7 kHz reads 0.04-0.06).
//!
//! A strictly plain tone above the ceiling means nothing in the tracker's range is sounding:
//! the hop is unvoiced (the tracker's reading there is a multiple of the tone's period).
//!
//! ## Latency
//! YIN's (half its frame). The guard never delays the tracker it backs as long as that
//! tracker's latency is at least YIN's; a hop YIN has not reported yet is not plain.
//!
//! The queue holds the hops YIN has judged and the tracker has not reported yet: its
//! `capacity` ([`PlainGuard::new`]) covers the tracker's lag; a block longer than that
//! grows it once, and nothing is allocated after that.

use std::collections::VecDeque;

use crate::yin::{PitchEstimate, Yin, YinConfig};
use crate::{ConfigError, HopStage};

/// Half a semitone: `2^(1/24)`.
const SLACK: f32 = 1.029_302_2;

/// Ceiling on YIN's aperiodicity for a plain hop (docs/decisions/0051-plain-guard.md).
pub const MAX_APERIODICITY: f32 = 0.05;

/// Ceiling on YIN's aperiodicity for a note YIN has taken over to stay YIN's
/// ([`PlainGuard::resolve`]): the hysteresis of [`MAX_APERIODICITY`].
pub const HELD_APERIODICITY: f32 = 0.1;

/// YIN's aperiodicity under which a plain hop overrules a tracker that reads its pitch or
/// lower ([`PlainGuard::resolve`]).
pub const STRICT_APERIODICITY: f32 = 0.015;

/// YIN's aperiodicity under which a plain hop overrules a tracker that reads higher than
/// YIN ([`PlainGuard::resolve`]).
pub const LOWER_APERIODICITY: f32 = 0.005;

/// What YIN says of a hop of the stem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Plain {
    /// A plain tone in range: YIN's estimate.
    Tone(PitchEstimate),
    /// A plain tone above the ceiling (YIN's estimate).
    Above(PitchEstimate),
    /// Not a plain tone (or not known yet): the tracker decides.
    Unsure,
}

/// One YIN and the estimates it has made that nobody has asked for yet.
struct Track {
    yin: Yin,
    pending: VecDeque<(usize, PitchEstimate)>,
}

impl Track {
    fn process(&mut self, x: &[f32]) {
        let pending = &mut self.pending;
        self.yin.process(x, &mut |i, e| pending.push_back((i, e)));
    }

    fn finish(&mut self) {
        let pending = &mut self.pending;
        self.yin.finish(&mut |i, e| pending.push_back((i, e)));
    }

    /// YIN's estimate of hop `i`, if made; forgets hops up to `i`.
    fn take(&mut self, i: usize) -> Option<PitchEstimate> {
        while let Some(&(j, e)) = self.pending.front() {
            if j > i {
                return None;
            }
            self.pending.pop_front();
            if j == i {
                return Some(e);
            }
        }
        None
    }

    fn reset(&mut self) {
        self.yin.reset();
        self.pending.clear();
    }
}

/// YIN beside a learned tracker; see the module docs.
pub struct PlainGuard {
    stem: Track,
    range_hz: (f32, f32),
    /// The note YIN took on the last hop: it stays YIN's while it stays nearly plain at
    /// that pitch.
    run: Option<Run>,
}

/// A note YIN took ([`PlainGuard::resolve`]).
#[derive(Clone, Copy, Debug)]
struct Run {
    /// YIN's pitch on the last hop, Hz.
    f0_hz: f32,
    /// Whether YIN overruled the tracker's reading (held against it) or filled its silence
    /// (held only while the tracker stays silent).
    overruled: bool,
}

impl PlainGuard {
    /// A guard for a tracker over `yc`'s range, rate and hops that accepts plain tones up
    /// to `ceiling_hz` (at least `yc`'s fmax); `capacity`: hops to hold without allocating
    /// (the tracker's latency minus YIN's, in hops, and a few more).
    pub fn new(yc: &YinConfig, ceiling_hz: f32, capacity: usize) -> Result<Self, ConfigError> {
        let quarter = 0.25 * yc.sample_rate as f32;
        let ceiling_hz = ceiling_hz.max(yc.fmax_hz).min(quarter);
        let mut wide = yc.clone();
        // Up to a quarter of the rate (lags from 4 samples): a tone anywhere below it is
        // found at its own period.
        wide.fmax_hz = quarter.max(yc.fmax_hz);
        Ok(PlainGuard {
            stem: Track {
                yin: Yin::new(wide)?.with_vertex_aperiodicity(),
                pending: VecDeque::with_capacity(capacity.max(4)),
            },
            // Half a semitone of slack at both ends: a tone at the ceiling may read a hair
            // above it.
            range_hz: (yc.fmin_hz / SLACK, ceiling_hz * SLACK),
            run: None,
        })
    }

    /// Feeds the block the tracker gets.
    pub fn process(&mut self, x: &[f32]) {
        self.stem.process(x);
    }

    /// Ends the stream: YIN's last hops.
    pub fn finish(&mut self) {
        self.stem.finish();
    }

    /// What YIN says of hop `i` of the stem ([`Plain`]); forgets hops up to `i`. Call with
    /// increasing `i`.
    pub fn take(&mut self, i: usize) -> Plain {
        let e = self.stem.take(i);
        self.classify(e)
    }

    /// [`Plain`] of YIN's estimate of a hop.
    fn classify(&self, e: Option<PitchEstimate>) -> Plain {
        match e {
            Some(e) if e.f0_hz > 0.0 && e.aperiodicity <= MAX_APERIODICITY => {
                if e.f0_hz > self.range_hz.1 {
                    Plain::Above(e)
                } else if e.f0_hz >= self.range_hz.0 {
                    Plain::Tone(e)
                } else {
                    Plain::Unsure
                }
            }
            _ => Plain::Unsure,
        }
    }

    /// What hop `i` becomes, given the tracker's `f0` for it (Hz, 0 unvoiced): `Some(f0)`
    /// to replace it (YIN's f0, or 0 for unvoiced), `None` to keep it. Call with increasing
    /// `i`. See the module docs.
    pub fn resolve(&mut self, i: usize, f0: f32) -> Option<f32> {
        let run = self.run.take();
        let est = self.stem.take(i);
        // A note YIN has taken over stays YIN's while YIN reads it at the same pitch, in
        // range, a little less plain than it must be to take it: a saw near the top of the
        // lead's range gliding at a decimated rate reads 0.04-0.06.
        if let (Some(r), Some(e)) = (run, est) {
            if (r.overruled || f0 <= 0.0)
                && e.f0_hz >= self.range_hz.0
                && e.f0_hz <= self.range_hz.1
                && e.aperiodicity <= HELD_APERIODICITY
                && same_pitch(r.f0_hz, e.f0_hz)
            {
                self.run = Some(Run {
                    f0_hz: e.f0_hz,
                    ..r
                });
                return Some(e.f0_hz);
            }
        }
        match self.classify(est) {
            Plain::Tone(e) => {
                // A YIN pitch below the tracker's may be a common period of two notes: it
                // must be plainer still.
                let strict = if e.f0_hz * SLACK < f0 {
                    LOWER_APERIODICITY
                } else {
                    STRICT_APERIODICITY
                };
                if e.aperiodicity <= strict {
                    self.run = Some(Run {
                        f0_hz: e.f0_hz,
                        overruled: true,
                    });
                    Some(e.f0_hz)
                } else if f0 <= 0.0 {
                    self.run = Some(Run {
                        f0_hz: e.f0_hz,
                        overruled: false,
                    });
                    Some(e.f0_hz)
                } else {
                    None
                }
            }
            Plain::Above(e) if e.aperiodicity <= STRICT_APERIODICITY => Some(0.0),
            Plain::Above(_) | Plain::Unsure => None,
        }
    }

    /// Back to the just-constructed state.
    pub fn reset(&mut self) {
        self.stem.reset();
        self.run = None;
    }

    /// YIN's latency in samples.
    pub fn latency_samples(&self) -> usize {
        self.stem.yin.latency_samples()
    }
}

/// Whether two pitches are within half a semitone.
fn same_pitch(a: f32, b: f32) -> bool {
    (a / b).clamp(1.0 / SLACK, SLACK) == a / b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(rate: u32, f0: f32, n: usize) -> Vec<f32> {
        (0..n)
            .map(|j| 0.5 * (std::f32::consts::TAU * f0 * j as f32 / rate as f32).sin())
            .collect()
    }

    fn plain_hops(g: &mut PlainGuard, x: &[f32]) -> Vec<Option<f32>> {
        g.process(x);
        g.finish();
        let n = x.len().div_ceil(g.stem.yin.hop());
        (0..n)
            .map(|i| match g.take(i) {
                Plain::Tone(e) => Some(e.f0_hz),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_tone_in_range_is_plain_at_its_own_pitch() {
        let yc = YinConfig::new(4900, 35.0, 400.0);
        let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
        let hops = plain_hops(&mut g, &tone(4900, 110.0, 4900));
        let mid = &hops[20..80];
        assert!(mid
            .iter()
            .all(|f| f.is_some_and(|f| (f / 110.0 - 1.0).abs() < 0.003)));
    }

    #[test]
    fn a_tone_above_the_range_is_not_a_subharmonic_in_it() {
        // 1 kHz: every multiple of its 1 ms period in 2.5..28.6 ms is a perfect period; a
        // YIN over 35-400 Hz alone reports one of them.
        let yc = YinConfig::new(4900, 35.0, 400.0);
        let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
        let x = tone(4900, 1000.0, 4900);
        g.process(&x);
        g.finish();
        let said: Vec<Plain> = (0..x.len().div_ceil(g.stem.yin.hop()))
            .map(|i| g.take(i))
            .collect();
        assert!(
            said.iter().all(|p| !matches!(p, Plain::Tone(_))),
            "{said:?}"
        );
        assert!(
            said[20..80].iter().all(|p| matches!(p, Plain::Above(_))),
            "{said:?}"
        );
    }

    #[test]
    fn a_ceiling_above_the_range_accepts_a_higher_tone() {
        let yc = YinConfig::new(14_700, 70.0, 1400.0);
        let mut g = PlainGuard::new(&yc, 2000.0, 16).unwrap();
        let hops = plain_hops(&mut g, &tone(14_700, 1900.0, 14_700));
        assert!(hops[20..80]
            .iter()
            .all(|f| f.is_some_and(|f| (f / 1900.0 - 1.0).abs() < 0.003)));
        let mut g = PlainGuard::new(&yc, 1400.0, 16).unwrap();
        let hops = plain_hops(&mut g, &tone(14_700, 1900.0, 14_700));
        assert!(hops.iter().all(Option::is_none));
    }

    /// A saw's first two harmonics (as the spectral separator's vocal band, up to 5 kHz,
    /// leaves a 2 kHz saw) whose period is a fractional number of samples (1970 Hz at 14.7 kHz: 7.46): judged at
    /// integer lags YIN misses the threshold at lag 7 and takes twice the period; judged at
    /// the interpolated lag it reads the saw at its own pitch, and plain.
    #[test]
    fn the_interpolated_lag_reads_a_high_saw_at_its_own_period() {
        let rate = 14_700;
        let f0 = 1970.0f32;
        let x: Vec<f32> = (0..rate as usize)
            .map(|j| {
                let t = j as f32 / rate as f32;
                (1..=2)
                    .map(|h| 0.3 / h as f32 * (std::f32::consts::TAU * h as f32 * f0 * t).sin())
                    .sum()
            })
            .collect();
        let mut yc = YinConfig::new(rate, 70.0, 3675.0);
        yc.fmax_hz = 3675.0;
        let read = |vertex: bool| {
            let y = Yin::new(yc.clone()).unwrap();
            let mut y = if vertex {
                y.with_vertex_aperiodicity()
            } else {
                y
            };
            let mut est = Vec::new();
            y.process(&x, &mut |_, e| est.push(e));
            est[20..80].to_vec()
        };
        let (vertex, integer) = (read(true), read(false));
        // At its own pitch with the interpolated lag; at twice the period, or not at all,
        // with integer lags.
        assert!(vertex.iter().all(|e| (e.f0_hz / f0 - 1.0).abs() < 0.01));
        let own = |e: &&PitchEstimate| (e.f0_hz / f0 - 1.0).abs() < 0.01;
        assert!(
            integer.iter().filter(own).count() * 2 < integer.len(),
            "{:?}",
            &integer[..4]
        );
    }

    #[test]
    fn noise_silence_and_dc_are_not_plain() {
        let yc = YinConfig::new(4900, 35.0, 400.0);
        let mut rng = 0x9E37_79B9_7F4A_7C15u64;
        let noise: Vec<f32> = (0..4900)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                (rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5
            })
            .collect();
        for (name, x) in [
            ("noise", noise),
            ("silence", vec![0.0; 4900]),
            ("DC", vec![0.3; 4900]),
        ] {
            let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
            let hops = plain_hops(&mut g, &x);
            assert!(hops.iter().all(Option::is_none), "{name}: {hops:?}");
        }
    }

    #[test]
    fn resolve_fills_silence_overrules_strictly_and_holds_a_note_it_took() {
        let yc = YinConfig::new(4900, 35.0, 400.0);
        let e = |f0_hz, aperiodicity| PitchEstimate {
            f0_hz,
            aperiodicity,
            voiced_prob: 1.0 - aperiodicity,
        };
        // (stem YIN, tracker) → result, in hop order (a taken note carries over).
        let cases = [
            // Silent tracker, plain hop: filled.
            (e(110.0, 0.03), 0.0, Some(110.0)),
            // Merely plain, the tracker reads an octave, a fifth, far off: kept.
            (e(110.0, 0.03), 55.0, None),
            (e(110.0, 0.03), 165.0, None),
            (e(110.0, 0.03), 660.0, None),
            (e(110.0, 0.2), 0.0, None),
            // YIN lower than the tracker: needs 0.005.
            (e(110.0, 0.008), 220.0, None),
            (e(110.0, 0.004), 220.0, Some(110.0)),
            // Taken: the note stays YIN's while plain at the same pitch...
            (e(110.5, 0.04), 220.0, Some(110.5)),
            (e(111.0, 0.04), 220.0, Some(111.0)),
            // ...or nearly plain (the hysteresis)...
            (e(111.2, 0.08), 220.0, Some(111.2)),
            (e(111.0, 0.11), 220.0, None),
            (e(110.0, 0.004), 220.0, Some(110.0)),
            // ...until it moves or stops being plain.
            (e(130.0, 0.04), 220.0, None),
            (e(130.0, 0.03), 220.0, None),
            // A filled note stays filled while nearly plain and the tracker silent...
            (e(130.0, 0.03), 0.0, Some(130.0)),
            (e(130.5, 0.08), 0.0, Some(130.5)),
            // ...but does not overrule the tracker when it speaks.
            (e(130.5, 0.08), 260.0, None),
            (e(130.0, 0.03), 0.0, Some(130.0)),
            (e(130.0, 0.08), 260.0, None),
            // YIN higher than (or at) the tracker: 0.015 is enough.
            (e(110.0, 0.012), 55.0, Some(110.0)),
            (e(110.0, 0.2), 55.0, None),
            (e(110.0, 0.03), 55.0, None),
            // A strictly plain tone above the ceiling unvoices; a merely plain one does not.
            (e(1000.0, 0.005), 100.0, Some(0.0)),
            (e(1000.0, 0.03), 100.0, None),
            (e(20.0, 0.001), 0.0, None),
        ];
        let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
        for (i, &(y, _, _)) in cases.iter().enumerate() {
            g.stem.pending.push_back((i, y));
        }
        for (i, &(y, f0, want)) in cases.iter().enumerate() {
            assert_eq!(g.resolve(i, f0), want, "hop {i}: YIN {y:?}, tracker {f0}");
        }
    }

    /// Streaming equals one whole block for any chunking: a tone that starts, glides and
    /// stops over noise, fed in random chunks, resolved hop by hop against a tracker that
    /// reads an octave low, silence, or the tone.
    #[test]
    fn any_chunking_resolves_the_same_hops() {
        let rate = 4900;
        let yc = YinConfig::new(rate, 35.0, 400.0);
        let mut rng = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let mut ph = 0.0f32;
        let x: Vec<f32> = (0..3 * rate as usize)
            .map(|j| {
                let t = j as f32 / rate as f32;
                let f = 110.0 * 2f32.powf((t - 1.0).clamp(0.0, 1.0) / 12.0);
                ph += std::f32::consts::TAU * f / rate as f32;
                let on = if (0.5..2.5).contains(&t) { 0.5 } else { 0.0 };
                on * ph.sin() + 0.01 * ((next() >> 40) as f32 / (1u64 << 24) as f32 - 0.5)
            })
            .collect();
        let tracker = |i: usize| [55.0, 0.0, 110.0][i % 3];
        let run = |chunks: &mut dyn FnMut() -> usize| {
            let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
            let (mut out, mut pos, mut hop) = (Vec::new(), 0, 0);
            let mut drain = |g: &mut PlainGuard, out: &mut Vec<Option<f32>>| {
                while let Some(&(j, _)) = g.stem.pending.back() {
                    if hop > j {
                        break;
                    }
                    out.push(g.resolve(hop, tracker(hop)));
                    hop += 1;
                }
            };
            while pos < x.len() {
                let n = chunks().min(x.len() - pos);
                g.process(&x[pos..pos + n]);
                pos += n;
                drain(&mut g, &mut out);
            }
            g.finish();
            drain(&mut g, &mut out);
            out
        };
        let whole = run(&mut || usize::MAX);
        assert_eq!(whole.len(), x.len().div_ceil(yc.hop));
        assert!(whole.iter().filter(|r| r.is_some()).count() > 100);
        for _ in 0..4 {
            let got = run(&mut || 1 + (next() % 700) as usize);
            assert_eq!(got, whole);
        }
    }

    /// The guard's latency: hop `i` (centred on sample `i·hop`) is judged once sample
    /// `i·hop + latency_samples() − 1` has arrived, and not before; a tone that starts at
    /// hop `i` is plain there.
    #[test]
    fn a_hop_is_judged_latency_samples_after_its_centre() {
        let rate = 4900;
        let yc = YinConfig::new(rate, 35.0, 400.0);
        let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
        let hop = yc.hop;
        let lat = g.latency_samples();
        let x = tone(rate, 110.0, 2 * rate as usize);
        let i = 50;
        g.process(&x[..i * hop + lat - 1]);
        assert!(g.stem.pending.back().is_some_and(|&(j, _)| j < i));
        g.process(&x[i * hop + lat - 1..i * hop + lat]);
        assert_eq!(g.stem.pending.back().map(|&(j, _)| j), Some(i));
        assert!(matches!(g.take(i), Plain::Tone(_)));
    }

    #[test]
    fn take_skips_hops_and_never_returns_a_later_one() {
        let yc = YinConfig::new(4900, 35.0, 400.0);
        let mut g = PlainGuard::new(&yc, 400.0, 16).unwrap();
        g.process(&tone(4900, 110.0, 4900));
        g.finish();
        assert!(matches!(g.take(30), Plain::Tone(_)));
        // Hop 10 was forgotten on the way to 30.
        assert_eq!(g.take(10), Plain::Unsure);
        assert!(matches!(g.take(31), Plain::Tone(_)));
    }
}
