//! Latency profiles (`docs/decisions/0006-live-latency-profile.md`).
//!
//! The same engine serves the offline renderer and the live glove; a [`Profile`] picks how
//! much look-ahead each stage may spend on quality.
//!
//! * [`Profile::Full`] (default for `render` and `play`): the stages as documented in their
//!   modules: the spectral separator's 2048-point frames and 2 frames of look-ahead
//!   (92.9 ms), pYIN / harmonic-sum pitch with a 100 ms Viterbi lag, the per-instrument drum
//!   transcriber on the separated drum stem (61.6 ms), 100 ms (render) or 25 ms (play) bins.
//! * [`Profile::Live`] (chosen by `tactus live`): every stage trades quality for
//!   milliseconds, each latency stated in samples below (44.1 kHz) and checked against an
//!   impulse or a step in `tests/profile.rs`:
//!
//! | stage | live profile | latency (samples @ 44.1 kHz) |
//! |---|---|---|
//! | capture (`tactus live`) | the engine's rate (no resampler), a 256-frame period asked for | the device's period (PulseAudio gave 170 frames, 3.9 ms) |
//! | drums | no separator: the drum detector listens to the mix (no separator latency) | 0 |
//! | denoise | Butterworth high-pass + 3-sample median | 1 |
//! | drum onsets (`--drums classes-live`, `tactus live`'s default) | the per-instrument transcriber on the mix (its embedded 1-hop model) | 953 (21.6 ms) |
//! | drum onsets (`--drums bands`) | Butterworth bands, spectral flux with 1024-point frames every 5 ms, causal rising-edge picking, the gate's level over two hops | 220 (5.0 ms) |
//! | drum onsets (`--drums classes`) | the per-instrument transcriber on the mix (its embedded 4-hop model and the snare's one-hop second stage) | 2,717 (61.6 ms) |
//! | separator (melodic stems) | spectral, [`separator`]: 512-point frames, hop 128, harmonic median over 5 frames, no look-ahead | 511 (11.6 ms) |
//! | pitch, bass and lead (`--pitch auto`) | the live models ([`tactus_dsp::bassnet`], "The live models") on the separator's harmonic sum: frames of [`LIVE_BASS_NET_FRAME_S`] (78 ms) and [`LIVE_LEAD_NET_FRAME_S`] (35 ms) centred on their hop, past frames as context, Viterbi lags of [`LIVE_BASS_LAG_HOPS`] and [`LIVE_LEAD_LAG_HOPS`] hops; YIN behind them on a plain tone (`tactus_dsp::plain`) | bass 1,728 (39.2 ms), vocals 1,209 (27.4 ms) |
//! | pitch, other (and bass and lead with `--pitch yin`) | YIN on two frames ([`tactus_dsp::twoframe`]): two periods of [`TWO_FRAME_SPLIT`]` · fmin` ([`pitch_frame`]) answer for every note but those below that split, which come from a frame of two periods of `fmin`, one hop later; a YIN bass from 41 Hz (E1); `--pitch pyin` gets one frame of two periods of `fmin` and a Viterbi lag of [`PITCH_LAG_HOPS`] hops | YIN bass 819 (18.6 ms; below 54.7 Hz 1,260), vocals 477, other 666 |
//! | bins | [`BIN_MS`] = 10 ms | 441 |
//! | pins | a beat holds its pins up for [`PULSE_MS`] = 50 ms, so a 50 ms pin rise completes | 0 |
//!
//! The rhythm path sums to 1 + 953 + 441 = 1,395 samples (31.6 ms; with `--drums bands`,
//! 1 + 220 + 441 = 662 samples, 15 ms), the slowest pitch path (bass) to
//! 511 + 1 + 1,728 + 441 = 2,681 samples (60.8 ms; with `--pitch yin` 1,772 = 40.2 ms);
//! `tests/profile.rs` feeds a
//! drum hit and tone steps in 64-sample blocks and checks that the frame showing them
//! exists within that (plus one detector hop and one block). Measured from outside, sound to
//! frame at the glove: `tests/live_latency.rs` and `docs/decisions/0006-live-latency-profile.md`.
//!
//! The glove shows each feature as soon as it is final: the rhythm cells of frame `k` are
//! those of bin `k`, a pitch cell shows the bin that its slower chain had finished when the
//! rhythm of bin `k` was ([`crate::Engine::live_frame`]), so a pitch tracker's look-ahead
//! never holds the drums back.
//!
//! Statistics warm up at once: the gate reference is a running maximum (the first loud hop
//! sets it), the flux threshold is a 100 ms mean, and the level range starts from a prior
//! span around the first note (`track::PriorRange`).

use tactus_separate::spectral::SpectralConfig;

/// How much look-ahead the stages may spend; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Profile {
    /// Quality first: every stage as documented in its module.
    #[default]
    Full,
    /// Milliseconds first: short frames, no look-ahead, 10 ms bins, pin pulses.
    Live,
}

impl Profile {
    /// Name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Full => "full",
            Profile::Live => "live",
        }
    }

    /// Bins a beat keeps its pins up for (1 = the bin itself) at `bin_ms`.
    pub fn pulse_bins(self, bin_ms: u32) -> usize {
        match self {
            Profile::Full => 1,
            Profile::Live => PULSE_MS.div_ceil(bin_ms.max(1)).max(1) as usize,
        }
    }
}

/// Bin length of the live profile, ms.
pub const BIN_MS: u32 = 10;
/// Shortest pin pulse of the live profile, ms: the glove's pins take 50 ms to rise
/// (`tactus_glove::RISE_MS`), so a one-bin beat of 10 ms would be lowered before it is felt.
pub const PULSE_MS: u32 = 50;
/// Viterbi lag of the live profile's pYIN and harmonic-sum trackers (`--pitch pyin|shs`),
/// hops of 10 ms. Plain YIN (the live `other`, and `--pitch yin`) has none; the live models
/// have their own ([`LIVE_BASS_LAG_HOPS`], [`LIVE_LEAD_LAG_HOPS`]).
pub const PITCH_LAG_HOPS: usize = 2;
/// Viterbi lag of the live profile's learned bass tracker (the default), hops of 10 ms:
/// none, so that a bass note reaches the thumb within the 80 ms pitch budget measured from
/// outside (`benches/live_latency.py`: 98 Hz bursts p95 82 ms at lag 0 on this 2-core
/// machine; each hop of lag adds 10 ms). On 20 tuning mixes a lag of 1 would give bass RPA
/// 0.772 against 0.766 (`docs/decisions/0057-learned-live-pitch.md`).
pub const LIVE_BASS_LAG_HOPS: usize = 0;
/// Viterbi lag of the live profile's learned lead tracker, hops: one (lead RPA on the 20
/// tuning mixes 0.805 / 0.811 / 0.813 at lags 0 / 1 / 2; its frame is 35 ms, the bass's 78).
pub const LIVE_LEAD_LAG_HOPS: usize = 1;
/// Where the live profile's YIN hands over from its long frame to its short one
/// ([`tactus_dsp::twoframe`]), as a ratio to the stem's lowest note: a fourth above it. Notes
/// from there up are shown with a frame of two periods of `4/3·fmin` (bass: 819 samples of
/// latency instead of 1,089), the notes below it one 10 ms hop later than a single long
/// frame would (bass: 1,260). Measured with `--profile live` on 18 corpus songs (6 chorales,
/// 12 sung; `benches/bass_eval.py --modes streaming --extra "--profile live"`), isolated
/// stems, against one frame: bass RPA 0.919 → 0.923, vocals 0.882 → 0.884, bass note-onset F
/// 0.714 → 0.676; a split at `2·fmin` saved 6 ms more on a 98 Hz tone but dropped the bass
/// note-onset F to 0.395 (a whole octave of notes stamped two hops late), at `1.5·fmin` 0.648.
pub const TWO_FRAME_SPLIT: f32 = 4.0 / 3.0;
/// Lowest bass note the live profile tracks, Hz (E1, the lowest string of a bass guitar):
/// its frame holds two periods of it ([`pitch_frame`]).
pub const BASS_FMIN_HZ: f32 = 41.0;

/// The live profile's spectral separator for the melodic stems: 512-point frames every 128
/// samples, the harmonic (time) median over 4 past frames and none ahead.
/// Latency `n_fft − 1` = 511 samples (11.6 ms at 44.1 kHz). The causal median calls a new
/// note percussive until it fills half its window, so a short window matters as much as
/// the frame: with 1024/256 and 12 past frames the tone bursts of `benches/live_latency.py`
/// reached the pitch pins after 90 ms (median), with 1024/256 and 4 after 69 ms, with
/// 512/128 and 4 after 56 ms.
pub fn separator() -> SpectralConfig {
    SpectralConfig {
        n_fft: 512,
        hop: 128,
        past_frames: 4,
        // The full profile's longer bass median (which keeps kick bodies out of the bass)
        // would make a new bass note wait for 5 rather than 3 frames: off.
        bass_past_frames: 4,
        lookahead_frames: 0,
        percussive_half_bins: 4,
        // The learned low-band drum mask needs the full profile's bins and look-ahead.
        low_band_drums: false,
        ..SpectralConfig::default()
    }
}

/// The live profile's YIN frame at `rate` for a lowest pitch `fmin_hz`: the shortest even
/// frame whose half (YIN's integration window) holds the longest period plus one lag, i.e.
/// two periods of `fmin_hz` (the full profile rounds this up to a power of two, up to twice
/// as long). Latency: half the frame.
pub fn pitch_frame(rate: u32, fmin_hz: f32) -> usize {
    let tau_max = (rate as f64 / fmin_hz.max(1.0) as f64).ceil() as usize;
    (2 * (tau_max + 1)).next_multiple_of(2).max(64)
}

/// Frame of the live bass model, seconds: 384 samples at the bass chain's 4.9 kHz
/// (78 ms; its latency is half of it). A 256-sample model gave bass RPA 0.717 against
/// 0.772 on the 20 tuning mixes (both at a lag of one hop). `models/bassnet/train.py --stem bass_live`.
pub const LIVE_BASS_NET_FRAME_S: f64 = 384.0 / 4900.0;
/// Frame of the live lead model, seconds: 512 samples at the lead chain's 14.7 kHz (35 ms).
pub const LIVE_LEAD_NET_FRAME_S: f64 = 512.0 / 14700.0;

/// The live models' frame at the decimated `rate` (the lead's for a `melody` grid): the
/// nearest even number of samples to [`LIVE_BASS_NET_FRAME_S`] or [`LIVE_LEAD_NET_FRAME_S`].
pub fn live_net_frame(rate: u32, melody: bool) -> usize {
    let secs = if melody {
        LIVE_LEAD_NET_FRAME_S
    } else {
        LIVE_BASS_NET_FRAME_S
    };
    (((rate as f64 * secs / 2.0).round() as usize) * 2).max(8)
}

/// The search range of a melodic stem in a profile: the live profile starts the bass at
/// [`BASS_FMIN_HZ`].
pub fn pitch_range_hz(profile: Profile, stem: tactus_dsp::Stem) -> Option<(f32, f32)> {
    let (lo, hi) = stem.pitch_range_hz()?;
    Some(match (profile, stem) {
        (Profile::Live, tactus_dsp::Stem::Bass) => (lo.max(BASS_FMIN_HZ), hi),
        _ => (lo, hi),
    })
}
