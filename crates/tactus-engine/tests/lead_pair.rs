//! The mix's lead under the learned method
//! (`docs/decisions/0027-learned-lead-pitch-inside-harmonic-sum-voicing.md`,
//! `docs/decisions/0028-learned-lead-voicing-veto.md`): a voicing/pitch pair voiced only where
//! the harmonic-sum melody tracker is (the learned tracker may veto), whose pitch is the
//! learned lead salience's where both are voiced, and whose note onsets read that pitch
//! (`docs/decisions/0034-mix-lead-note-onsets-from-the-pair.md`), offline and streaming, for
//! any chunking. Its level range comes from held notes or hops both trackers agree on
//! (`docs/decisions/0029-mix-lead-range-from-held-or-agreed-hops.md`), offline narrowed to
//! the hops where the learned tracker is sure of its pitch
//! (`docs/decisions/0038-mix-lead-range-narrowed-to-sure-hops.md`), against `tactus_dsp`'s
//! range functions replayed on the track's two pitches and its confidence.

use tactus_dsp::discretize::{
    agree_mask, narrow_range, pitches_agree, range_quantiles_kept_or, range_quantiles_kept_or_sure,
    Discretizer, HeldRange, RangePrior,
};
use tactus_dsp::Stem;
use tactus_engine::notes::{NoteRole, PitchNotes};
use tactus_engine::profile::Profile;
use tactus_engine::recipe::{recipe, Recipe, Role, SeparatorKind, Source};
use tactus_engine::track::PitchTrack;
use tactus_engine::{Mode, NoteRule, PitchMethod};

mod common;
use common::SR;

/// A lead over a chord pad: a sung-like line (harmonics with a formant-ish tilt, vibrato,
/// rests) of 0.25–0.5 s notes over sustained chord tones a sixth and an octave below.
fn lead_over_chords() -> Vec<f32> {
    synth_over_chords(&[
        (64.0, 0.4),
        (67.0, 0.3),
        (69.0, 0.5),
        (0.0, 0.2),
        (72.0, 0.3),
        (71.0, 0.25),
        (67.0, 0.5),
        (0.0, 0.3),
        (62.0, 0.4),
        (64.0, 0.4),
    ])
}

/// The same line with eighths (0.12 s, 12 hops) as its highest and lowest notes: too short
/// to be held for 8 hops on each side.
fn lead_with_short_extremes() -> Vec<f32> {
    synth_over_chords(&[
        (64.0, 0.4),
        (67.0, 0.3),
        (76.0, 0.12),
        (69.0, 0.5),
        (0.0, 0.2),
        (72.0, 0.3),
        (60.0, 0.12),
        (67.0, 0.5),
        (0.0, 0.3),
        (62.0, 0.4),
        (64.0, 0.4),
    ])
}

/// The line of [`lead_over_chords`] without its rests, three times, and in the two breaks
/// between the passes (1 s each) the lead rests while a dyad (D3 + A3, eight harmonics)
/// sounds over the pad: the pair holds a pitch near B3 there, two and a half semitones
/// under the lead's lowest note, of which the learned tracker is unsure.
fn lead_with_a_dyad_in_its_rests() -> Vec<f32> {
    let notes = [
        (64.0, 0.4),
        (67.0, 0.3),
        (69.0, 0.5),
        (72.0, 0.3),
        (71.0, 0.25),
        (67.0, 0.5),
        (62.0, 0.4),
        (64.0, 0.4),
    ];
    let sr = SR as f64;
    let (mut x, mut ph, mut t) = (Vec::new(), 0.0f64, 0.0f64);
    let pad = |t: f64| -> f64 {
        [220.0, 261.6]
            .iter()
            .map(|pf| 0.03 * (std::f64::consts::TAU * pf * t).sin())
            .sum()
    };
    for pass in 0..3 {
        for &(st, dur) in &notes {
            let f = 440.0 * ((st - 69.0) / 12.0f64).exp2();
            for i in 0..(dur * sr) as usize {
                let vib = 1.0 + 0.004 * (std::f64::consts::TAU * 5.5 * i as f64 / sr).sin();
                ph += std::f64::consts::TAU * f * vib / sr;
                let s: f64 = (1..=8)
                    .map(|h| 0.08 / h as f64 * (h as f64 * ph).sin())
                    .sum();
                x.push((s + pad(t)) as f32);
                t += 1.0 / sr;
            }
        }
        if pass < 2 {
            for _ in 0..sr as usize {
                let mut s = pad(t);
                for m in [50.0f64, 57.0] {
                    let f = 440.0 * ((m - 69.0) / 12.0f64).exp2();
                    for h in 1..=8 {
                        s += 0.08 / h as f64 * (std::f64::consts::TAU * f * h as f64 * t).sin();
                    }
                }
                x.push(s as f32);
                t += 1.0 / sr;
            }
        }
    }
    x
}

/// Three passes of `notes` (MIDI, seconds; 0 = rest) over the pad.
fn synth_over_chords(notes: &[(f64, f64)]) -> Vec<f32> {
    let sr = SR as f64;
    let mut x = Vec::new();
    let mut ph = 0.0f64;
    let mut t = 0.0f64;
    for _ in 0..3 {
        for &(st, dur) in notes {
            let n = (dur * sr) as usize;
            let f = 440.0 * ((st - 69.0) / 12.0f64).exp2();
            for i in 0..n {
                let vib = 1.0 + 0.004 * (std::f64::consts::TAU * 5.5 * i as f64 / sr).sin();
                let mut s = 0.0;
                if st > 0.0 {
                    ph += std::f64::consts::TAU * f * vib / sr;
                    for h in 1..=8 {
                        s += 0.08 / h as f64 * (h as f64 * ph).sin();
                    }
                }
                // The pad: A3 and C4, always on.
                for pf in [220.0, 261.6] {
                    s += 0.03 * (std::f64::consts::TAU * pf * t).sin();
                }
                t += 1.0 / sr;
                x.push(s as f32);
            }
        }
    }
    x
}

/// The lead's track with `method` (without the plain guard, whose YIN may take a hop of
/// the pair: these tests are about the pair) over `x`, fed in `chunk`s.
fn track(method: PitchMethod, mode: Mode, x: &[f32], chunk: usize) -> (PitchTrack, Vec<bool>) {
    let (lo, hi) = tactus_dsp::Stem::Vocals.pitch_range_hz().unwrap();
    let geo = common::geo(mode, Profile::Full);
    let mut t = common::pitch_track_unguarded(geo, Role::Lead, true, method, (lo, hi));
    let mut notes = PitchNotes::new(geo, &t, NoteRule::Attack, NoteRole::default()).unwrap();
    for b in x.chunks(chunk) {
        t.process(b);
        notes.update(&t);
    }
    t.finish();
    notes.update(&t);
    notes.finish(&t);
    (t, notes.beats.onsets.clone())
}

#[test]
fn the_mix_leads_pair_keeps_the_harmonic_sums_own_pitch_beside_its_own_and_may_only_unvoice() {
    let x = lead_over_chords();
    for mode in [Mode::Offline, Mode::Streaming] {
        let (shs, _) = track(PitchMethod::Shs, mode, &x, 4096);
        let (pair, pair_onsets) = track(PitchMethod::Learned, mode, &x, 4096);
        assert_eq!(pair.f0.len(), shs.f0.len());
        assert_eq!(pair.voicing_f0().len(), shs.f0.len());
        // The voicing tracker's pitch is the harmonic sum's (the fences, which read each stream's own
        // values, may drop a hop in one stream and not the other); the veto only unvoices.
        let (mut vetoed, mut differ, mut fenced) = (0, 0, 0);
        for (i, ((&n, &p), &s)) in pair
            .voicing_f0()
            .iter()
            .zip(&pair.f0)
            .zip(&shs.f0)
            .enumerate()
        {
            if n > 0.0 && s > 0.0 {
                assert_eq!(n.to_bits(), s.to_bits(), "{mode:?} hop {i}: voicing pitch");
            }
            fenced += usize::from((n > 0.0) != (p > 0.0));
            if p > 0.0 && s > 0.0 && (p / s - 1.0).abs() > 0.01 {
                differ += 1;
            }
            vetoed += usize::from(s > 0.0 && p == 0.0);
        }
        // Offline keeps the trackers' raw output: voiced only where the harmonic sum is.
        if mode == Mode::Offline {
            for (i, (&p, &s)) in pair.raw_f0.iter().zip(&shs.raw_f0).enumerate() {
                assert!(
                    !(p > 0.0 && s <= 0.0),
                    "hop {i}: voiced where the harmonic sum is not"
                );
            }
        }
        let voiced = shs.f0.iter().filter(|&&f| f > 0.0).count();
        assert!(differ > 0, "{mode:?}: the learned pitch is used");
        assert!(
            fenced * 50 < voiced,
            "{mode:?}: {fenced} hops voiced in one stream only"
        );
        assert!(
            vetoed * 10 < voiced,
            "{mode:?}: {vetoed} of {voiced} voiced hops vetoed"
        );
        // Note onsets read the pair's pitch: the detector run by hand over the pair's
        // pitch and levels (the offline function; streaming pushes the same hops one by
        // one) gives them exactly, and over the harmonic sum's own pitch it would not.
        let cfg = NoteRule::Attack.config(Profile::Full, NoteRole::default());
        let want =
            tactus_dsp::notes::note_onsets_offline_level(&pair.f0, &pair.level_db, cfg).unwrap();
        assert_eq!(pair_onsets, want, "{mode:?}: onsets of the pair's pitch");
        let other =
            tactus_dsp::notes::note_onsets_offline_level(pair.voicing_f0(), &pair.level_db, cfg)
                .unwrap();
        assert_ne!(
            other, want,
            "{mode:?}: the two pitches give other onsets here"
        );
        assert!(
            want.iter().filter(|&&o| o).count() >= 10,
            "{mode:?}: notes found"
        );
        if mode == Mode::Streaming {
            for chunk in [1, 441, 10_000] {
                let (c, o) = track(PitchMethod::Learned, mode, &x, chunk);
                assert_eq!(c.f0, pair.f0, "chunk {chunk}");
                assert_eq!(c.voicing_f0(), pair.voicing_f0(), "chunk {chunk}");
                assert_eq!(o, pair_onsets, "chunk {chunk}");
                assert_eq!(c.bins, pair.bins, "chunk {chunk}");
            }
        }
    }
}

#[test]
fn the_mix_leads_range_comes_from_held_or_agreed_hops_offline_and_streaming() {
    let x = lead_with_short_extremes();
    let d = Discretizer::default();
    let (t, _) = track(PitchMethod::Learned, Mode::Offline, &x, 4096);
    let trusted = agree_mask(&t.f0, t.voicing_f0(), common::tuning().agree_tol_st);
    let agreed = trusted.iter().filter(|&&a| a).count();
    let voiced = t.f0.iter().filter(|&&f| f > 0.0).count();
    assert!(
        agreed * 2 > voiced,
        "{agreed} of {voiced} voiced hops agreed"
    );
    let range = range_quantiles_kept_or(
        &t.f0,
        &trusted,
        common::tuning().follow_range_quantile,
        common::tuning().mix_lead_held_hops,
        common::tuning().held_tol_st,
        0,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    // Offline, narrowed to a semitone beyond the sure hops' range.
    let conf = t.pitch_confidence();
    assert_eq!(conf.len(), t.f0.len());
    let sure: Vec<bool> = conf
        .iter()
        .map(|&c| c >= common::tuning().mix_lead_sure)
        .collect();
    let unsure = (0..t.f0.len())
        .filter(|&i| t.f0[i] > 0.0 && !sure[i])
        .count();
    assert!(
        unsure > 0 && unsure * 2 < voiced,
        "{unsure} of {voiced} voiced hops unsure"
    );
    let sure_range = range_quantiles_kept_or_sure(
        &t.f0,
        &trusted,
        &sure,
        common::tuning().mix_lead_sure_quantile,
        common::tuning().mix_lead_held_hops,
        common::tuning().held_tol_st,
        0,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    let narrowed = narrow_range(
        range,
        sure_range,
        common::tuning().mix_lead_sure_margin_st,
        common::tuning().mix_lead_sure_margin_st,
    );
    let want: Vec<u8> =
        t.f0.iter()
            .map(|&f| narrowed.map_or(0, |r| d.level(f, r)))
            .collect();
    assert_eq!(t.hop_levels, want);
    // The rule matters here: held notes alone lose the low eighth (C4), the agreed hops keep
    // it. (The high eighth, a leap of nine semitones in 0.12 s, is not tracked closely enough
    // by both to move the 99th percentile either way.)
    let held = range_quantiles_kept_or(
        &t.f0,
        &[],
        common::tuning().follow_range_quantile,
        common::tuning().mix_lead_held_hops,
        common::tuning().held_tol_st,
        0,
        common::tuning().held_min_share,
        common::tuning().held_min_hops,
    );
    let (a, b) = (range.unwrap(), held.unwrap());
    assert!(
        (a.0 / 261.63 - 1.0).abs() < 0.03 && a.0 < b.0 * 0.95,
        "{a:?} against {b:?}"
    );
    // Streaming, hop by hop: the held range fed each hop's agreement, narrowed to the sure
    // hops' once they hold.
    let (s, _) = track(PitchMethod::Learned, Mode::Streaming, &x, 4096);
    assert_eq!(
        s.hop_levels,
        streaming_levels(&s, t.pitch_confidence(), true)
    );
}

/// The streaming rule replayed by hand on a streaming lead track: the held range of the
/// held or agreed hops and, with `narrow`, the same range of the sure ones (`conf`: the
/// learned tracker's confidence per hop, which the tracker gives alike offline and
/// streaming), once that holds, clipping it to a semitone beyond its ends.
fn streaming_levels(s: &PitchTrack, conf: &[f32], narrow: bool) -> Vec<u8> {
    let range = |p: f32| {
        HeldRange::with_prior(
            RangePrior::Span(common::tuning().lead_prior_span_st),
            common::tuning().follow_prior_fade_hops,
            p,
            common::tuning().mix_lead_held_hops,
            common::tuning().held_tol_st,
            common::tuning().held_min_share,
            common::tuning().held_min_hops,
        )
        .unwrap()
    };
    let (mut r, mut rs) = (
        range(common::tuning().follow_range_quantile),
        range(common::tuning().mix_lead_sure_quantile),
    );
    let d = Discretizer::default();
    assert_eq!(conf.len(), s.f0.len());
    s.f0.iter()
        .zip(s.voicing_f0())
        .zip(conf)
        .map(|((&f, &n), &c)| {
            let trusted = pitches_agree(f, n, common::tuning().agree_tol_st);
            let a = r.update_trusted(f, trusted);
            let b = rs.update_sure(f, trusted, c >= common::tuning().mix_lead_sure);
            let range = if narrow && rs.holds() {
                narrow_range(
                    a,
                    b,
                    common::tuning().mix_lead_sure_margin_st,
                    common::tuning().mix_lead_sure_margin_st,
                )
            } else {
                a
            };
            range.map_or(0, |range| d.level(f, range))
        })
        .collect()
}

#[test]
fn offline_the_mix_leads_range_is_narrowed_to_a_semitone_beyond_its_sure_hops() {
    let x = lead_with_a_dyad_in_its_rests();
    let d = Discretizer::default();
    let (t, _) = track(PitchMethod::Learned, Mode::Offline, &x, 4096);
    let st = |f: f32| 69.0 + 12.0 * (f / 440.0).log2();
    let conf = t.pitch_confidence();
    assert_eq!(conf.len(), t.f0.len());
    // The held pitch in the breaks is under the lead's compass, and the tracker is unsure of
    // it; inside the lead's notes it is sure.
    let (mut low, mut low_unsure, mut lead, mut lead_sure) = (0, 0, 0, 0);
    for (&f, &c) in t.f0.iter().zip(conf) {
        if f <= 0.0 {
            continue;
        }
        if st(f) < 61.0 {
            low += 1;
            low_unsure += usize::from(c < common::tuning().mix_lead_sure);
        } else {
            lead += 1;
            lead_sure += usize::from(c >= common::tuning().mix_lead_sure);
        }
    }
    assert!(
        low >= 100 && low_unsure == low,
        "{low_unsure} of {low} low hops unsure"
    );
    assert!(
        lead_sure * 5 >= lead * 4,
        "{lead_sure} of {lead} lead hops sure"
    );
    let trusted = agree_mask(&t.f0, t.voicing_f0(), common::tuning().agree_tol_st);
    let sure: Vec<bool> = conf
        .iter()
        .map(|&c| c >= common::tuning().mix_lead_sure)
        .collect();
    let kept = |sure: &[bool], p: f32| {
        range_quantiles_kept_or_sure(
            &t.f0,
            &trusted,
            sure,
            p,
            common::tuning().mix_lead_held_hops,
            common::tuning().held_tol_st,
            0,
            common::tuning().held_min_share,
            common::tuning().held_min_hops,
        )
    };
    let range = kept(&[], common::tuning().follow_range_quantile);
    let narrowed = narrow_range(
        range,
        kept(&sure, common::tuning().mix_lead_sure_quantile),
        common::tuning().mix_lead_sure_margin_st,
        common::tuning().mix_lead_sure_margin_st,
    );
    let want: Vec<u8> =
        t.f0.iter()
            .map(|&f| narrowed.map_or(0, |r| d.level(f, r)))
            .collect();
    assert_eq!(t.hop_levels, want);
    // The rule matters here: the held or agreed hops reach down to the break's pitch, the
    // narrowed range stops a semitone under the lead's lowest note (D4, MIDI 62).
    let (a, b) = (range.unwrap(), narrowed.unwrap());
    assert!(st(a.0) < 60.0, "held or agreed from {}", st(a.0));
    assert!((st(b.0) - 61.0).abs() < 0.3, "narrowed from {}", st(b.0));
    assert_eq!(a.1, b.1, "the top is the lead's own");
    // Streaming: the held or agreed range hop by hop, narrowed the same way once the sure
    // hops hold a range; here that matters too. Any chunking gives the same.
    let (s, _) = track(PitchMethod::Learned, Mode::Streaming, &x, 4096);
    let want = streaming_levels(&s, conf, true);
    assert_eq!(s.hop_levels, want);
    assert_ne!(
        want,
        streaming_levels(&s, conf, false),
        "the rule matters streaming"
    );
    for chunk in [441, 10_000] {
        let (c, _) = track(PitchMethod::Learned, Mode::Streaming, &x, chunk);
        assert_eq!(c.hop_levels, want, "chunk {chunk}");
    }
}

/// The lead over its chords with a bass line under them (a root a bar, harmonics of
/// amplitude `harmonics`), 6.6 s, rendered by the default engine (offline). Returns the
/// features' pitch of `stem`, and that stem as its chain receives it beside the
/// separator's harmonic sum (vocals + bass + other), both through the chain's denoiser
/// (`hp_hz`), as the engine runs them.
fn engine_and_views(stem: Stem, hp_hz: f64, harmonics: &[f32]) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    use tactus_engine::track::Denoise;
    use tactus_engine::{Engine, EngineConfig};
    use tactus_separate::spectral::{SpectralConfig, SpectralSeparator};
    use tactus_separate::{Separator, StemOutput, StemSet};
    let x: Vec<f32> = lead_over_chords()
        .iter()
        .enumerate()
        .map(|(i, &s)| {
            let t = i as f32 / SR as f32;
            let f = [55.0f32, 73.4, 65.4, 49.0][(t / 1.1) as usize % 4];
            let ph = std::f32::consts::TAU * f * t;
            let bass: f32 = harmonics
                .iter()
                .enumerate()
                .map(|(h, a)| a * ((h + 1) as f32 * ph).sin())
                .sum();
            s + 0.2 * bass
        })
        .collect();
    let mut e = Engine::new(EngineConfig {
        mode: Mode::Offline,
        ..EngineConfig::default()
    })
    .unwrap();
    e.process(&x, &x, &[]);
    e.finish();
    let got = e.features().pitch_hz[stem.name()].clone();
    let mut sep = SpectralSeparator::new(
        SR,
        StemSet::all(),
        SpectralConfig {
            low_band_drums: EngineConfig::default().kit_mask,
            ..SpectralConfig::default()
        },
    )
    .unwrap();
    // The engine removes DC from the mix first (docs/decisions/0053-dc-at-the-input.md).
    let mut x = x;
    tactus_dsp::SampleStage::process_inplace(
        &mut tactus_dsp::dc::DcBlock::new(SR).unwrap(),
        &mut x,
    );
    let mut out = StemOutput::new();
    sep.process(&x, &x, &mut out);
    sep.finish(&mut out);
    let mut own = out.get(stem).to_vec();
    let (b, v, o) = (
        out.get(Stem::Bass),
        out.get(Stem::Vocals),
        out.get(Stem::Other),
    );
    let mut view: Vec<f32> = b
        .iter()
        .zip(v)
        .zip(o)
        .map(|((b, v), o)| b + v + o)
        .collect();
    Denoise::new(hp_hz, SR).unwrap().process_inplace(&mut own);
    Denoise::new(hp_hz, SR).unwrap().process_inplace(&mut view);
    (got, own, view)
}

/// The pitch of a track built from `recipe` over the whole of `stem` beside `view`.
fn track_with_view(recipe: &Recipe, stem: &[f32], view: &[f32]) -> Vec<f32> {
    let geo = common::geo(Mode::Offline, Profile::Full);
    let mut t = PitchTrack::new(geo, recipe).unwrap();
    t.process_view(stem, view);
    t.finish();
    t.f0
}

/// Hops where two pitch tracks differ in voicing or by more than 1 %.
fn hops_differing(a: &[f32], b: &[f32]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(a, b)| (**a > 0.0) != (**b > 0.0) || (*a / *b - 1.0).abs() > 0.01)
        .count()
}

fn assert_bits_eq(got: &[f32], want: &[f32]) {
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "hop {i}: {g} vs {w}");
    }
}

/// The spectral separator's lead through the engine
/// (`docs/decisions/0037-learned-lead-reads-the-harmonic-sum.md`): the ring finger's pitch is a track of the engine's recipe for it fed by
/// hand with the separator's vocals stem and its harmonic sum (vocals + bass + other), each
/// through the vocals chain's 60 Hz denoiser; the same track fed the stem as its own view
/// reports other pitches.
#[test]
fn the_engines_mix_lead_reads_the_separators_harmonic_sum() {
    let (got, stem, view) = engine_and_views(Stem::Vocals, 60.0, &[1.0]);
    let r = recipe(
        Role::Lead,
        Source::Mix,
        Profile::Full,
        SeparatorKind::Spectral,
        PitchMethod::Auto,
    );
    assert!(r.harmonic_view);
    let want = track_with_view(&r, &stem, &view);
    assert_bits_eq(&got, &want);
    let differ = hops_differing(&track_with_view(&r, &stem, &stem), &want);
    assert!(differ >= 10, "the view changes the pitch: {differ} hops");
}

/// The spectral separator's bass through the engine
/// (`docs/decisions/0042-bass-reads-the-harmonic-sum.md`): the thumb's pitch is a track of the engine's recipe for it (the harmonic-view bass
/// model) fed by hand with the separator's bass stem and its harmonic sum, each through the
/// bass chain's 30 Hz denoiser, bit for bit; the plain learned bass model on the stem
/// (otherwise the same recipe) differs.
#[test]
fn the_engines_mix_bass_reads_the_harmonic_sum() {
    let (got, stem, view) = engine_and_views(Stem::Bass, 30.0, &[1.0, 0.4, 0.2]);
    let spectral = recipe(
        Role::Bass,
        Source::Mix,
        Profile::Full,
        SeparatorKind::Spectral,
        PitchMethod::Auto,
    );
    assert!(spectral.harmonic_view);
    let viewed = track_with_view(&spectral, &stem, &view);
    let plain = Recipe {
        advance_hops: spectral.advance_hops,
        ..recipe(
            Role::Bass,
            Source::Mix,
            Profile::Full,
            SeparatorKind::None,
            PitchMethod::Learned,
        )
    };
    let plain = track_with_view(&plain, &stem, &stem);
    assert_bits_eq(&got, &viewed);
    let differ = hops_differing(&plain, &viewed);
    assert!(differ >= 5, "the view changes the bass: {differ} hops");
}
