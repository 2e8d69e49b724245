#!/usr/bin/env python3
"""Deterministic synthetic multitrack corpus with exact ground truth, for Tactus.

Each song is a Bach chorale from music21's bundled corpus, arranged for four stems and
rendered stem by stem with FluidSynth and the FluidR3 General MIDI soundfont:

* vocals: the soprano line on a voice-like program (voice oohs / choir aahs / flute), with
  pitch-bend vibrato (5.5 Hz, +-35 cents, starting 150 ms into each note) and a 40-cent
  scoop into some notes;
* bass:   the bass line an octave down (notes below E1 = MIDI 28 folded up an octave) on
  acoustic bass / fingered bass / bassoon;
* other:  alto + tenor (polyphonic) on piano / strings / organ; the truth stores the top
  line (the highest sounding note at each instant);
* drums:  a generated groove on GM channel 10: kick, snare, closed / open hi-hat, ride,
  crash, toms, soft snare ghost notes (~ -20 dB below the backbeat, calibrated), and a tom
  fill on the last beat of bar 2 and of every 4th bar.

Ground truth (truth.json, schema in corpus/README.md) comes from the MIDI events that are
rendered, so it is exact up to the soundfont's own behaviour (sample attack, release tails),
which `--verify` measures.

Usage:
    python corpus/generate.py --out DIR [--small] [--format wav|flac] [--verify]
    python corpus/generate.py --out corpus/fixtures --update-band-truth   # truth.json only

Everything is deterministic: fixed pieces, fixed tempos, a seeded numpy RNG for the groove.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import mido
import numpy as np
import soundfile as sf

SR = 44100
HOP_S = 0.01
TPB = 960  # MIDI ticks per beat
LEAD_IN_BEATS = 1.0  # silence before the music starts
SOUNDFONT_CANDIDATES = [
    "/usr/share/sounds/sf2/FluidR3_GM.sf2",
    "/usr/share/soundfonts/FluidR3_GM.sf2",
]
# GM drum note -> Tactus band (docs/design.md band split)
DRUM_BANDS = {
    35: "kick", 36: "kick",
    37: "snare", 38: "snare", 40: "snare",
    41: "toms", 43: "toms", 45: "toms", 47: "toms", 48: "toms", 50: "toms",
    42: "cymbals", 44: "cymbals", 46: "cymbals", 49: "cymbals", 51: "cymbals",
    52: "cymbals", 53: "cymbals", 55: "cymbals", 57: "cymbals", 59: "cymbals",
}
# Ghost-note velocity: measured with --calibrate (FluidR3 snare 38: velocity 100 vs 33 is
# about -20 dB in RMS over the hit). See README "Rendering checks".
GHOST_VELOCITY = 33
BACKBEAT_VELOCITY = 100

# name, music21 work, tempo (bpm), vocals program, bass program, other program, seed
SONGS = [
    ("bwv66-6_96bpm", "bach/bwv66.6", 96, 53, 33, 0, 1),
    ("bwv347_120bpm", "bach/bwv347", 120, 52, 32, 48, 2),
    ("bwv153-1_72bpm", "bach/bwv153.1", 72, 73, 70, 19, 3),
    ("bwv40-8_140bpm", "bach/bwv40.8", 140, 53, 33, 0, 4),
    ("bwv269_108bpm", "bach/bwv269", 108, 52, 70, 48, 5),
    ("bwv7-7_84bpm", "bach/bwv7.7", 84, 73, 32, 0, 6),
]
SMALL_SONGS = ["bwv66-6_96bpm", "bwv347_120bpm"]
SMALL_SECONDS = 8.0


def find_soundfont() -> str:
    for p in SOUNDFONT_CANDIDATES:
        if os.path.exists(p):
            return p
    sys.exit("FluidR3_GM.sf2 not found: apt-get install fluidsynth fluid-soundfont-gm")


def midi_hz(m: float) -> float:
    return 440.0 * 2.0 ** ((m - 69.0) / 12.0)


# ---------------------------------------------------------------------------------------
# Arrangement: everything in beats (quarter notes) first, then ticks.
# A note is (start_beat, end_beat, midi_pitch, velocity).


def chorale_parts(work: str):
    from music21 import corpus

    score = corpus.parse(work).stripTies()
    parts = {}
    for p in score.parts:
        notes = []
        for n in p.flatten().notes:
            if n.isChord:
                continue
            start = float(n.offset)
            end = start + float(n.quarterLength)
            notes.append((start + LEAD_IN_BEATS, end + LEAD_IN_BEATS, int(n.pitch.midi)))
        parts[p.id] = sorted(notes)
    ts = score.recurse().getElementsByClass("TimeSignature").first()
    beats_per_bar = int(ts.numerator) if ts is not None else 4
    return parts, beats_per_bar, float(score.highestTime) + LEAD_IN_BEATS


def extra_songs(n: int):
    """`n` chorales beyond SONGS: four-part works of music21's Bach corpus in a seeded order,
    each with a tempo and programs drawn from those of SONGS (seed 1000 + index)."""
    from music21 import corpus

    used = {w for _, w, *_ in SONGS}
    works = sorted({"bach/" + os.path.splitext(os.path.basename(str(p)))[0]
                    for p in corpus.getComposer("bach")} - used)
    rng = np.random.default_rng(2026)
    rng.shuffle(works)
    vps = sorted({s[3] for s in SONGS})
    bps = sorted({s[4] for s in SONGS})
    ops = sorted({s[5] for s in SONGS})
    out = []
    for work in works:
        if len(out) == n:
            break
        try:
            parts, _, end_beat = chorale_parts(work)
        except Exception:  # noqa: BLE001 - a score music21 cannot read is skipped
            continue
        if not {"Soprano", "Alto", "Tenor", "Bass"} <= set(parts) or end_beat > 120:
            continue
        k = len(out)
        r = np.random.default_rng(1000 + k)
        bpm = int(r.integers(66, 141))
        name = f"{work.split('/')[1].replace('.', '-')}_{bpm}bpm"
        out.append((name, work, bpm, int(r.choice(vps)), int(r.choice(bps)), int(r.choice(ops)), 1000 + k))
    return out


def arrange(work: str, seed: int):
    parts, bpb, end_beat = chorale_parts(work)
    rng = np.random.default_rng(seed)
    # vocals: soprano, slightly detached so that each note is re-articulated
    vocals = [(s, e - 0.05, p, 96) for s, e, p in parts["Soprano"]]
    # bass: one octave down, folded to stay at or above E1 (MIDI 28, 41.2 Hz)
    bass = []
    for s, e, p in parts["Bass"]:
        q = p - 12
        while q < 28:
            q += 12
        bass.append((s, e - 0.05, q, 100))
    other = [(s, e - 0.02, p, 72) for s, e, p in parts["Alto"] + parts["Tenor"]]
    drums = groove(rng, bpb, end_beat)
    return {"vocals": vocals, "bass": bass, "other": other, "drums": drums}, end_beat


def groove(rng, bpb: int, end_beat: float):
    """A rock/pop groove with ghost notes, an open hat now and then and fills every 4 bars."""
    hits = []
    bar = 0
    start = LEAD_IN_BEATS
    n_bars = int(math.floor((end_beat - start) / bpb))
    for bar in range(n_bars):
        b0 = start + bar * bpb
        fill = bar % 4 == 3 or bar == 1  # bar 1: so that short excerpts have a fill
        if bar % 4 == 0:
            hits.append((b0, 49, 110))  # crash on the phrase downbeat
        for beat in range(bpb):
            t = b0 + beat
            in_fill = fill and beat == bpb - 1
            if in_fill:
                toms = [50, 48, 45, 43] if rng.random() < 0.5 else [48, 47, 43, 41]
                for k, note in enumerate(toms):
                    hits.append((t + 0.25 * k, note, 105 - 5 * k))
                continue
            # kick on 1 (and 3 in 4/4), plus an occasional syncopated "and"
            if beat == 0 or (bpb == 4 and beat == 2):
                hits.append((t, 36, 115))
            elif rng.random() < 0.3:
                hits.append((t + 0.5, 36, 95))
            # backbeat snare, ghost notes on some sixteenths
            if beat % 2 == 1:
                hits.append((t, 38, BACKBEAT_VELOCITY))
            for sixteenth in (0.25, 0.75):
                if rng.random() < 0.25:
                    hits.append((t + sixteenth, 38, GHOST_VELOCITY))
            # hats in eighths (ride in bars 4..7 of each 8), open hat on the last "and"
            cym = 51 if (bar // 4) % 2 == 1 else 42
            hits.append((t, cym, 80 if beat % 2 == 0 else 70))
            if beat == bpb - 1 and rng.random() < 0.5 and cym == 42:
                hits.append((t + 0.5, 46, 75))
            else:
                hits.append((t + 0.5, cym, 55))
    hits.append((start + n_bars * bpb, 49, 110))
    hits.append((start + n_bars * bpb, 36, 115))
    # deduplicate identical (time, note) and sort
    seen = {}
    for t, n, v in hits:
        key = (round(t * TPB), n)
        seen[key] = max(v, seen.get(key, 0))
    return sorted((k[0] / TPB, k[1], v) for k, v in seen.items())


# ---------------------------------------------------------------------------------------
# MIDI writing. Pitch bends are explicit events so that the truth can replay them.

BEND_RANGE = 2.0  # semitones, set via RPN 0 on every melodic channel


def vibrato_bends(notes, bpm: float, rng_seed: int):
    """Pitch-bend events (tick, value in semitones) for the vocals: scoop + vibrato."""
    rng = np.random.default_rng(rng_seed)
    events = []
    step_s = 0.01
    for s, e, _p, _v in notes:
        ts, te = s * 60.0 / bpm, e * 60.0 / bpm
        scoop = rng.random() < 0.4
        t = ts
        while t < te:
            age = t - ts
            cents = 0.0
            if scoop and age < 0.06:
                cents += -40.0 * (1.0 - age / 0.06)
            if age >= 0.15:
                ramp = min(1.0, (age - 0.15) / 0.2)
                cents += 35.0 * ramp * math.sin(2 * math.pi * 5.5 * (age - 0.15))
            events.append((t, cents / 100.0))
            t += step_s
        events.append((te, 0.0))
    return events


def bend_to_midi(semitones: float) -> int:
    v = int(round(semitones / BEND_RANGE * 8192.0))
    return max(-8192, min(8191, v))


def midi_to_bend(value: int) -> float:
    return value / 8192.0 * BEND_RANGE


def write_midi(path, notes, bpm, channel, program, bends=None, drums=False):
    mid = mido.MidiFile(ticks_per_beat=TPB)
    tr = mido.MidiTrack()
    mid.tracks.append(tr)
    events = []  # (tick, order, message)
    tick = lambda seconds: int(round(seconds * bpm / 60.0 * TPB))
    events.append((0, 0, mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(bpm))))
    if not drums:
        events.append((0, 1, mido.Message("program_change", channel=channel, program=program)))
        for ctl, val in ((101, 0), (100, 0), (6, int(BEND_RANGE)), (38, 0)):
            events.append((0, 2, mido.Message("control_change", channel=channel, control=ctl, value=val)))
    for s, e, p, v in notes:
        # A note that ends before it starts (a grace note shorter than the release gap, as
        # in bwv299) would get its note-off first and then sound forever: fluidsynth's fast
        # render of a sustained patch never ends. It has no f0 in the truth either.
        if e <= s:
            continue
        events.append((int(round(s * TPB)), 5, mido.Message("note_on", channel=channel, note=p, velocity=v)))
        events.append((int(round(e * TPB)), 4, mido.Message("note_off", channel=channel, note=p, velocity=0)))
    for t, semis in bends or []:
        events.append((tick(t), 3, mido.Message("pitchwheel", channel=channel, pitch=bend_to_midi(semis))))
    save_events(mid, tr, events, path)
    return mid


def save_events(mid, tr, events, path):
    """Appends `events` ((tick, order, message), absolute ticks) to track `tr` in tick then
    order, with delta times and an end of track one beat later, and saves `mid` to `path`."""
    events.sort(key=lambda x: (x[0], x[1]))
    last = 0
    for t, _o, msg in events:
        tr.append(msg.copy(time=t - last))
        last = t
    tr.append(mido.MetaMessage("end_of_track", time=TPB))
    mid.save(path)


def render(sf2, mid_path, wav_path):
    subprocess.run(
        ["fluidsynth", "-ni", "-q", "-R", "0", "-C", "0", "-g", "0.6", "-r", str(SR),
         "-O", "float", "-F", wav_path, sf2, mid_path],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    x, sr = sf.read(wav_path, dtype="float64", always_2d=True)
    assert sr == SR, sr
    return x.mean(axis=1)  # mono


# ---------------------------------------------------------------------------------------
# Truth


def f0_track(mid: mido.MidiFile, n_frames: int, top_line=False):
    """f0 per HOP_S frame from the MIDI events actually written (ticks, bends included)."""
    sec_per_tick = None
    t = 0
    active = {}  # note -> True
    bend = 0.0
    changes = []  # (seconds, frozenset(active), bend)
    for msg in mido.merge_tracks(mid.tracks):
        t += msg.time
        if msg.type == "set_tempo":
            sec_per_tick = msg.tempo / 1e6 / mid.ticks_per_beat
            continue
        if msg.type == "note_on" and msg.velocity > 0:
            active[msg.note] = True
        elif msg.type in ("note_off", "note_on"):
            active.pop(msg.note, None)
        elif msg.type == "pitchwheel":
            bend = midi_to_bend(msg.pitch)
        else:
            continue
        changes.append((t * sec_per_tick, tuple(sorted(active)), bend))
    f0 = np.zeros(n_frames)
    k = 0
    state = ((), 0.0)
    for i in range(n_frames):
        ti = i * HOP_S
        while k < len(changes) and changes[k][0] <= ti + 1e-9:
            state = (changes[k][1], changes[k][2])
            k += 1
        notes, b = state
        if notes:
            if len(notes) > 1 and not top_line:
                raise ValueError("polyphony in a monophonic stem")
            f0[i] = midi_hz(max(notes) + b)
    return f0


def note_starts(mid: mido.MidiFile, top_line=False):
    """Start times (s) of the notes written, rounded to 0.1 ms; with `top_line`, only notes that
    become the highest sounding note when they start (the `other` stem's top line)."""
    sec_per_tick = None
    t = 0
    active = set()
    starts = []
    for msg in mido.merge_tracks(mid.tracks):
        t += msg.time
        if msg.type == "set_tempo":
            sec_per_tick = msg.tempo / 1e6 / mid.ticks_per_beat
        elif msg.type == "note_on" and msg.velocity > 0:
            if not top_line or not active or msg.note >= max(active):
                starts.append(round(t * sec_per_tick, 4))
            active.add(msg.note)
        elif msg.type in ("note_off", "note_on"):
            active.discard(msg.note)
    return sorted(set(starts))


# Per-band truth (docs/design.md "Known weakness"): the Tactus band edges in Hz, and the rule that
# puts a hit in a band. A GM drum note belongs to band b when the energy of its isolated
# sound in b is within BAND_TRUTH_DB of its loudest band. Energy: the note rendered alone
# (velocity 100, no reverb/chorus), first BAND_TRUTH_WINDOW_S after note-on, Hann window,
# |rfft|^2 summed over the band's bins [lo, hi). Velocity scales all bands alike, so the
# table is per note (ghost notes share their note's bands).
BAND_EDGES_HZ = {"kick": (30.0, 150.0), "snare": (150.0, 800.0), "toms": (800.0, 5000.0), "cymbals": (5000.0, 12000.0)}
BAND_TRUTH_DB = 10.0
BAND_TRUTH_WINDOW_S = 0.2


def drum_band_table(sf2, notes, tmp):
    """{note: {band: dB re the note's loudest band}} from one FluidSynth render per note."""
    table = {}
    for note in sorted(set(notes)):
        mp = os.path.join(tmp, f"band{note}.mid")
        write_midi(mp, [(1.0, 1.1, note, 100)], 60, 9, 0, drums=True)
        x = render(sf2, mp, os.path.join(tmp, f"band{note}.wav"))
        seg = x[SR : SR + int(BAND_TRUTH_WINDOW_S * SR)]
        spec = np.abs(np.fft.rfft(seg * np.hanning(len(seg)))) ** 2
        freqs = np.fft.rfftfreq(len(seg), 1.0 / SR)
        e = {b: float(spec[(freqs >= lo) & (freqs < hi)].sum()) for b, (lo, hi) in BAND_EDGES_HZ.items()}
        top = max(e.values())
        table[note] = {b: round(10 * math.log10(max(v, 1e-30) / top), 2) for b, v in e.items()}
    return table


def band_truth(onsets, table):
    """Per-band truth: every hit whose note is within BAND_TRUTH_DB of its loudest band in b."""
    out = {b: [] for b in BAND_EDGES_HZ}
    hits = sorted((h for hs in onsets.values() for h in hs), key=lambda h: (h["time_s"], h["note"]))
    for h in hits:
        for b, db in table[h["note"]].items():
            if db >= -BAND_TRUTH_DB:
                out[b].append(h)
    return out


def add_band_truth(truth, table):
    truth["band_onsets"] = band_truth(truth["onsets"], table)
    truth["band_truth_rule"] = (
        f"a hit is in band b when its GM note's isolated sound (velocity 100, first "
        f"{BAND_TRUTH_WINDOW_S * 1000:g} ms) has energy in b within {BAND_TRUTH_DB:g} dB of its loudest band"
    )
    truth["band_db_by_note"] = {str(n): table[n] for n in sorted(table)}
    return truth


def drum_truth(hits, bpm):
    out = {b: [] for b in ("kick", "snare", "toms", "cymbals")}
    for beat, note, vel in hits:
        tick = int(round(beat * TPB))
        out[DRUM_BANDS[note]].append(
            {"time_s": round(tick * 60.0 / bpm / TPB, 9), "velocity": int(vel), "note": int(note)}
        )
    return out


# ---------------------------------------------------------------------------------------


def build_song(sf2, name, work, bpm, vprog, bprog, oprog, seed, out_dir, seconds, fmt, tmp):
    arr, end_beat = arrange(work, seed)
    limit_beat = None if seconds is None else seconds * bpm / 60.0
    if limit_beat is not None:
        arr = {
            k: [n for n in v if n[0] < limit_beat - 0.25] for k, v in arr.items()
        }
        cut = lambda n: (n[0], min(n[1], limit_beat - 0.05), *n[2:])
        for k in ("vocals", "bass", "other"):
            arr[k] = [cut(n) for n in arr[k]]
    duration = (seconds if seconds is not None else end_beat * 60.0 / bpm + 1.5)
    n_samples = int(round(duration * SR))
    n_frames = int(math.ceil(duration / HOP_S))

    mids, audio = {}, {}
    bends = vibrato_bends(arr["vocals"], bpm, seed)
    specs = {
        "vocals": (0, vprog, bends, False),
        "bass": (1, bprog, None, False),
        "other": (2, oprog, None, False),
        "drums": (9, 0, None, True),
    }
    for stem, (ch, prog, bd, is_drum) in specs.items():
        notes = (
            [(t, t + 0.1, n, v) for t, n, v in arr["drums"]] if is_drum else arr[stem]
        )
        mp = os.path.join(tmp, f"{name}_{stem}.mid")
        mids[stem] = write_midi(mp, notes, bpm, ch, prog, bd, drums=is_drum)
        x = render(sf2, mp, os.path.join(tmp, f"{name}_{stem}.wav"))
        y = np.zeros(n_samples)
        y[: min(n_samples, len(x))] = x[:n_samples]
        if seconds is not None:  # short fade-out over the last 50 ms of a cut excerpt
            f = int(0.05 * SR)
            y[-f:] *= np.linspace(1.0, 0.0, f)
        audio[stem] = y

    # One gain for all stems so that the mix peaks at -1 dBFS, then quantize the stems to
    # 16 bits and build the mix as their exact integer sum (so mix == sum of stems).
    mix = sum(audio.values())
    gain = (10 ** (-1 / 20)) / max(1e-9, np.max(np.abs(mix)))
    ints = {k: np.round(v * gain * 32767.0).astype(np.int32) for k, v in audio.items()}
    mix_i = sum(ints.values())
    assert np.max(np.abs(mix_i)) <= 32767, "mix clips"
    song_dir = os.path.join(out_dir, name)
    os.makedirs(song_dir, exist_ok=True)
    for k, v in list(ints.items()) + [("mix", mix_i)]:
        sf.write(os.path.join(song_dir, f"{k}.{fmt}"), v.astype(np.int16), SR, subtype="PCM_16")

    truth = {
        "format": "tactus-truth",
        "version": 1,
        "song": name,
        "source": f"music21 corpus {work}",
        "tempo_bpm": bpm,
        "programs": {"vocals": vprog, "bass": bprog, "other": oprog},
        "sample_rate": SR,
        "duration_s": n_samples / SR,
        "hop_s": HOP_S,
        "audio_format": fmt,
        "f0_hz": {
            "vocals": [round(v, 4) for v in f0_track(mids["vocals"], n_frames)],
            "bass": [round(v, 4) for v in f0_track(mids["bass"], n_frames)],
            "other": [round(v, 4) for v in f0_track(mids["other"], n_frames, top_line=True)],
        },
        "f0_notes": {"other": "top line of the polyphonic alto + tenor accompaniment"},
        "note_onsets_s": {
            "vocals": [x for x in note_starts(mids["vocals"]) if x < n_samples / SR],
            "bass": [x for x in note_starts(mids["bass"]) if x < n_samples / SR],
            "other": [x for x in note_starts(mids["other"], top_line=True) if x < n_samples / SR],
        },
        "onsets": drum_truth(arr["drums"], bpm),
    }
    add_band_truth(truth, drum_band_table(sf2, [n for _t, n, _v in arr["drums"]], tmp))
    with open(os.path.join(song_dir, "truth.json"), "w") as fh:
        json.dump(truth, fh, separators=(",", ":"))
        fh.write("\n")
    return song_dir


# ---------------------------------------------------------------------------------------
# Checks: does the audio match the truth?


def yin(x, fmin, fmax, frame=2048, threshold=0.1):
    """Plain YIN (de Cheveigne & Kawahara 2002) per HOP_S hop, centred frames; for --verify."""
    hop = int(round(HOP_S * SR))
    pad = np.concatenate([np.zeros(frame // 2), x, np.zeros(frame)])
    n = int(math.ceil(len(x) / hop))
    half = frame // 2
    tmin, tmax = int(SR / fmax), min(half - 2, int(SR / fmin) + 1)
    out = np.zeros(n)
    for i in range(n):
        w = pad[i * hop : i * hop + frame]
        if np.sqrt(np.mean(w**2)) < 1e-4:
            continue
        # difference function d(t) = sum_j (w[j] - w[j+t])^2, j < half, via correlation
        r = np.correlate(w[: half + tmax + 2], w[:half], "valid")[: tmax + 2]
        c = np.concatenate([[0.0], np.cumsum(w**2)])
        e_t = c[np.arange(tmax + 2) + half] - c[np.arange(tmax + 2)]
        d = c[half] + e_t - 2.0 * r
        cm = np.ones_like(d)
        cs = np.cumsum(d[1:])
        cm[1:] = d[1:] * np.arange(1, len(d)) / np.maximum(cs, 1e-12)
        cand = np.where(cm[tmin:tmax] < threshold)[0]
        if len(cand) == 0:
            continue
        t = cand[0] + tmin
        while t + 1 < tmax and cm[t + 1] < cm[t]:
            t += 1
        a, b, c = cm[t - 1], cm[t], cm[t + 1]
        den = a - 2 * b + c
        shift = 0.5 * (a - c) / den if den != 0 else 0.0
        out[i] = SR / (t + shift)
    return out


def first_onset(x, thresh_rel=0.05):
    env = np.abs(x)
    idx = np.flatnonzero(env > thresh_rel * env.max())
    return idx[0] / SR if len(idx) else float("nan")


def verify(song_dir, fmt):
    truth = json.load(open(os.path.join(song_dir, "truth.json")))
    rows = []
    stems = {k: sf.read(os.path.join(song_dir, f"{k}.{fmt}"))[0] for k in ("vocals", "bass", "other", "drums")}
    mix = sf.read(os.path.join(song_dir, f"mix.{fmt}"), dtype="int16")[0].astype(np.int64)
    total = sum(sf.read(os.path.join(song_dir, f"{k}.{fmt}"), dtype="int16")[0].astype(np.int64) for k in stems)
    rows.append(f"  mix == sum of stems: {bool(np.array_equal(mix, total))}")
    for stem, (lo, hi) in {"vocals": (70, 1400), "bass": (35, 400)}.items():
        ref = np.array(truth["f0_hz"][stem])
        est = yin(stems[stem], lo, hi, frame=4096 if stem == "bass" else 2048)
        n = min(len(ref), len(est))
        ref, est = ref[:n], est[:n]
        voiced = ref > 0
        ok = voiced & (est > 0) & (np.abs(1200 * np.log2(np.maximum(est, 1e-9) / np.maximum(ref, 1e-9))) < 50)
        rows.append(f"  {stem}: YIN raw pitch accuracy vs truth {ok.sum() / max(1, voiced.sum()):.3f}")
    # onset latency: first audible sample of each stem vs the first truth event
    for stem in ("vocals", "bass", "other"):
        f0 = np.array(truth["f0_hz"][stem])
        t_truth = np.flatnonzero(f0 > 0)[0] * HOP_S
        rows.append(f"  {stem}: first note truth {t_truth:.3f} s, audio {first_onset(stems[stem]):.4f} s")
    first_drum = min(h["time_s"] for b in truth["onsets"].values() for h in b)
    rows.append(f"  drums: first hit truth {first_drum:.3f} s, audio {first_onset(stems['drums']):.4f} s")
    return "\n".join(rows)


def calibrate(sf2, tmp):
    """Prints the level of snare hits at several velocities relative to velocity 100."""
    levels = {}
    for vel in (100, 40, 30, 20):
        mp = os.path.join(tmp, f"cal{vel}.mid")
        write_midi(mp, [(0.5, 0.6, 38, vel)], 120, 9, 0, drums=True)
        x = render(sf2, mp, os.path.join(tmp, f"cal{vel}.wav"))
        levels[vel] = 20 * np.log10(np.sqrt(np.mean(x[int(0.25 * SR) : int(0.45 * SR)] ** 2)))
    for vel, db in levels.items():
        print(f"snare velocity {vel}: {db - levels[100]:+.1f} dB re velocity 100")
    # onset latency of isolated notes per program
    for prog, note in ((53, 72), (52, 72), (73, 72), (33, 40), (32, 40), (70, 40), (0, 60), (48, 60), (19, 60)):
        mp = os.path.join(tmp, f"lat{prog}.mid")
        write_midi(mp, [(1.0, 2.0, note, 100)], 60, 0, prog)
        x = render(sf2, mp, os.path.join(tmp, f"lat{prog}.wav"))
        print(f"program {prog}: first sample above 5% of peak at {first_onset(x) - 1.0:+.4f} s after note-on")
    for note in (36, 38, 42, 45, 49):
        mp = os.path.join(tmp, f"latd{note}.mid")
        write_midi(mp, [(1.0, 1.1, note, 100)], 60, 9, 0, drums=True)
        x = render(sf2, mp, os.path.join(tmp, f"latd{note}.wav"))
        print(f"drum {note}: first sample above 5% of peak at {first_onset(x) - 1.0:+.4f} s after note-on")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--extra", type=int, default=0, metavar="N",
                    help="instead of the six songs: N further four-part chorales of music21's Bach "
                         "corpus (never those six), programs and tempo drawn per song from the six's "
                         "(seeded), for training learned models")
    ap.add_argument("--skip", type=int, default=0, metavar="K",
                    help="with --extra: render only the extra chorales from the K-th on (a later held-out set)")
    ap.add_argument("--small", action="store_true", help=f"the committed fixture set: {len(SMALL_SONGS)} songs x {SMALL_SECONDS:g} s, FLAC")
    ap.add_argument("--format", choices=("wav", "flac"), default=None, help="audio format (default wav, flac with --small)")
    ap.add_argument("--verify", action="store_true", help="after generating, check audio against truth")
    ap.add_argument("--calibrate", action="store_true", help="measure ghost-note level and onset latencies, then exit")
    ap.add_argument("--update-band-truth", action="store_true",
                    help="only (re)compute band_onsets in the truth.json files under --out; audio untouched")
    args = ap.parse_args()
    sf2 = find_soundfont()
    fmt = args.format or ("flac" if args.small else "wav")
    tmp = tempfile.mkdtemp(prefix="tactus-corpus-")
    try:
        if args.calibrate:
            calibrate(sf2, tmp)
            return
        if args.update_band_truth:
            for song in sorted(os.listdir(args.out)):
                path = os.path.join(args.out, song, "truth.json")
                if not os.path.exists(path):
                    continue
                truth = json.load(open(path))
                notes = [h["note"] for hs in truth["onsets"].values() for h in hs]
                add_band_truth(truth, drum_band_table(sf2, notes, tmp))
                with open(path, "w") as fh:
                    json.dump(truth, fh, separators=(",", ":"))
                    fh.write("\n")
                print(path, {b: len(v) for b, v in truth["band_onsets"].items()})
            return
        os.makedirs(args.out, exist_ok=True)
        songs = [s for s in SONGS if (not args.small) or s[0] in SMALL_SONGS]
        if args.extra:
            songs = extra_songs(args.extra)[args.skip:]
        for name, work, bpm, vp, bp, op, seed in songs:
            d = build_song(sf2, name, work, bpm, vp, bp, op, seed, args.out,
                           SMALL_SECONDS if args.small else None, fmt, tmp)
            print(d)
            if args.verify:
                print(verify(d, fmt))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
