//! The spectral separator: the embedded default backend (pure Rust, streaming).
//!
//! An honest approximation, not a learned model. Every stem is a soft mask on the STFT of
//! the mono mix `M = (L + R) / 2`, and the four masks sum to 1 in every bin, so
//! `drums + bass + vocals + other` reconstructs the mono mix to float round-off (the STFT
//! round trip is exact, see [`crate::stft`]).
//!
//! 1. **Drums** = the percussive part of median-filter harmonic/percussive separation
//!    (Fitzgerald, "Harmonic/percussive separation using median filtering", DAFx 2010).
//!    Per bin, `H` = median of `|M|` over time, `P` = median of `|M|` over frequency;
//!    the percussive mask is the Wiener-like `P² / (H² + P²)`. The time median is made
//!    streaming with a bounded look-ahead: it spans `past_frames` frames before the frame
//!    and `lookahead_frames` after it (frames before the start and after the end count as
//!    silence).
//! 2. **Bass** = the harmonic part below `bass_crossover_hz`, with a raised-cosine crossover
//!    half an octave wide (in log frequency) centred on it. Below the crossover a second,
//!    longer time median (`bass_past_frames` past frames, same look-ahead, so no added latency)
//!    also votes: `bass = min(harm, harm_long) · crossover`. A kick's low body lasts long
//!    enough that the short median still calls part of it harmonic; the long one calls it less
//!    so, and the bass tracker stops following kicks (`tests/quality.rs`: kick energy left in
//!    bass −1.1 → −2.0 dB; on the drum corpus's `timgm` mixes bass RPA 0.733 → 0.758, bass
//!    levels ±1 0.60 → 0.71). Then the **kit mask** (`low_band_drums`, [`crate::lowband`]): a
//!    small learned network gives, per bin below 301 Hz, the drum kit's share, which moves from
//!    the bass mask to the drums (`bass·p` leaves bass, joins drums; vocals and other are
//!    untouched). It reads the frames the time median already holds, so it adds no latency.
//!    Held-out mixes of the corpus: bass RPA 0.61 → 0.69 (sung songs), 0.71 → 0.77 (drum
//!    corpus) (`docs/decisions/0020-kit-mask.md`).
//! 3. **Vocals** = the rest of the harmonic part, times a vocal band (`vocal_band_hz`,
//!    raised-cosine edges half an octave wide), times a **centre** weight. With side
//!    spectrum `S = (L − R) / 2`, the per-bin index `c = (|M|² − |S|²) / (|M|² + |S|²)`
//!    equals `2·Re(L·R̄) / (|L|² + |R|²)` (Avendano & Jot 2002 style similarity): 1 for a
//!    bin that is identical in both channels, `2g/(1+g²)` for a source whose channel gains
//!    differ by the ratio `g`, ≤ 0 for anti-phase. The weight rises smoothly from 0 for
//!    sources panned `centre_zero_db` off-centre to 1 within `centre_full_db`. Mono input
//!    has `S = 0`, so vocals degrade to the harmonic mid band.
//! 4. **Other** = everything else (`1 −` the three masks above).
//!
//! **What each stem needs.** Only requested stems are inverse-transformed. The side
//! channel is analysed only when vocals or other are requested. HPSS runs only over the
//! bins the requested stems can occupy: bass alone needs the bins below the crossover's
//! top (+ the frequency median's half-width), vocals the bins below the vocal band's top;
//! drums and other need all bins. The output of a stem does not depend on which other
//! stems were requested.
//!
//! **Defaults** ([`SpectralConfig::default`]): `n_fft` 2048, hop 1024, time median over
//! 5 past + 2 look-ahead frames (8 frames, 186 ms at 44.1 kHz; the bass median 8 + 2),
//! frequency median over
//! 17 bins (±8), bass crossover 250 Hz, vocal band 120–5000 Hz, centre 3 dB / 10 dB.
//! Hop 1024 (50 % overlap) instead of 512 halves the cost; on the synthetic mix below it
//! moves the SDRs by at most 0.2 dB (drums 0.62 → 0.55, bass 6.96 → 6.77, vocals 9.07 →
//! 9.12, other 2.18 → 2.19 dB with hop 512 / 10 + 4 frames → hop 1024 / 5 + 2 frames).
//!
//! **Latency** = `n_fft − 1 + lookahead_frames · hop` samples (the STFT round trip plus
//! the look-ahead): 2047 + 2 · 1024 = 4095 samples = 92.9 ms by default at 44.1 kHz.
//!
//! **Measured** (synthetic 8 s stereo mix of `tests/quality.rs`, plain SDR): drums 0.6, bass
//! 6.8, vocals 9.1, other 2.2 dB, i.e. 8.2 / 5.8 / 14.5 / 13.1 dB better than using the mix
//! itself. The weak spot is drums: kick thumps are long low sines, which the time median calls
//! harmonic, so they leak into bass. Speed (`crates/tactus-separate/benches/separate.rs`, 2
//! shared cores, idle): about 180× real time for all four stems, about 1900× for bass alone.
//!
//! **Hygiene**: non-finite input samples become 0, samples below 1e-30 are flushed to 0
//! (`tactus_dsp::sanitize`), and mid/side samples are clamped to ±1e9 so the output is
//! always finite.
//!
//! **Allocation**: none after construction in `process` / `finish`, provided the caller
//! reserved room in the [`StemOutput`] (input length + latency per stem).

use realfft::num_complex::Complex;
use tactus_dsp::sanitize::sanitize_sample;
use tactus_dsp::ConfigError;

use crate::lowband::LowBand;
use crate::stft::{OverlapAdd, StftAnalysis, StftConfig};
use crate::{stem_index, SeparateError, Separator, Stem, StemOutput, StemSet};

/// Parameters of the [`SpectralSeparator`]. See the module docs for their meaning.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralConfig {
    /// FFT length in samples (even, ≥ 16).
    pub n_fft: usize,
    /// Hop in samples (`1..=n_fft/2`).
    pub hop: usize,
    /// Frames before the current one in the harmonic (time) median.
    pub past_frames: usize,
    /// Frames after the current one in the harmonic (time) median; adds `hop` latency each.
    pub lookahead_frames: usize,
    /// Frames before the current one in a second, longer time median used for the bass
    /// mask only (`bass = min(harm, harm_long) · crossover`, so a kick's body that the short
    /// median still calls harmonic stays out of the bass). No latency (past frames only);
    /// `<= past_frames` turns it off.
    pub bass_past_frames: usize,
    /// Half-width in bins of the percussive (frequency) median: `2·w + 1` bins.
    pub percussive_half_bins: usize,
    /// Centre of the bass crossover in Hz.
    pub bass_crossover_hz: f32,
    /// The vocal band `(low, high)` in Hz (centres of its raised-cosine edges).
    pub vocal_band_hz: (f32, f32),
    /// Sources panned less than this many dB off-centre are fully "centre".
    pub centre_full_db: f32,
    /// Sources panned more than this many dB off-centre are not "centre" at all.
    pub centre_zero_db: f32,
    /// Move the drum kit's learned share of the lowest bins from the bass mask to the drums
    /// ([`crate::lowband`]). Active only where the model's bin width and look-ahead match
    /// (44.1 kHz, `n_fft` 2048, 2 look-ahead frames: the defaults).
    pub low_band_drums: bool,
}

impl Default for SpectralConfig {
    fn default() -> Self {
        SpectralConfig {
            n_fft: 2048,
            hop: 1024,
            past_frames: 5,
            lookahead_frames: 2,
            bass_past_frames: 8,
            percussive_half_bins: 8,
            bass_crossover_hz: 250.0,
            vocal_band_hz: (120.0, 5000.0),
            centre_full_db: 3.0,
            centre_zero_db: 10.0,
            low_band_drums: true,
        }
    }
}

/// Samples per internal block when converting L/R to mid/side.
const BLOCK: usize = 512;

/// Samples of point-reflected signal appended at the end of the stream: enough that the frame
/// centred on the last sample and the `lookahead_frames` after it see signal, not zeros. Zero
/// padding was a cut that the harmonic/percussive split saw as a broadband hit, so a sound
/// lasting to the end gave the drum stem a burst
/// (`docs/decisions/0010-reflected-end-padding.md`). The synthesis is limited to the real
/// length, so none of the padding's own output leaves.
fn end_padding(cfg: &SpectralConfig) -> usize {
    cfg.n_fft / 2 + cfg.lookahead_frames * cfg.hop
}

/// Slides `tail` (oldest first) to end with `new`.
fn remember(tail: &mut [f32], new: &[f32]) {
    let n = tail.len();
    if new.len() >= n {
        tail.copy_from_slice(&new[new.len() - n..]);
    } else {
        tail.copy_within(new.len().., 0);
        tail[n - new.len()..].copy_from_slice(new);
    }
}

/// Mid and side samples are clamped to ±1e9 (180 dB above full scale): far beyond any
/// real audio, low enough that an FFT sum and its square stay finite in `f32`.
const INPUT_LIMIT: f32 = 1e9;

/// Half the width, in octaves, of the raised-cosine band edges.
const EDGE_HALF_OCTAVES: f32 = 0.25;

/// The spectral separator. See the module docs.
pub struct SpectralSeparator {
    sample_rate: u32,
    stems: StemSet,
    cfg: SpectralConfig,
    analysis: StftAnalysis,
    core: Core,
    mid: Vec<f32>,
    side: Vec<f32>,
    /// The last `tail_mid.len()` mid and side samples (the newest last), for the padding
    /// at the end of the stream.
    tail_mid: Vec<f32>,
    tail_side: Vec<f32>,
}

/// Everything but the analysis, so the analysis callback can borrow it mutably.
struct Core {
    stems: StemSet,
    stereo: bool,
    /// Bins `< hi` get masks; above, every requested stem is zero.
    hi: usize,
    /// Bins `< mag_hi` keep magnitudes (hi + the frequency median's half-width).
    mag_hi: usize,
    half: usize,
    lookahead: usize,
    /// Ring of the last `lookahead + 1` mid spectra.
    mids: Vec<Vec<Complex<f32>>>,
    /// Ring of the last `lookahead + 1` centre weights (stereo only).
    centres: Vec<Vec<f32>>,
    /// Ring of the last `past + lookahead + 1` magnitude frames (`mag_hi` bins each).
    mags: Vec<Vec<f32>>,
    /// Per bin `< hi`: the ring's values at that bin, kept sorted (`ring` values each), so
    /// the time median is one look-up and each new frame costs one sorted replacement.
    sorted: Vec<f32>,
    /// Sliding sorted window for the frequency median (capacity `2·half + 1`).
    fwin: Vec<f32>,
    /// Bins `< bass_hi` also keep the longer bass median (0 when it is off).
    bass_hi: usize,
    /// Ring of the last `bass_past + lookahead + 1` magnitude frames (`bass_hi` bins each).
    bass_mags: Vec<Vec<f32>>,
    /// Per bin `< bass_hi`: that ring's values, sorted.
    bass_sorted: Vec<f32>,
    bass_w: Vec<f32>,
    vocal_w: Vec<f32>,
    c_lo: f32,
    c_hi: f32,
    /// Per stem (index = `stem_index`): the masked spectrum (empty when not requested).
    stem_spec: [Vec<Complex<f32>>; 4],
    /// The learned low-band drum share ([`crate::lowband`]), when active.
    lowband: Option<LowBand>,
    /// Its output for the frame being synthesised.
    share: Vec<f32>,
    /// Synthesis channel -> stem.
    channel_stem: [Stem; 4],
    /// Stem index -> synthesis channel.
    stem_channel: [usize; 4],
    synthesis: OverlapAdd,
}

/// `2g / (1 + g²)` for a gain ratio of `db` decibels: the centre index of such a source.
fn centre_index(db: f32) -> f32 {
    let g = 10f32.powf(-db.abs() / 20.0);
    2.0 * g / (1.0 + g * g)
}

/// Raised-cosine step from 1 (well below `edge_hz`) to 0 (well above), over half an
/// octave centred on `edge_hz` in log frequency.
fn falling_edge(f: f32, edge_hz: f32) -> f32 {
    if f <= 0.0 {
        return 1.0;
    }
    let x = (f / edge_hz).log2();
    if x <= -EDGE_HALF_OCTAVES {
        1.0
    } else if x >= EDGE_HALF_OCTAVES {
        0.0
    } else {
        let t = (x + EDGE_HALF_OCTAVES) / (2.0 * EDGE_HALF_OCTAVES);
        0.5 + 0.5 * (std::f32::consts::PI * t).cos()
    }
}

/// First bin at or above which `falling_edge(bin frequency, edge_hz)` is 0.
fn top_bin(edge_hz: f32, sample_rate: u32, n_fft: usize, bins: usize) -> usize {
    let f_top = edge_hz * EDGE_HALF_OCTAVES.exp2();
    ((f_top * n_fft as f32 / sample_rate as f32).ceil() as usize + 1).min(bins)
}

fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Checks the rate, the stems and `cfg` before anything is built; returns the STFT
/// configuration.
fn validate(
    sample_rate: u32,
    stems: StemSet,
    cfg: &SpectralConfig,
) -> Result<StftConfig, SeparateError> {
    if sample_rate < 1000 {
        return Err(SeparateError::SampleRate(sample_rate));
    }
    if stems.is_empty() {
        return Err(SeparateError::NoStems);
    }
    if cfg.n_fft < 16 {
        return Err(ConfigError::invalid("n_fft", "must be at least 16").into());
    }
    let stft = StftConfig {
        n_fft: cfg.n_fft,
        hop: cfg.hop,
    };
    stft.validate()?;
    let nyquist = sample_rate as f32 / 2.0;
    let finite_pos = |x: f32| x.is_finite() && x > 0.0;
    if !finite_pos(cfg.bass_crossover_hz) || cfg.bass_crossover_hz >= nyquist {
        return Err(ConfigError::invalid("bass_crossover_hz", "must be in (0, Nyquist)").into());
    }
    let (v_lo, v_hi) = cfg.vocal_band_hz;
    if !finite_pos(v_lo) || !finite_pos(v_hi) || v_lo >= v_hi {
        return Err(ConfigError::invalid("vocal_band_hz", "must be 0 < low < high").into());
    }
    let (full, none_db) = (cfg.centre_full_db, cfg.centre_zero_db);
    if !(full.is_finite() && none_db.is_finite() && full >= 0.0 && none_db > full) {
        return Err(
            ConfigError::invalid("centre_zero_db", "must exceed centre_full_db >= 0").into(),
        );
    }
    if cfg.past_frames + cfg.lookahead_frames > 256
        || cfg.bass_past_frames + cfg.lookahead_frames > 256
        || cfg.percussive_half_bins > 256
    {
        return Err(
            ConfigError::invalid("median", "windows are limited to 256 frames / bins").into(),
        );
    }
    Ok(stft)
}

impl SpectralSeparator {
    /// A spectral separator at `sample_rate` Hz that outputs `stems`.
    pub fn new(
        sample_rate: u32,
        stems: StemSet,
        cfg: SpectralConfig,
    ) -> Result<Self, SeparateError> {
        let stft = validate(sample_rate, stems, &cfg)?;
        let (v_lo, v_hi) = cfg.vocal_band_hz;
        let (full, none_db) = (cfg.centre_full_db, cfg.centre_zero_db);
        let bins = stft.bins();
        let needs_all = stems.contains(Stem::Drums) || stems.contains(Stem::Other);
        let stereo = stems.contains(Stem::Vocals) || stems.contains(Stem::Other);
        let mut hi = 0;
        if stems.contains(Stem::Bass) {
            hi = hi.max(top_bin(cfg.bass_crossover_hz, sample_rate, cfg.n_fft, bins));
        }
        if stems.contains(Stem::Vocals) {
            hi = hi.max(top_bin(v_hi, sample_rate, cfg.n_fft, bins));
        }
        if needs_all {
            hi = bins;
        }
        let half = cfg.percussive_half_bins;
        let mag_hi = (hi + half).min(bins);
        let bin_hz = |k: usize| k as f32 * sample_rate as f32 / cfg.n_fft as f32;
        let bass_w: Vec<f32> = (0..bins)
            .map(|k| falling_edge(bin_hz(k), cfg.bass_crossover_hz))
            .collect();
        let vocal_w: Vec<f32> = (0..bins)
            .map(|k| {
                let f = bin_hz(k);
                (1.0 - falling_edge(f, v_lo)) * falling_edge(f, v_hi)
            })
            .collect();

        let ring = cfg.past_frames + cfg.lookahead_frames + 1;
        // The bass mask also shapes vocals and other (they share what bass leaves), so the
        // long median runs whenever it is on, whichever stems were requested.
        let (bass_hi, bass_ring) = if cfg.bass_past_frames > cfg.past_frames {
            (
                top_bin(cfg.bass_crossover_hz, sample_rate, cfg.n_fft, bins).min(hi),
                cfg.bass_past_frames + cfg.lookahead_frames + 1,
            )
        } else {
            (0, 0)
        };
        let lowband =
            if cfg.low_band_drums && (stems.contains(Stem::Bass) || stems.contains(Stem::Drums)) {
                LowBand::new(sample_rate, cfg.n_fft, cfg.hop)
                    .filter(|lb| lb.future() == cfg.lookahead_frames && lb.out_bins() <= hi)
            } else {
                None
            };
        let share = vec![0.0; lowband.as_ref().map_or(0, |lb| lb.out_bins())];
        let zero = Complex::new(0.0, 0.0);
        let mut channel_stem = [Stem::Drums; 4];
        let mut stem_channel = [usize::MAX; 4];
        for (ch, s) in stems.iter().enumerate() {
            channel_stem[ch] = s;
            stem_channel[stem_index(s)] = ch;
        }
        let spec_for = |s: Stem| {
            if stems.contains(s) {
                vec![zero; bins]
            } else {
                Vec::new()
            }
        };
        let core = Core {
            stems,
            stereo,
            hi,
            mag_hi,
            half,
            lookahead: cfg.lookahead_frames,
            mids: vec![vec![zero; bins]; cfg.lookahead_frames + 1],
            centres: if stereo {
                vec![vec![1.0; bins]; cfg.lookahead_frames + 1]
            } else {
                Vec::new()
            },
            mags: vec![vec![0.0; mag_hi]; ring],
            bass_w,
            vocal_w,
            c_lo: centre_index(none_db),
            c_hi: centre_index(full),
            sorted: vec![0.0; hi * ring],
            fwin: vec![0.0; 2 * half + 1],
            bass_hi,
            bass_mags: vec![vec![0.0; bass_hi]; bass_ring],
            bass_sorted: vec![0.0; bass_hi * bass_ring],
            stem_spec: [
                spec_for(Stem::Drums),
                spec_for(Stem::Bass),
                spec_for(Stem::Vocals),
                spec_for(Stem::Other),
            ],
            lowband,
            share,
            channel_stem,
            stem_channel,
            synthesis: OverlapAdd::new(stft, stems.len())?,
        };
        Ok(SpectralSeparator {
            sample_rate,
            stems,
            analysis: StftAnalysis::new(stft, if stereo { 2 } else { 1 })?,
            core,
            mid: vec![0.0; BLOCK],
            side: vec![0.0; BLOCK],
            tail_mid: vec![0.0; end_padding(&cfg)],
            tail_side: vec![0.0; end_padding(&cfg)],
            cfg,
        })
    }

    /// Feeds `mid[..m]` (and `side[..m]` in stereo) to the analysis.
    fn push_block(&mut self, m: usize, out: &mut StemOutput) {
        let core = &mut self.core;
        let channels: [&[f32]; 2] = [&self.mid[..m], &self.side[..m]];
        let channels = if core.stereo {
            &channels[..]
        } else {
            &channels[..1]
        };
        self.analysis
            .push(channels, |t, spectra| core.on_frame(t, spectra, out));
    }

    /// The configuration it was built with.
    pub fn config(&self) -> &SpectralConfig {
        &self.cfg
    }
}

impl Core {
    /// Stores analysed frame `t` and synthesises frame `t - lookahead` when it exists.
    fn on_frame(&mut self, t: usize, spectra: &[Vec<Complex<f32>>], out: &mut StemOutput) {
        let slot = t % (self.lookahead + 1);
        let mid = &spectra[0];
        self.mids[slot].copy_from_slice(mid);
        self.store_mags(t, Some(mid));
        if let Some(lb) = &mut self.lowband {
            lb.push(Some(mid));
        }
        if self.stereo {
            let side = &spectra[1];
            let (c_lo, span) = (self.c_lo, self.c_hi - self.c_lo);
            for ((w, m), s) in self.centres[slot][..self.hi].iter_mut().zip(mid).zip(side) {
                let (pm, ps) = (m.norm_sqr(), s.norm_sqr());
                let c = if pm + ps > 1e-30 {
                    (pm - ps) / (pm + ps)
                } else {
                    1.0
                };
                *w = smoothstep((c - c_lo) / span);
            }
        }
        if t >= self.lookahead {
            self.synthesise(t - self.lookahead, out);
        }
    }

    /// A silent frame `t` after the end of the stream (completes the look-ahead).
    fn on_virtual_frame(&mut self, t: usize, out: &mut StemOutput) {
        self.store_mags(t, None);
        if let Some(lb) = &mut self.lowband {
            lb.push(None);
        }
        if t >= self.lookahead {
            self.synthesise(t - self.lookahead, out);
        }
    }

    /// Writes the magnitudes of frame `t` (silence for `None`) into the ring, keeping the
    /// per-bin sorted windows in step.
    fn store_mags(&mut self, t: usize, spectrum: Option<&[Complex<f32>]>) {
        let ring = self.mags.len();
        let frame = &mut self.mags[t % ring];
        for (k, m) in frame.iter_mut().enumerate() {
            // `sqrt(re² + im²)` rather than `hypot`: magnitudes are clamped far below
            // overflow, and libm's hypot costs several times more.
            let new = spectrum.map_or(0.0, |x| x[k].norm_sqr().sqrt());
            if k < self.hi {
                replace_sorted(&mut self.sorted[k * ring..(k + 1) * ring], *m, new);
            }
            *m = new;
        }
        if self.bass_hi > 0 {
            let ring = self.bass_mags.len();
            let frame = &mut self.bass_mags[t % ring];
            for (k, m) in frame.iter_mut().enumerate() {
                let new = spectrum.map_or(0.0, |x| x[k].norm_sqr().sqrt());
                replace_sorted(&mut self.bass_sorted[k * ring..(k + 1) * ring], *m, new);
                *m = new;
            }
        }
    }

    fn synthesise(&mut self, ts: usize, out: &mut StemOutput) {
        let slot = ts % (self.lookahead + 1);
        let ring = self.mags.len();
        let cur = ts % ring;
        let want = |s: Stem| self.stems.contains(s);
        let (w_drums, w_bass, w_vocals, w_other) = (
            want(Stem::Drums),
            want(Stem::Bass),
            want(Stem::Vocals),
            want(Stem::Other),
        );
        if let Some(lb) = &mut self.lowband {
            lb.drum_share(&mut self.share);
        }
        let n_share = self.share.len();
        let [sd, sb, sv, so] = &mut self.stem_spec;
        let mid = &self.mids[slot];
        let frame = &self.mags[cur];
        // Frequency window of bin 0: [0, min(mag_hi, half + 1)).
        let mut flen = 0;
        for &v in &frame[..(self.half + 1).min(self.mag_hi)] {
            insert_sorted(&mut self.fwin, &mut flen, v);
        }
        for k in 0..self.hi {
            if k > 0 {
                // Slide the window from bin k-1 to bin k (clipped at the edges).
                if k > self.half {
                    remove_sorted(&mut self.fwin, &mut flen, frame[k - 1 - self.half]);
                }
                if k + self.half < self.mag_hi {
                    insert_sorted(&mut self.fwin, &mut flen, frame[k + self.half]);
                }
            }
            // Harmonic: median over time (the ring holds exactly frames
            // ts-past..=ts+lookahead); percussive: median over frequency.
            let h = self.sorted[k * ring + ring / 2];
            let p = self.fwin[flen / 2];
            let (h2, p2) = (h * h, p * p);
            let den = h2 + p2;
            let perc = if den > 1e-30 { p2 / den } else { 0.0 };
            let harm = 1.0 - perc;
            let bass_harm = if k < self.bass_hi {
                let ring = self.bass_mags.len();
                let hl = self.bass_sorted[k * ring + ring / 2];
                let den = hl * hl + p2;
                harm.min(if den > 1e-30 { hl * hl / den } else { 1.0 })
            } else {
                harm
            };
            let bass_all = bass_harm * self.bass_w[k];
            let rest = harm - bass_all;
            // The drum kit's learned share of the lowest bins goes from bass to drums.
            let moved = if k < n_share {
                bass_all * self.share[k]
            } else {
                0.0
            };
            let bass = bass_all - moved;
            let perc = perc + moved;
            let centre = if self.stereo {
                self.centres[slot][k]
            } else {
                1.0
            };
            let vocals = rest * self.vocal_w[k] * centre;
            let other = rest - vocals;
            let x = mid[k];
            if w_drums {
                sd[k] = x * perc;
            }
            if w_bass {
                sb[k] = x * bass;
            }
            if w_vocals {
                sv[k] = x * vocals;
            }
            if w_other {
                so[k] = x * other;
            }
        }
        for s in Stem::ALL {
            let i = stem_index(s);
            if self.stems.contains(s) {
                let spec = &mut self.stem_spec[i];
                spec[self.hi..].fill(Complex::new(0.0, 0.0));
                self.synthesis.add(self.stem_channel[i], spec);
            }
        }
        let channel_stem = self.channel_stem;
        self.synthesis
            .advance(|ch, samples| out.extend(channel_stem[ch], samples));
    }

    fn reset(&mut self) {
        let zero = Complex::new(0.0, 0.0);
        for m in &mut self.mids {
            m.fill(zero);
        }
        for c in &mut self.centres {
            c.fill(1.0);
        }
        for m in &mut self.mags {
            m.fill(0.0);
        }
        self.sorted.fill(0.0);
        for m in &mut self.bass_mags {
            m.fill(0.0);
        }
        self.bass_sorted.fill(0.0);
        if let Some(lb) = &mut self.lowband {
            lb.reset();
        }
        self.synthesis.reset();
    }
}

/// In the sorted slice `w`, replaces one element equal to `old` by `new`, keeping it sorted.
/// Values are finite and non-negative magnitudes; `old` must be present (if it is not, the
/// nearest larger element is replaced, and the slice still stays sorted).
fn replace_sorted(w: &mut [f32], old: f32, new: f32) {
    let mut i = w.partition_point(|&x| x < old).min(w.len() - 1);
    if new > w[i] {
        while i + 1 < w.len() && w[i + 1] < new {
            w[i] = w[i + 1];
            i += 1;
        }
    } else {
        while i > 0 && w[i - 1] > new {
            w[i] = w[i - 1];
            i -= 1;
        }
    }
    w[i] = new;
}

/// Inserts `v` into the sorted prefix `w[..*len]` (the caller guarantees room).
fn insert_sorted(w: &mut [f32], len: &mut usize, v: f32) {
    // Shift by hand: the window holds a few dozen values, where a loop beats a call to
    // memmove.
    let mut j = *len;
    while j > 0 && w[j - 1] > v {
        w[j] = w[j - 1];
        j -= 1;
    }
    w[j] = v;
    *len += 1;
}

/// Removes one element equal to `v` from the sorted prefix `w[..*len]` (it is present).
fn remove_sorted(w: &mut [f32], len: &mut usize, v: f32) {
    let i = w[..*len].partition_point(|&x| x < v).min(*len - 1);
    for j in i..*len - 1 {
        w[j] = w[j + 1];
    }
    *len -= 1;
}

impl Separator for SpectralSeparator {
    fn name(&self) -> &'static str {
        "spectral"
    }

    fn sample_rate(&self) -> u32 {
        self.sample_rate
    }

    fn stems(&self) -> StemSet {
        self.stems
    }

    fn process(&mut self, left: &[f32], right: &[f32], out: &mut StemOutput) {
        out.declare(self.stems);
        for (bl, br) in crate::stereo_blocks(left, right, BLOCK) {
            let m = bl.len();
            for (i, (&l, &r)) in bl.iter().zip(br).enumerate() {
                let (l, r) = (sanitize_sample(l).0, sanitize_sample(r).0);
                // Halve first so that two large samples cannot overflow; clamp so that
                // FFT sums and squared magnitudes stay finite.
                self.mid[i] = (0.5 * l + 0.5 * r).clamp(-INPUT_LIMIT, INPUT_LIMIT);
                self.side[i] = (0.5 * l - 0.5 * r).clamp(-INPUT_LIMIT, INPUT_LIMIT);
            }
            remember(&mut self.tail_mid, &self.mid[..m]);
            remember(&mut self.tail_side, &self.side[..m]);
            self.push_block(m, out);
        }
    }

    fn finish(&mut self, out: &mut StemOutput) {
        out.declare(self.stems);
        // Continue the signal past its end by point reflection about the last sample
        // (value and slope stay continuous; a DC offset stays constant), see `end_padding`.
        let real = self.analysis.samples_seen();
        self.core.synthesis.limit_output(real);
        let n = self.tail_mid.len();
        let pad = n.saturating_sub(1).min(real.saturating_sub(1));
        let mut k = 0;
        while k < pad {
            let m = (pad - k).min(BLOCK);
            for i in 0..m {
                let j = n - 2 - (k + i);
                let (em, es) = (self.tail_mid[n - 1], self.tail_side[n - 1]);
                self.mid[i] = (2.0 * em - self.tail_mid[j]).clamp(-INPUT_LIMIT, INPUT_LIMIT);
                self.side[i] = (2.0 * es - self.tail_side[j]).clamp(-INPUT_LIMIT, INPUT_LIMIT);
            }
            self.push_block(m, out);
            k += m;
        }
        let core = &mut self.core;
        self.analysis
            .finish(|t, spectra| core.on_frame(t, spectra, out));
        let frames = self.analysis.frames_emitted();
        for t in frames..frames + core.lookahead {
            core.on_virtual_frame(t, out);
        }
        let channel_stem = core.channel_stem;
        core.synthesis
            .finish(real, |ch, samples| out.extend(channel_stem[ch], samples));
    }

    fn reset(&mut self) {
        self.analysis.reset();
        self.core.reset();
        self.tail_mid.fill(0.0);
        self.tail_side.fill(0.0);
    }

    fn latency_samples(&self) -> usize {
        self.cfg.n_fft - 1 + self.cfg.lookahead_frames * self.cfg.hop
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_are_smooth_and_complementary() {
        assert_eq!(falling_edge(100.0, 250.0), 1.0);
        assert_eq!(falling_edge(400.0, 250.0), 0.0);
        assert!((falling_edge(250.0, 250.0) - 0.5).abs() < 1e-6);
        // 3 dB off-centre -> full weight, 10 dB -> none, centre -> 1.
        assert!((centre_index(0.0) - 1.0).abs() < 1e-6);
        assert!((centre_index(10.0) - 0.5750).abs() < 1e-3);
    }

    /// The incremental medians against sorting from scratch, on random windows.
    #[test]
    fn sorted_windows_match_a_full_sort() {
        let mut state = 9u64;
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            // Few distinct values, so duplicates are exercised.
            ((state >> 59) as f32) * 0.5
        };
        let r = 7;
        let mut ring = vec![0.0f32; r];
        let mut sorted = vec![0.0f32; r];
        for t in 0..500 {
            let v = rnd();
            replace_sorted(&mut sorted, ring[t % r], v);
            ring[t % r] = v;
            let mut oracle = ring.clone();
            oracle.sort_by(f32::total_cmp);
            assert_eq!(sorted, oracle, "t {t}");
        }
        let frame: Vec<f32> = (0..40).map(|_| rnd()).collect();
        let (half, hi) = (3usize, 40usize);
        let mut w = vec![0.0f32; 2 * half + 1];
        let mut len = 0;
        for &v in &frame[..half + 1] {
            insert_sorted(&mut w, &mut len, v);
        }
        for k in 0..hi {
            if k > 0 {
                if k > half {
                    remove_sorted(&mut w, &mut len, frame[k - 1 - half]);
                }
                if k + half < hi {
                    insert_sorted(&mut w, &mut len, frame[k + half]);
                }
            }
            let mut oracle = frame[k.saturating_sub(half)..(k + half + 1).min(hi)].to_vec();
            oracle.sort_by(f32::total_cmp);
            assert_eq!(&w[..len], &oracle[..], "bin {k}");
        }
    }

    #[test]
    fn top_bin_is_where_the_edge_reaches_zero() {
        let (sr, n) = (44_100, 2048);
        let k = top_bin(250.0, sr, n, 1025);
        let f = |k: usize| k as f32 * sr as f32 / n as f32;
        assert_eq!(falling_edge(f(k), 250.0), 0.0);
        assert_eq!(falling_edge(f(k - 1), 250.0), 0.0);
        assert!(falling_edge(f(k - 2), 250.0) > 0.0 || falling_edge(f(k - 3), 250.0) > 0.0);
    }
}
