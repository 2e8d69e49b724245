#!/usr/bin/env python3
"""Sung-lead corpus: a synthetic singer with exact f0 over a pop backing (issue 16, item 6).

Every other corpus's "vocals" stem is an instrument from a soundfont. Here the lead is sung:
espeak-ng says one syllable per note ("la", "ta", "so", ...), the WORLD vocoder (`pyworld`)
analyses it (spectral envelope, aperiodicity, voicing), the syllable is stretched to the note's
length, and WORLD resynthesises it on **the melody's own f0 contour**: WORLD's analysed f0 is
thrown away, so the f0 in the truth is the f0 that was synthesised, exactly. The contour is
sung, not quantised: portamento between legato notes, scoops into some notes, vibrato
(5-6.5 Hz, 20-60 cents, entering 150-300 ms into a note), a slow drift of a few cents, rests
between phrases. Unvoiced consonants (t, s, k, p, f) are synthesised unvoiced and are
**unvoiced (0) in the truth**; voiced ones (l, m, n, v, r) carry the note's pitch.

The backing (bass, chords, drums, from corpus/drums.py's generators; FluidR3_GM melodic
programs and a FluidR3_GM drum kit) and the stereo mix follow corpus/drums.py: stems at their
RMS times a random gain, one gain so that the mix peaks at -1 dBFS, mix = sum of the stems.

Truth (truth.json, `tactus-truth` v1, see corpus/README.md): f0 per 10 ms hop for vocals (the
sung contour, 0 on rests and unvoiced consonants), bass and other (top line); `note_onsets_s`
(vocals: where each sung note's pitch begins, i.e. the start of its voiced part; a note
sung after an unvoiced consonant starts at its vowel); drum `onsets`/`hits`; `lyrics` (one
syllable per note with its times).

Usage:
    corpus/.venv-sung/bin/python corpus/sung.py --out /work/data/sung [--songs 12] [--seed 16] [--jobs 2]

Needs `apt-get install espeak-ng fluidsynth fluid-soundfont-gm` and a venv with
`pip install pyworld numpy scipy soundfile mido`. Deterministic for a given seed and the same
packages; existing songs are skipped unless --force. Songs with an even index are the tuning
half, odd ones are held out (`held_out` in the truth, and OUT/SPLIT.txt).
"""
from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import pyworld as pw
import soundfile as sf
from scipy.signal import resample_poly

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from generate import HOP_S, SR, f0_track, note_starts, write_midi  # noqa: E402
import drums as D  # noqa: E402

FRAME_MS = 5.0  # WORLD frame period
VOICE_SR = 22050  # espeak-ng's output rate; WORLD runs there, the result is resampled to 44.1 kHz
# (espeak-ng voice, language, register): register "high" sings the backing's lead (C4..A5),
# "low" an octave lower (C3..A4).
VOICES = [
    ("it+f3", "it", "high"), ("en-us+f2", "en", "high"), ("it+m3", "it", "low"), ("en-us+m1", "en", "low"),
    ("es+f4", "es", "high"), ("it+f5", "it", "high"), ("de+m4", "de", "low"), ("es+m2", "es", "low"),
]  # song i sings VOICES[i % 8]: both halves (even / odd i) get two high and two low voices
SYLLABLES = {
    "it": ["la", "na", "ma", "ta", "sa", "ka", "lo", "no", "mi", "ti", "se", "ve", "ri", "pa", "do", "fa"],
    "es": ["la", "na", "ma", "ta", "sa", "ka", "lo", "no", "mi", "ti", "se", "be", "ri", "pa", "do", "fa"],
    "en": ["la", "na", "ma", "ta", "sa", "ka", "lo", "no", "mee", "tee", "say", "vay", "ree", "pa", "doe", "fa"],
    "de": ["la", "na", "ma", "ta", "sa", "ka", "lo", "no", "mi", "ti", "se", "we", "ri", "pa", "do", "fa"],
}
STYLES = ["rock8", "funk16", "halftime", "disco", "shuffle12", "six8", "rock8", "ride", "halftime",
          "disco", "swing", "funk16"]


def midi_hz(m):
    return 440.0 * 2.0 ** ((m - 69.0) / 12.0)


# ---------------------------------------------------------------------------------------
# Syllables: espeak-ng -> WORLD analysis (cached per process)

_CACHE = {}


def syllable(voice, text, tmp):
    """WORLD analysis of one spoken syllable, trimmed to its audible part: dict with sp, ap
    (frames x bins) and `voiced` (bool per frame: DIO + StoneMask found a pitch)."""
    key = (voice, text)
    if key in _CACHE:
        return _CACHE[key]
    wav = os.path.join(tmp, "syl.wav")
    subprocess.run(["espeak-ng", "-v", voice, "-s", "100", "-w", wav, text], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    x, sr = sf.read(wav, dtype="float64")
    if x.ndim > 1:
        x = x.mean(axis=1)
    assert sr == VOICE_SR, sr
    f0, t = pw.dio(x, sr, frame_period=FRAME_MS)
    f0 = pw.stonemask(x, f0, t, sr)
    sp = pw.cheaptrick(x, f0, t, sr)
    ap = pw.d4c(x, f0, t, sr)
    e = 10 * np.log10(sp.sum(axis=1) + 1e-30)
    keep = np.nonzero(e > e.max() - 35.0)[0]
    a, b = int(keep[0]), int(keep[-1]) + 1
    voiced = f0[a:b] > 0
    # one unvoiced frame inside the vowel is DIO's, not a consonant: fill isolated gaps
    first = int(np.argmax(voiced)) if voiced.any() else len(voiced)
    v2 = voiced.copy()
    v2[first:] = True
    last = len(v2)
    # drop a trailing unvoiced breath
    idx = np.nonzero(voiced)[0]
    if len(idx):
        last = int(idx[-1]) + 1
    sp_, ap_ = sp[a:a + last], ap[a:a + last]
    v2 = v2[:last]
    # unit vowel power: the mean power of the voiced frames
    pv = float(np.mean(sp_[v2].sum(axis=1))) if v2.any() else 1.0
    res = {"sp": sp_ / pv, "ap": ap_, "voiced": v2, "n_cons": int(first)}
    _CACHE[key] = res
    return res


def stretch(frames, n):
    """Resamples a (T x bins) frame sequence to n frames by linear interpolation of the index."""
    t = frames.shape[0]
    if n <= 0:
        return frames[:0]
    if t == 1:
        return np.repeat(frames, n, axis=0)
    pos = np.linspace(0, t - 1, n)
    i0 = np.floor(pos).astype(int)
    i1 = np.minimum(i0 + 1, t - 1)
    w = (pos - i0)[:, None]
    return frames[i0] * (1 - w) + frames[i1] * w


# ---------------------------------------------------------------------------------------
# The sung line


def phrase_notes(rng, lead, bpb, end_beat):
    """The backing's lead (start_beat, end_beat, pitch, vel) with phrase rests: the last 1-2
    beats of every 4-bar phrase are silent; notes within a phrase are sung legato when the
    gap to the next is short."""
    phrase = 4 * bpb
    out = []
    for s, e, p, v in lead:
        pos = (s - D.LEAD_IN_BEATS) % phrase
        rest = phrase - (1.0 if bpb == 2 else float(rng.choice([1.0, 2.0])))
        if pos >= rest:
            continue
        e = min(e, s - pos + rest)
        out.append([s, e, p, v])
    for k in range(len(out) - 1):
        if out[k + 1][0] - out[k][1] < 0.35:  # legato: hold until the next note
            out[k][1] = out[k + 1][0]
    return [tuple(x) for x in out if x[1] - x[0] > 0.12]


def sing(rng, notes, bpm, voice, lang, octave, n_out, tmp):
    """Synthesises the sung line. Returns (audio at SR, truth f0 per 5 ms frame, note onsets,
    lyrics)."""
    beat_s = 60.0 / bpm
    fp = FRAME_MS / 1000.0
    n_fr = int(math.ceil(n_out / SR / fp)) + 2
    probe = syllable(voice, "la", tmp)
    bins = probe["sp"].shape[1]
    sp = np.full((n_fr, bins), 1e-16)
    ap = np.ones((n_fr, bins))
    f0 = np.zeros(n_fr)
    vib_rate = rng.uniform(5.0, 6.5)
    vib_depth = rng.uniform(20.0, 60.0)
    drift = np.cumsum(rng.normal(0, 1.0, n_fr))
    drift = np.convolve(drift - np.mean(drift), np.ones(40) / 40, mode="same")
    drift = 8.0 * drift / max(1e-9, float(np.max(np.abs(drift))))
    onsets, lyrics = [], []
    prev_end_fr, prev_hz, prev_on = -10, None, -1
    sylls = SYLLABLES[lang]
    for k, (sb, eb, p, vel) in enumerate(notes):
        text = str(rng.choice(sylls))
        syl = syllable(voice, text, tmp)
        hz = midi_hz(p + 12 * octave)
        t_on = sb * beat_s
        t_off = eb * beat_s
        on = int(round(t_on / fp))
        off = int(round(t_off / fp))
        nc = syl["n_cons"]
        # the consonant may cut into the previous note, never into its first 60 %
        cons_start = max(0, on - nc, prev_on + int(0.6 * (on - prev_on)) if prev_on >= 0 else 0)
        legato = prev_end_fr >= on - 1 and prev_hz is not None
        # unvoiced consonant before the note's time: cut the previous vowel there
        if nc > 0:
            seg = syl["sp"][:nc][-(on - cons_start):] if on > cons_start else syl["sp"][:0]
            sp[cons_start:on] = seg
            ap[cons_start:on] = syl["ap"][:nc][-(on - cons_start):] if on > cons_start else 0
            f0[cons_start:on] = 0.0
            legato = False
        vsp, vap = syl["sp"][nc:], syl["ap"][nc:]
        n = off - on
        head = min(len(vsp) // 3, 12, n // 2)  # consonant-vowel transition kept at its pace
        body_sp = stretch(vsp[head:], n - head)
        if len(body_sp):  # a sung vowel holds its level: flatten the stretched vowel's power
            pw_ = body_sp.sum(axis=1)
            body_sp = body_sp * (np.mean(pw_) / np.maximum(pw_, 1e-30))[:, None]
        body_ap = stretch(vap[head:], n - head)
        g = (vel / 100.0) ** 2
        env = np.ones(n)
        nxt_legato = k + 1 < len(notes) and notes[k + 1][0] - eb < 1e-6
        if not nxt_legato:  # a phrase end or a gap: 40 ms release
            r = min(8, n)
            env[n - r:] = np.linspace(1.0, 0.05, r)
        sp[on:off] = np.concatenate([vsp[:head], body_sp]) * (g * env)[:, None]
        ap[on:off] = np.concatenate([vap[:head], body_ap])
        # the sung contour (cents relative to the note)
        age = np.arange(n) * fp
        cents = np.zeros(n)
        if legato and prev_hz is not None:
            glide = rng.uniform(0.04, 0.09)
            d0 = 1200 * math.log2(prev_hz / hz)
            m = age < glide
            cents[m] += d0 * 0.5 * (1 + np.cos(np.pi * age[m] / glide))
        elif rng.random() < 0.4:
            sc = rng.uniform(0.05, 0.08)
            m = age < sc
            cents[m] += -rng.uniform(30, 80) * (1 - age[m] / sc)
        vd = rng.uniform(0.15, 0.3)
        ramp = np.clip((age - vd) / 0.2, 0.0, 1.0)
        cents += vib_depth * ramp * np.sin(2 * np.pi * vib_rate * np.maximum(0.0, age - vd))
        cents += drift[on:off]
        f0[on:off] = hz * 2.0 ** (cents / 1200.0)
        onsets.append(round(on * fp, 4))
        lyrics.append({"text": text, "onset_s": round(on * fp, 4), "end_s": round(off * fp, 4),
                       "consonant_s": round((on - cons_start) * fp, 4), "midi": int(p + 12 * octave)})
        prev_end_fr, prev_hz, prev_on = off, hz, on
    y = pw.synthesize(f0, np.ascontiguousarray(sp), np.ascontiguousarray(ap), VOICE_SR, FRAME_MS)
    y = resample_poly(y, SR, VOICE_SR)
    out = np.zeros(n_out)
    out[: min(n_out, len(y))] = y[:n_out]
    return out, f0, onsets, lyrics


# ---------------------------------------------------------------------------------------


def build_song(args):
    index, out_dir, seed0, force = args
    seed = D.seed_of("tactus-sung-v1", seed0, index)
    rng = np.random.default_rng(seed)
    style = STYLES[index % len(STYLES)]
    voice, lang, register = VOICES[index % len(VOICES)]
    kit = D.ACOUSTIC_KITS[index % len(D.ACOUSTIC_KITS)]
    song = f"{style}_{voice.split('+')[1]}{lang}_s{index:02d}"
    final = os.path.join(out_dir, song)
    if os.path.exists(os.path.join(final, "truth.json")) and not force:
        return song, final, "exists", 0.0
    t0 = time.time()
    bpb, sub, (lo, hi), meter = D.STYLES[style]
    bpm = int(rng.integers(max(70, lo), min(150, hi) + 1))
    target_s = float(rng.uniform(24.0, 30.0))
    hits_b, flams, n_bars, end_beat = D.groove(rng, style, bpm, kit, target_s)
    hits_s = [h for h in D.humanise(rng, hits_b, flams, bpm) if h[0] > 0.01]
    parts, harmony = D.backing(rng, style, n_bars, bpm, hits_b)
    lead = phrase_notes(rng, parts["vocals"], bpb, end_beat)
    progs = {"bass": int(rng.choice(D.BASS_PROGRAMS)), "other": int(rng.choice(D.CHORD_PROGRAMS))}
    reverb = bool(rng.random() < 0.5)
    duration = end_beat * 60.0 / bpm + D.TAIL_S
    n_samples = int(round(duration * SR))
    n_frames = int(math.ceil(duration / HOP_S))
    octave = 0 if register == "high" else -1

    tmp = tempfile.mkdtemp(prefix="tactus-sung-")
    try:
        audio, mids = {}, {}
        mp_ = os.path.join(tmp, "drums.mid")
        exact = D.write_drum_midi(mp_, hits_s, bpm, kit)
        x = D.fluid_render(D.BACKING_SF2, mp_, os.path.join(tmp, "drums.wav"), reverb)
        y = np.zeros((n_samples, 2))
        y[: min(n_samples, len(x))] = x[:n_samples]
        audio["drums"] = y
        chans = {"bass": 1, "other": 2}
        for stem in ("bass", "other"):
            mp_ = os.path.join(tmp, f"{stem}.mid")
            mids[stem] = write_midi(mp_, parts[stem], bpm, chans[stem], progs[stem])
            x = D.fluid_render(D.BACKING_SF2, mp_, os.path.join(tmp, f"{stem}.wav"), reverb)
            y = np.zeros((n_samples, 2))
            y[: min(n_samples, len(x))] = x[:n_samples]
            audio[stem] = y
        voc, f0_5ms, v_onsets, lyrics = sing(rng, lead, bpm, voice, lang, octave, n_samples, tmp)
        audio["vocals"] = np.stack([voc, voc], axis=1)
        if reverb:
            audio["vocals"] = D.simple_reverb(rng, audio["vocals"])
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    gains_db = {"bass": float(rng.uniform(-4, 0)), "other": float(rng.uniform(-7, -1)),
                "vocals": float(rng.uniform(-3, 1)), "drums_vs_backing": float(rng.uniform(-3, 3))}
    for stem in ("bass", "other", "vocals"):
        audio[stem] = audio[stem] / D.rms(audio[stem]) * 10 ** (gains_db[stem] / 20)
    back = audio["bass"] + audio["other"] + audio["vocals"]
    audio["drums"] = audio["drums"] / D.rms(audio["drums"]) * D.rms(back) * 10 ** (gains_db["drums_vs_backing"] / 20)
    mix = back + audio["drums"]
    gain = (10 ** (-1 / 20)) / max(1e-9, float(np.max(np.abs(mix))))
    ints = {k: np.round(v * gain * 32767.0).astype(np.int32) for k, v in audio.items()}
    mix_i = sum(ints.values())
    assert np.max(np.abs(mix_i)) <= 32767, "mix clips"

    step = int(round(HOP_S * 1000 / FRAME_MS))
    f0_voc = [round(float(f0_5ms[i * step]), 4) if i * step < len(f0_5ms) else 0.0 for i in range(n_frames)]
    hits = [{"time_s": round(t, 9), "velocity": int(v), "note": int(n), "class": D.DRUM_BANDS[n]}
            for t, n, v in sorted(exact)]
    end_s = n_samples / SR
    truth = {
        "format": "tactus-truth",
        "version": 1,
        "song": f"sung/{song}",
        "source": "corpus/sung.py",
        "seed": seed0,
        "held_out": index % 2 == 1,
        "voice": {"espeak_ng": voice, "language": lang, "register": register,
                  "vocoder": "WORLD (pyworld): espeak-ng's envelope and aperiodicity, the melody's f0"},
        "kit": {"soundfont": "FluidR3_GM.sf2", "bank": 128, "preset": kit},
        "style": style,
        "meter": meter,
        "tempo_bpm": bpm,
        "reverb": reverb,
        "harmony": harmony,
        "gains_db": {k: round(v, 2) for k, v in gains_db.items()},
        "programs": progs,
        "sample_rate": SR,
        "channels": 2,
        "duration_s": end_s,
        "hop_s": HOP_S,
        "audio_format": "wav",
        "f0_hz": {
            "vocals": f0_voc,
            "bass": [round(v, 4) for v in f0_track(mids["bass"], n_frames)],
            "other": [round(v, 4) for v in f0_track(mids["other"], n_frames, top_line=True)],
        },
        "f0_notes": {"other": "top line of the polyphonic chords",
                     "vocals": "the sung contour (vibrato, scoops, portamento, drift) as synthesised; "
                               "0 on rests and unvoiced consonants"},
        "note_onsets_s": {
            "vocals": [x for x in v_onsets if x < end_s],
            "bass": [x for x in note_starts(mids["bass"]) if x < end_s],
            "other": [x for x in note_starts(mids["other"], top_line=True) if x < end_s],
        },
        "lyrics": lyrics,
        "onsets": D.class_onsets(hits),
        "onsets_rule": D.ONSETS_RULE,
        "hits": hits,
    }
    D.write_song_dir(out_dir, song, final, ints, mix_i, truth)
    voiced = sum(1 for v in f0_voc if v > 0) / max(1, n_frames)
    return song, final, f"{style} {bpm} bpm {duration:.1f} s, {voice}, {len(lyrics)} notes, voiced {voiced:.2f}", \
        time.time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--songs", type=int, default=12)
    ap.add_argument("--seed", type=int, default=16)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--force", action="store_true")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    t0 = time.time()
    names = []
    with mp.Pool(a.jobs) as pool:
        for k, (song, path, info, dt) in enumerate(pool.imap(build_song, [(i, a.out, a.seed, a.force)
                                                                        for i in range(a.songs)])):
            names.append((song, path))
            print(f"[{k + 1}/{a.songs} {time.time() - t0:6.1f}s] {song}: {info} ({dt:.1f} s)", flush=True)
    tmp = os.path.join(a.out, "SPLIT.txt.tmp")
    with open(tmp, "w") as fh:
        fh.write(f"corpus/sung.py --seed {a.seed}: even song index = tuning, odd = held out "
                 "(never used for tuning)\n")
        for i, (song, path) in enumerate(names):
            fh.write(f"{'held-out' if i % 2 else 'tuning'} {path}\n")
    os.replace(tmp, os.path.join(a.out, "SPLIT.txt"))
    print(f"done: {len(names)} songs under {a.out} ({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
