#!/usr/bin/env python3
"""Drum-transcription corpus: random grooves on several free drum-kit families, with a backing.

Each song is a 20-30 s groove (4/4 rock, funk, half-time, disco, ride, tom grooves, brush train
beats, 12/8 shuffle, 6/8, jazz swing) with fills (tom runs, snare rolls, flams), crashes,
splashes and chinas, humanised timing (+-8 ms) and velocities, plus a musical backing (bass line,
chords, a lead with vibrato) rendered with FluidR3_GM melodic programs. The drum kit comes from
one of five families:

* fluid     FluidR3_GM bank 128 (Standard, Room, Power, Jazz, Brush; Electronic and TR-808 once)
* timgm     TimGM6mb bank 128 (same presets)
* csound    sf_GMbank (csound-soundfont) bank 128 (same presets)
* sonicpi   one-shot samples from sonic-pi-samples mixed with numpy (velocity as gain)
* synth     every drum synthesised with numpy from random parameters per song (sine kicks with and
            without pitch sweeps, tuned snares, toms from 60 to 400 Hz, metallic or noise cymbals)
* synth2    the synth family widened (issue 10): snares of every body tuning and wire colour and
            decay, three velocity layers (ghost notes darker and wire-dominated), rim shots,
            cross-stick, brushes; toms with stick noise and snare-wire buzz; hats and cymbals
            reaching down into the snare's range; two round-robin variants per layer
* remix     each class (kick, snare, toms, cymbals) from a different training source per song:
            a TimGM6mb or sf_GMbank preset, or a synth2 kit (never fluid, musescore or sonicpi)
* choke     (a trial, made only when named) every sound of one training source per song (timgm,
            csound or sonicpi; the name starts with it), but the closed and pedal hats are another
            of its cymbals retuned and cut short (12-70 ms decay): more kinds of closed hat
* choke2    (a trial, made only when named) choke, and the snares and rim shots (37, 38, 40) of
            the same source retuned (+-4 semitones) and tilted (+-3 dB/octave) per song: the
            snare's colour as wide as the hats'
* musescore MuseScore_General_Full bank 128: the HELD-OUT family (evaluate only, never train)

FluidR3_GS.sf2 has only an SFX kit in bank 128, so it contributes no drum kit.

Ground truth (truth.json, format `tactus-truth` v1, see corpus/README.md) comes from the very
events that are rendered: per-hit time, velocity and GM note under onsets.{kick,snare,toms,
cymbals}, f0 of bass / lead ("vocals") / chords' top line ("other") per 10 ms hop.

Usage:
    corpus/.venv/bin/python corpus/drums.py --out /work/data/drums [--songs 12]
        [--families fluid,timgm,csound,sonicpi,musescore] [--jobs 2] [--force]

Deterministic: every song is seeded from (family, index); existing songs are skipped unless
--force, so `--songs 40` later only adds songs 12..39.
"""
from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import shutil
import subprocess
import sys
import tempfile
import time
import zlib

import mido
import numpy as np
import soundfile as sf

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from generate import DRUM_BANDS, HOP_S, SR, TPB, f0_track, save_events, vibrato_bends, write_midi  # noqa: E402

SF2_DIR = "/usr/share/sounds/sf2"
SONICPI_DIR = "/usr/share/sonic-pi/samples"
BACKING_SF2 = os.path.join(SF2_DIR, "FluidR3_GM.sf2")
FAMILY_SF2 = {
    "fluid": "FluidR3_GM.sf2",
    "timgm": "TimGM6mb.sf2",
    "csound": "sf_GMbank.sf2",
    "musescore": "MuseScore_General_Full.sf2",
}
FAMILIES = ["fluid", "timgm", "csound", "sonicpi", "musescore", "synth", "synth2", "remix", "choke", "choke2"]
# `choke` and `choke2` (trial families, issue 10) are made only when asked for by name
CHOKE_FAMILIES = ("choke", "choke2")
DEFAULT_FAMILIES = [f for f in FAMILIES if f not in CHOKE_FAMILIES]
# the snare notes a `choke2` song retunes and tilts
CHOKE2_SNARES = (37, 38, 40)
# "choke" songs: one training source per song (its name starts with it); the closed and pedal
# hats are other cymbals of that source, choked
CHOKE_SOURCES = ["timgm", "csound", "sonicpi"]
CHOKE_SF2_CYMBALS = [46, 49, 51, 52, 55, 57, 59, 42]
CHOKE_SP_CYMBALS = ["drum_cymbal_open", "drum_cymbal_hard", "drum_cymbal_soft", "drum_splash_soft",
                    "drum_splash_hard", "elec_cymbal", "drum_cymbal_closed", "drum_cymbal_pedal"]
HATS = (42, 44, 46)
# "remix" songs take each class (kick, snare, toms, cymbals) from a different training source
REMIX_SOURCES = ["timgm", "csound", "synth2"]
REMIX_PRESETS = [0, 8, 16, 24, 25, 32, 40]
REMIX_LEVELS = {"kick": 1.0, "snare": 0.8, "toms": 0.7, "cymbals": 0.45}
HELD_OUT = {"musescore"}
# Kit order per song index: the acoustic kits cycle; Electronic (24) and TR-808 (25) once each.
KIT_ORDER = [0, 8, 16, 32, 40, 24, 0, 8, 16, 32, 40, 25]
ACOUSTIC_KITS = [0, 8, 16, 32, 40]
KIT_ABBR = {0: "std", 8: "room", 16: "power", 24: "elec", 25: "tr808", 32: "jazz", 40: "brush"}
CLASSES = ("kick", "snare", "toms", "cymbals")

# Backing programs (FluidR3_GM, General MIDI numbering from 0)
BASS_PROGRAMS = [32, 33, 34, 35, 38, 39]  # acoustic, fingered, picked, fretless, synth 1, synth 2
CHORD_PROGRAMS = [0, 1, 4, 5, 16, 19, 24, 25, 27, 48, 49, 89]  # pianos, e-pianos, organs, guitars, strings, pad
LEAD_PROGRAMS = [52, 53, 54, 65, 66, 73, 80, 81, 56]  # choir, oohs, synth voice, saxes, flute, leads, trumpet

MAJOR = [0, 2, 4, 5, 7, 9, 11]
MINOR = [0, 2, 3, 5, 7, 8, 10]
PROGRESSIONS = {
    "major": [[0, 4, 5, 3], [5, 3, 0, 4], [0, 3, 4, 3], [0, 5, 3, 4], [1, 4, 0, 0], [0, 0, 3, 4]],
    "minor": [[0, 5, 2, 6], [0, 3, 4, 0], [0, 6, 5, 6], [0, 5, 3, 4], [0, 3, 0, 4]],
}

# style: (beats per bar, subdivisions per beat, tempo range, meter label)
STYLES = {
    "rock8": (4, 4, (80, 160), "4/4"),
    "funk16": (4, 4, (80, 115), "4/4"),
    "halftime": (4, 4, (120, 180), "4/4"),
    "disco": (4, 4, (100, 130), "4/4"),
    "ride": (4, 4, (90, 170), "4/4"),
    "tomgroove": (4, 4, (80, 150), "4/4"),
    "train": (4, 4, (70, 140), "4/4"),
    "shuffle12": (4, 3, (70, 120), "12/8"),
    "six8": (2, 3, (70, 110), "6/8"),
    "swing": (4, 3, (110, 180), "4/4 swing"),
}
STYLE_ORDER = ["rock8", "funk16", "tomgroove", "shuffle12", "halftime", "ride", "six8", "disco",
               "rock8", "train", "tomgroove", "swing"]
LEAD_IN_BEATS = 1.0
TAIL_S = 1.5
HUMANISE_MS = 8.0


def seed_of(*parts) -> int:
    return zlib.crc32("/".join(str(p) for p in parts).encode())


# ---------------------------------------------------------------------------------------
# Grooves. A hit is (beat, note, velocity); beats are the style's beat unit from song start.


def vel(rng, v, spread=8):
    return int(np.clip(round(v + rng.uniform(-spread, spread)), 1, 127))


def timekeeper_for(style, rng, kit):
    if style in ("ride", "swing"):
        return 51
    if style == "tomgroove":
        return 42 if rng.random() < 0.6 else 51
    if kit in (32, 40) and rng.random() < 0.4:
        return 51
    return 42 if rng.random() < 0.75 else 51


def bar_groove(rng, style, b0, bpb, sub, tk, variant):
    """One bar of groove (no fill). tk: timekeeping cymbal (42 closed hat, 51 ride, 46 loose hat)."""
    h = []
    s = 1.0 / sub
    if style in ("rock8", "halftime", "ride", "disco", "funk16", "train", "tomgroove"):
        # timekeeping
        if style == "funk16" or (style == "disco" and variant % 2 == 0):
            for k in range(bpb * sub):
                h.append((b0 + k * s, tk, vel(rng, 85 if k % 2 == 0 else 55)))
        elif style == "tomgroove" and variant % 2 == 1:
            for k in range(bpb):
                h.append((b0 + k, tk, vel(rng, 80)))
        elif style != "train" or rng.random() < 0.5:
            for k in range(bpb * 2):
                h.append((b0 + k * 0.5, tk, vel(rng, 90 if k % 2 == 0 else 65)))
        if style == "ride" and variant % 2 == 1:
            for k in range(bpb):
                h.append((b0 + k, 53, vel(rng, 85)))
        if style == "disco":
            for k in range(bpb):
                h.append((b0 + k + 0.5, 46, vel(rng, 80)))
        if tk == 51 and rng.random() < 0.5:
            for k in (1, 3):
                h.append((b0 + k, 44, vel(rng, 60)))
        # kick
        if style == "disco":
            kicks = [0, 1, 2, 3]
        elif style == "halftime":
            kicks = [0] + ([1.5] if rng.random() < 0.5 else []) + ([2.75] if rng.random() < 0.4 else [])
        elif style == "funk16":
            kicks = [0] + [x for x in (0.75, 1.5, 2.25, 2.5, 3.25) if rng.random() < 0.35]
        else:
            kicks = [0, 2] + [x for x in (1.5, 2.5, 3.5) if rng.random() < 0.3]
        for k in kicks:
            h.append((b0 + k, 36 if rng.random() < 0.8 else 35, vel(rng, 110 if k in (0, 2) else 95)))
        # snare
        backs = [2] if style == "halftime" else [1, 3]
        for k in backs:
            if style == "ride" and variant % 4 == 3 and rng.random() < 0.5:
                h.append((b0 + k, 37, vel(rng, 95)))  # rim click / side stick on the backbeat
            else:
                h.append((b0 + k, 38 if rng.random() < 0.85 else 40, vel(rng, 108)))
        ghost_p = {"funk16": 0.35, "train": 0.0, "halftime": 0.2}.get(style, 0.15)
        for k in range(bpb * 4):
            pos = k * 0.25
            if pos in backs or pos in kicks:
                continue
            if rng.random() < ghost_p and (pos % 1) != 0:
                h.append((b0 + pos, 38, int(rng.integers(20, 46))))
        if style == "train":  # brush-like train beat: snare sixteenths, accents on 2 and 4
            for k in range(bpb * 4):
                pos = k * 0.25
                if pos not in backs:
                    h.append((b0 + pos, 38, int(rng.integers(22, 46)) if pos % 1 else vel(rng, 60)))
        if style == "tomgroove":
            # floor / low tom ostinato (the hard case: toms against kick and snare)
            pat = [0.0, 0.5, 0.75, 1.5, 2.0, 2.5, 2.75, 3.5] if variant % 2 == 0 else [0.5, 1.5, 2.5, 3.25, 3.5]
            tom_a, tom_b = (41, 43) if rng.random() < 0.5 else (43, 45)
            for k, pos in enumerate(pat):
                note = tom_a if k % 3 != 2 else tom_b
                h.append((b0 + pos, note, vel(rng, 100 if pos % 1 == 0 else 80)))
            if rng.random() < 0.4:
                h.append((b0 + 3.75, 48 if rng.random() < 0.5 else 47, vel(rng, 85)))
    elif style == "shuffle12":
        for k in range(bpb):
            h.append((b0 + k, tk, vel(rng, 90)))
            h.append((b0 + k + 2 * s, tk, vel(rng, 65)))
            if rng.random() < 0.2:
                h.append((b0 + k + s, tk, vel(rng, 45)))
        for k in (0, 2):
            h.append((b0 + k, 36, vel(rng, 110)))
        if rng.random() < 0.5:
            h.append((b0 + 2 + 2 * s, 36, vel(rng, 90)))
        for k in (1, 3):
            h.append((b0 + k, 38, vel(rng, 105)))
        for k in range(bpb):
            if rng.random() < 0.35:
                h.append((b0 + k + 2 * s, 38, int(rng.integers(20, 46))))
    elif style == "six8":
        for k in range(bpb * sub):
            h.append((b0 + k * s, tk, vel(rng, 85 if k % 3 == 0 else 60)))
        h.append((b0, 36, vel(rng, 110)))
        if rng.random() < 0.5:
            h.append((b0 + 2 * s, 36, vel(rng, 90)))
        h.append((b0 + 1, 38, vel(rng, 105)))
        if rng.random() < 0.3:
            h.append((b0 + 1 + 2 * s, 38, int(rng.integers(20, 46))))
    elif style == "swing":
        for k in range(bpb):
            h.append((b0 + k, 51, vel(rng, 85 if k % 2 else 75)))
            if k % 2 == 1:
                h.append((b0 + k + 2 * s, 51, vel(rng, 60)))
                h.append((b0 + k, 44, vel(rng, 65)))
        for k in range(bpb):  # feathered kick
            if rng.random() < 0.5:
                h.append((b0 + k, 36, int(rng.integers(35, 60))))
        for _ in range(int(rng.integers(1, 4))):  # snare comping, often soft
            pos = int(rng.integers(0, bpb)) + (2 * s if rng.random() < 0.6 else 0)
            h.append((b0 + pos, 38, int(rng.integers(25, 90))))
        if rng.random() < 0.2:
            h.append((b0 + bpb - 1 + 2 * s, 37, vel(rng, 80)))
    return h


def fill(rng, b0, bpb, sub, beats):
    """A fill over the last `beats` beats of the bar starting at b0."""
    h = []
    start = b0 + bpb - beats
    kind = rng.choice(["toms", "toms", "snare_roll", "mixed", "flams"])
    step = 1.0 / sub if rng.random() < 0.7 else 0.5
    n = int(round(beats / step))
    tom_sets = [[50, 48, 47, 45, 43, 41], [48, 47, 45, 43], [50, 48, 45, 41], [47, 45, 43, 41]]
    toms = tom_sets[int(rng.integers(0, len(tom_sets)))]
    for k in range(n):
        t = start + k * step
        if kind == "toms":
            note = toms[min(len(toms) - 1, k * len(toms) // n)]
            h.append((t, note, vel(rng, 100 - 10 * (k % 2))))
        elif kind == "snare_roll":
            # a roll in steps of half the grid, crescendo from ghost level
            for j in range(2):
                v = int(30 + 80 * (k * 2 + j) / (2 * n))
                h.append((t + j * step / 2, 38, vel(rng, v, 5)))
        elif kind == "mixed":
            note = 38 if k % 2 == 0 else toms[min(len(toms) - 1, k * len(toms) // n)]
            h.append((t, note, vel(rng, 100)))
        else:  # flams on snare and toms: a soft grace note 20-30 ms before the main stroke
            note = 38 if k % 2 == 0 else toms[k % len(toms)]
            h.append((t, note, vel(rng, 105)))
            h.append(("flam", t, note, int(rng.integers(35, 60))))
        if rng.random() < 0.2 and kind != "snare_roll":
            h.append((t, 36, vel(rng, 95)))
    return h


def groove(rng, style, bpm, kit, target_s):
    bpb, sub, _tempo, _meter = STYLES[style]
    beat_s = 60.0 / bpm
    n_bars = max(4, int(math.ceil((target_s - TAIL_S - LEAD_IN_BEATS * beat_s) / (bpb * beat_s))))
    while n_bars > 4 and (LEAD_IN_BEATS + n_bars * bpb) * beat_s + TAIL_S > 30.0:
        n_bars -= 1
    phrase = 4 if bpb == 4 else 8
    if rng.random() < 0.3:
        phrase *= 2
    hits, flams = [], []
    tk = timekeeper_for(style, rng, kit)
    rim_section = tom_section = False
    for bar in range(n_bars):
        b0 = LEAD_IN_BEATS + bar * bpb
        if bar % phrase == 0:
            if bar > 0 and rng.random() < 0.35:  # change the timekeeper at a phrase
                tk = timekeeper_for(style, rng, kit) if style not in ("swing",) else 51
                if tk == 42 and rng.random() < 0.2:
                    tk = 46  # a loose open hat section
            crash = 49 if rng.random() < 0.7 else 57
            hits.append((b0, crash, vel(rng, 112)))
            hits.append((b0, 36, vel(rng, 112)))
        elif rng.random() < 0.08:
            hits.append((b0, 55 if rng.random() < 0.6 else 52, vel(rng, 100)))
        is_fill = bar % phrase == phrase - 1 or (bar == 1 and rng.random() < 0.5)
        fill_beats = 0
        if is_fill:
            fill_beats = 1 if rng.random() < 0.6 else min(2, bpb)
        if bar % phrase == 0:
            rim_section = rng.random() < 0.25  # side stick instead of the backbeat snare
            tom_section = style not in ("tomgroove", "swing") and rng.random() < 0.15
        g = bar_groove(rng, style, b0, bpb, sub, tk, bar // phrase)
        if rim_section:
            g = [(t, 37 if n in (38, 40) and v > 60 else n, v) for t, n, v in g]
        if tom_section:  # floor tom instead of the hats / ride for a phrase
            g = [(t, 41 if n == tk and rng.random() < 0.8 else n, v) for t, n, v in g]
        cut = b0 + bpb - fill_beats - 1e-6
        hits += [x for x in g if x[0] < cut]
        if fill_beats:
            for x in fill(rng, b0, bpb, sub, fill_beats):
                (flams if x[0] == "flam" else hits).append(x)
        if bar % phrase != 0 and rng.random() < 0.06:  # an accent crash + snare mid-phrase
            pos = b0 + int(rng.integers(0, bpb))
            hits.append((pos, 49, vel(rng, 105)))
            hits.append((pos, 38, vel(rng, 110)))
    end = LEAD_IN_BEATS + n_bars * bpb
    hits.append((end, 49 if rng.random() < 0.6 else 57, vel(rng, 115)))
    hits.append((end, 36, vel(rng, 115)))
    if rng.random() < 0.3:
        hits.append((end, 38, vel(rng, 110)))
    # open hats close when the next hat hit comes (the kits choke them); nothing else to do here
    seen = {}
    for t, n, v in hits:
        key = (round(t * 48 * 4), n)
        seen[key] = (t, max(v, seen.get(key, (0, 0))[1]))
    hits = [(t, n, v) for (_k, n), (t, v) in seen.items()]
    return sorted(hits), flams, n_bars, end


def humanise(rng, hits, flams, bpm):
    """(beats) -> list of (time_s, note, velocity), jitter N(0, 3.5 ms) clipped to +-8 ms."""
    beat_s = 60.0 / bpm
    out = []
    for t, n, v in hits:
        j = float(np.clip(rng.normal(0, 3.5), -HUMANISE_MS, HUMANISE_MS)) / 1000.0
        out.append((t * beat_s + j, n, v))
    for _f, t, n, v in flams:
        j = float(np.clip(rng.normal(0, 3.5), -HUMANISE_MS, HUMANISE_MS)) / 1000.0
        out.append((t * beat_s - rng.uniform(0.02, 0.03) + j, n, v))
    out.sort()
    # a drummer cannot hit the same drum twice within 15 ms: drop the softer
    res = []
    last = {}
    for t, n, v in out:
        if n in last and t - res[last[n]][0] < 0.015:
            if v > res[last[n]][2]:
                res[last[n]] = (res[last[n]][0], n, v)
            continue
        last[n] = len(res)
        res.append((t, n, v))
    return res


# ---------------------------------------------------------------------------------------
# Backing: bass, chords, lead. Notes are (start_beat, end_beat, pitch, velocity).


def backing(rng, style, n_bars, bpm, drum_hits_beats):
    bpb, sub, _t, _m = STYLES[style]
    mode = "major" if rng.random() < 0.55 else "minor"
    scale = MAJOR if mode == "major" else MINOR
    root = int(rng.integers(0, 12))
    prog = PROGRESSIONS[mode][int(rng.integers(0, len(PROGRESSIONS[mode])))]
    bars_per_chord = 2 if bpb == 2 else 1
    kick_beats = sorted({round(t, 4) for t, n, _v in drum_hits_beats if n in (35, 36)})

    def degree_pc(d):
        return (root + scale[d % 7] + 12 * (d // 7)) % 12

    chords = []  # (start, end, [pcs], root pc)
    for bar in range(0, n_bars, bars_per_chord):
        d = prog[(bar // bars_per_chord) % len(prog)]
        pcs = [degree_pc(d), degree_pc(d + 2), degree_pc(d + 4)]
        s = LEAD_IN_BEATS + bar * bpb
        chords.append((s, s + bpb * bars_per_chord, pcs, pcs[0]))
    end = LEAD_IN_BEATS + n_bars * bpb

    # bass: E1 (28) .. G3 (55)
    bass_oct = 28 if rng.random() < 0.6 else 40
    bass_style = rng.choice(["quarters", "eighths", "kick", "rootfifth", "long"])
    bass = []
    for s, e, pcs, rpc in chords:
        rp = bass_oct + (rpc - 4) % 12
        fifth = rp + 7 if rp + 7 <= 55 else rp - 5
        if bass_style == "long":
            starts = [s]
        elif bass_style == "eighths" and sub == 4:
            starts = list(np.arange(s, e, 0.5))
        elif bass_style == "kick":
            starts = [k for k in kick_beats if s <= k < e] or [s]
        else:
            starts = list(np.arange(s, e, 1.0))
        for k, st in enumerate(starts):
            p = fifth if bass_style == "rootfifth" and k % 2 == 1 else rp
            if rng.random() < 0.1:
                p = min(55, p + 12)
            bass.append([float(st), None, int(p), vel(rng, 95, 10)])
    for k in range(len(bass)):
        nxt = bass[k + 1][0] if k + 1 < len(bass) else end
        bass[k][1] = max(bass[k][0] + 0.1, nxt - 0.08)
    bass = [tuple(b) for b in bass]

    # chords: close triads around C4..E5
    comp = rng.choice(["sustain", "beats", "offbeats"])
    other = []
    for s, e, pcs, _r in chords:
        pitches = sorted(55 + (pc - 55) % 12 for pc in pcs)
        if comp == "sustain":
            times = [(s, e - 0.05)]
        elif comp == "beats":
            times = [(t, t + 0.8) for t in np.arange(s, e, 1.0)]
        else:
            times = [(t + 0.5, t + 0.9) for t in np.arange(s, e, 1.0)] if sub == 4 else \
                [(t + 1 / 3, t + 0.6) for t in np.arange(s, e, 1.0)]
        v = vel(rng, 70, 10)
        for a, b in times:
            for p in pitches:
                other.append((float(a), float(b), int(p), v))

    # lead: a stepwise melody on the scale, chord tones on strong beats, rests between phrases
    lead = []
    durs = [0.5, 1.0, 1.0, 1.5, 2.0] if sub == 4 else [1 / 3, 2 / 3, 1.0, 1.0, 2.0]
    scale_pitches = [p for p in range(60, 82) if (p - root) % 12 in scale]
    idx = int(rng.integers(3, len(scale_pitches) - 3))
    t = LEAD_IN_BEATS + bpb  # the lead enters after one bar
    while t < end - 1.0:
        bar_pos = (t - LEAD_IN_BEATS) % (2 * bpb)
        if bar_pos < 1e-6 and rng.random() < 0.35:
            t += float(rng.choice([1.0, 2.0]))  # breath
            continue
        d = float(rng.choice(durs))
        idx = int(np.clip(idx + rng.choice([-2, -1, -1, 0, 1, 1, 2]), 0, len(scale_pitches) - 1))
        p = scale_pitches[idx]
        if abs(t - round(t)) < 1e-6 and rng.random() < 0.6:  # snap to a chord tone on the beat
            ch = [c for c in chords if c[0] <= t < c[1]]
            if ch:
                cands = [q for q in scale_pitches if q % 12 in ch[0][2]]
                p = min(cands, key=lambda q: abs(q - p))
                idx = scale_pitches.index(p)
        e = min(t + d, end - 0.5)
        if e - t > 0.15:
            lead.append((float(t), float(e - 0.06), int(p), vel(rng, 95, 8)))
        t += d
    return {"bass": bass, "other": other, "vocals": lead}, {"root": root, "mode": mode, "progression": prog}


# ---------------------------------------------------------------------------------------
# Rendering


def fluid_render(sf2, mid_path, wav_path, reverb):
    subprocess.run(
        ["fluidsynth", "-ni", "-q", "-R", "1" if reverb else "0", "-C", "0", "-g", "0.6", "-r", str(SR),
         "-O", "float", "-F", wav_path, sf2, mid_path],
        check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    x, sr = sf.read(wav_path, dtype="float64", always_2d=True)
    assert sr == SR, sr
    if x.shape[1] == 1:
        x = np.repeat(x, 2, axis=1)
    return x


def write_drum_midi(path, hits_s, bpm, kit):
    """Drum hits (time_s, note, vel) on channel 10 with the kit's program change; returns the
    exact times as rendered (rounded to ticks)."""
    mid = mido.MidiFile(ticks_per_beat=TPB)
    tr = mido.MidiTrack()
    mid.tracks.append(tr)
    to_tick = lambda s: int(round(s * bpm / 60.0 * TPB))
    ev = [(0, 0, mido.MetaMessage("set_tempo", tempo=mido.bpm2tempo(bpm))),
          (0, 1, mido.Message("control_change", channel=9, control=0, value=0)),
          (0, 2, mido.Message("program_change", channel=9, program=kit))]
    exact = []
    # note-off: 1.5 s later or just before the next hit of the same note (re-strike)
    by_note = {}
    for t, n, v in hits_s:
        by_note.setdefault(n, []).append(t)
    for t, n, v in hits_s:
        tk = max(1, to_tick(t))
        later = [u for u in by_note[n] if u > t]
        off = min(t + 1.5, later[0] - 0.002) if later else t + 1.5
        ev.append((tk, 5, mido.Message("note_on", channel=9, note=n, velocity=v)))
        ev.append((max(tk + 1, to_tick(off)), 4, mido.Message("note_off", channel=9, note=n, velocity=0)))
        exact.append((tk * 60.0 / bpm / TPB, n, v))
    save_events(mid, tr, ev, path)
    return exact


# sonic-pi kits: GM note -> candidate samples (soft, hard) by velocity
SP_KICKS = ["drum_bass_hard", "drum_heavy_kick", "bd_fat", "bd_boom", "bd_klub", "bd_haus", "bd_pure",
            "bd_zome", "bd_tek", "bd_808", "bd_sone", "bd_gas", "bd_mehackit", "elec_hollow_kick", "elec_soft_kick"]
SP_SNARES = ["drum_snare_hard", "sn_generic", "sn_dub", "sn_dolf", "sn_zome", "elec_snare", "elec_hi_snare",
             "elec_mid_snare", "elec_lo_snare"]
SP_RIMS = ["elec_wood", "elec_tick", "perc_snap"]
_SAMPLE_CACHE = {}


def _retuned(x, semitones):
    """x resampled (linear) so that it sounds `semitones` higher; as it is for 0."""
    if not semitones:
        return x
    r = 2.0 ** (semitones / 12.0)
    return np.interp(np.arange(int(len(x) / r)) * r, np.arange(len(x)), x)


def load_sample(name, semitones=0.0):
    key = (name, round(semitones, 3))
    if key in _SAMPLE_CACHE:
        return _SAMPLE_CACHE[key]
    x, sr = sf.read(os.path.join(SONICPI_DIR, name + ".flac"), dtype="float64", always_2d=True)
    assert sr == SR, (name, sr)
    x = x.mean(axis=1)
    pk = np.max(np.abs(x))
    first = int(np.flatnonzero(np.abs(x) > 0.02 * pk)[0])
    x = x[max(0, first - int(0.001 * SR)):]  # the attack lands on the hit time
    x = _retuned(x, semitones)
    x = x / max(1e-9, np.max(np.abs(x)))
    _SAMPLE_CACHE[key] = x
    return x


def sonicpi_kit(rng):
    kick = str(rng.choice(SP_KICKS))
    snare = str(rng.choice(SP_SNARES))
    rim = str(rng.choice(SP_RIMS))
    tshift = float(rng.uniform(-2, 2))
    cshift = float(rng.uniform(-1.5, 1.5))
    kit = {
        35: (kick, kick, -1.0, 0.0), 36: (kick, kick, 0.0, 0.0),
        37: (rim, rim, 0.0, -0.05), 40: (snare, snare, 1.0, -0.1),
        38: ("drum_snare_soft" if snare == "drum_snare_hard" else snare, snare, 0.0, -0.1),
        41: ("drum_tom_lo_soft", "drum_tom_lo_hard", tshift - 2, -0.5),
        43: ("drum_tom_lo_soft", "drum_tom_lo_hard", tshift, -0.35),
        45: ("drum_tom_mid_soft", "drum_tom_mid_hard", tshift - 1.5, -0.1),
        47: ("drum_tom_mid_soft", "drum_tom_mid_hard", tshift, 0.1),
        48: ("drum_tom_hi_soft", "drum_tom_hi_hard", tshift, 0.3),
        50: ("drum_tom_hi_soft", "drum_tom_hi_hard", tshift + 2, 0.45),
        42: ("drum_cymbal_closed", "drum_cymbal_closed", cshift, 0.4),
        44: ("drum_cymbal_pedal", "drum_cymbal_pedal", cshift, 0.4),
        46: ("drum_cymbal_open", "drum_cymbal_open", cshift, 0.4),
        49: ("drum_cymbal_hard", "drum_cymbal_hard", cshift, 0.3),
        57: ("drum_cymbal_hard", "drum_cymbal_hard", cshift - 2, -0.3),
        51: ("drum_cymbal_soft", "drum_cymbal_soft", cshift, -0.4),
        53: ("drum_cymbal_soft", "drum_cymbal_soft", cshift + 7, -0.4),
        55: ("drum_splash_soft", "drum_splash_hard", cshift, 0.2),
        52: ("elec_cymbal", "drum_splash_hard", cshift - 4, -0.2),
    }
    if rng.random() < 0.3:  # an electronic tom set now and then
        for n, st in zip((41, 43, 45, 47, 48, 50), (-7, -5, -3, -1, 1, 3)):
            kit[n] = ("elec_fuzz_tom", "elec_fuzz_tom", st + tshift, kit[n][3])
    levels = {35: 1.0, 36: 1.0, 37: 0.6, 38: 0.9, 40: 0.9, 42: 0.35, 44: 0.3, 46: 0.4, 51: 0.35, 53: 0.4,
              49: 0.55, 57: 0.55, 55: 0.45, 52: 0.5}
    name = kick.replace("drum_", "d").replace("_", "") + "-" + snare.replace("drum_", "d").replace("_", "")
    return kit, levels, name


def _mix_hits(hits_s, levels, n_samples, sample_of):
    """Mixes each hit (t, note, velocity) into a stereo buffer: `sample_of(note, velocity)`
    gives its mono sample and pan; an open hat is choked at the next closed or pedal hat;
    gain = level × (velocity / 127)², constant-power pan. Returns (y, exact hits)."""
    y = np.zeros((n_samples, 2))
    exact = []
    hats = sorted((t, n) for t, n, _v in hits_s if n in (42, 44, 46))
    for t, n, v in hits_s:
        x, pan = sample_of(n, v)
        pos = int(round(t * SR))
        if n == 46:  # choke the open hat at the next closed / pedal hat
            nxt = [u for u, m in hats if u > t + 1e-6 and m in (42, 44)]
            if nxt:
                L = max(1, int(round((nxt[0] - t) * SR)))
                x = x[:L].copy()
                f = min(len(x), int(0.01 * SR))
                x[-f:] *= np.linspace(1, 0, f)
        g = levels.get(n, 0.8) * (v / 127.0) ** 2
        L = min(len(x), n_samples - pos)
        if L <= 0:
            continue
        a = math.pi / 4 * (pan + 1)
        y[pos:pos + L, 0] += g * math.cos(a) * x[:L]
        y[pos:pos + L, 1] += g * math.sin(a) * x[:L]
        exact.append((pos / SR, n, v))
    return y, exact


def sonicpi_render(hits_s, kit, levels, n_samples):
    def sample_of(n, v):
        soft, hard, semis, pan = kit[n]
        return load_sample(soft if v < 70 else hard, semis), pan

    return _mix_hits(hits_s, levels, n_samples, sample_of)


# ---------------------------------------------------------------------------------------
# The "synth" family: every sound synthesised with numpy from random parameters (sine
# kicks with and without a pitch sweep, tuned snare bodies under band-passed noise, swept
# toms tuned anywhere from 60 to 400 Hz, metallic square-wave or noise cymbals), so the
# transcriber meets electronic and unusually tuned kits in training. No samples are used.


def _band_noise(rng, n, lo, hi):
    """White noise band-passed to [lo, hi] Hz (raised-cosine edges), unit peak."""
    x = rng.standard_normal(n)
    return _band(x, lo, hi)


def _band(x, lo, hi):
    n = len(x)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(n, 1.0 / SR)
    w = np.clip((f - 0.7 * lo) / (0.3 * lo + 1e-9), 0, 1) * np.clip((1.3 * hi - f) / (0.3 * hi), 0, 1)
    y = np.fft.irfft(X * np.sin(0.5 * np.pi * w) ** 2, n)
    return y / max(1e-9, float(np.max(np.abs(y))))


def _sweep(f_start, f_end, tau, n):
    t = np.arange(n) / SR
    f = f_end + (f_start - f_end) * np.exp(-t / tau)
    return np.sin(2 * np.pi * np.cumsum(f) / SR)


def _finish(x, fade_s=0.01):
    x = x / max(1e-9, float(np.max(np.abs(x))))
    k = min(len(x), int(fade_s * SR))
    x[-k:] *= np.linspace(1, 0, k)
    return x


def _darken(x, cutoff):
    """One-pole low-pass (soft hits are darker), unit peak."""
    a = math.exp(-2 * math.pi * cutoff / SR)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(len(x), 1.0 / SR)
    y = np.fft.irfft(X * (1 - a) / np.abs(1 - a * np.exp(-2j * np.pi * f / SR)), len(x))
    return y / max(1e-9, float(np.max(np.abs(y))))


def synth_kick(rng):
    n = int(rng.uniform(0.35, 0.8) * SR)
    t = np.arange(n) / SR
    f_end = rng.uniform(38, 75)
    ratio = 1.0 if rng.random() < 0.25 else rng.uniform(1.3, 5.0)
    x = _sweep(f_end * ratio, f_end, rng.uniform(0.008, 0.07), n) * np.exp(-t / rng.uniform(0.07, 0.45))
    if rng.random() < 0.7:  # beater click
        k = int(rng.uniform(0.001, 0.006) * SR)
        c = _band_noise(rng, k, rng.uniform(1000, 3000), rng.uniform(5000, 12000)) * np.exp(-np.arange(k) / (0.3 * k))
        x[:k] += rng.uniform(0.05, 0.6) * c
    if rng.random() < 0.4:  # drive
        g = rng.uniform(1.5, 5)
        x = np.tanh(g * x) / math.tanh(g)
    return _finish(x)


def synth_snare(rng, electronic):
    n = int(rng.uniform(0.25, 0.5) * SR)
    t = np.arange(n) / SR
    f0 = rng.uniform(150, 340)
    body = _sweep(f0 * rng.uniform(1.0, 1.4), f0, 0.01, n) * np.exp(-t / rng.uniform(0.03, 0.14))
    body += rng.uniform(0.2, 0.7) * _sweep(f0 * 1.6, f0 * 1.55, 0.01, n) * np.exp(-t / rng.uniform(0.02, 0.08))
    lo = rng.uniform(900, 3500) if not electronic else rng.uniform(2000, 6000)
    noise = _band_noise(rng, n, lo, rng.uniform(7000, 15000)) * np.exp(-t / rng.uniform(0.06, 0.3))
    x = body / np.max(np.abs(body)) + rng.uniform(0.4, 2.0) * noise
    return _finish(x)


def synth_rim(rng):
    n = int(0.15 * SR)
    t = np.arange(n) / SR
    x = np.sin(2 * np.pi * rng.uniform(400, 1200) * t) * np.exp(-t / rng.uniform(0.008, 0.03))
    x += rng.uniform(0.3, 1.0) * _band_noise(rng, n, 1500, 9000) * np.exp(-t / rng.uniform(0.002, 0.008))
    return _finish(x)


def synth_tom(rng, f0, electronic):
    n = int(rng.uniform(0.4, 0.9) * SR)
    t = np.arange(n) / SR
    tau = rng.uniform(0.12, 0.6)
    x = _sweep(f0 * rng.uniform(1.05, 1.6 if electronic else 1.3), f0, rng.uniform(0.02, 0.12), n) * np.exp(-t / tau)
    if not electronic:
        x += rng.uniform(0.1, 0.4) * _sweep(f0 * 1.6, f0 * 1.5, 0.03, n) * np.exp(-t / (0.4 * tau))
        k = int(0.006 * SR)
        x[:k] += rng.uniform(0.03, 0.25) * _band_noise(rng, k, 1000, 6000) * np.exp(-np.arange(k) / (0.3 * k))
    return _finish(x)


def _metal(rng, n, scale):
    t = np.arange(n) / SR
    fr = np.array([205.3, 304.4, 369.6, 522.7, 540.0, 800.0]) * scale
    return sum(np.sign(np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3))) for f in fr)


def _cymbal_noise(rng, n, lo, hi, tau, metallic, metal_scale):
    """A cymbal's body: noise (plus the metallic square-wave cluster) band-passed to
    [lo, hi] Hz, decaying with time constant tau s. Draws from rng in a fixed order."""
    t = np.arange(n) / SR
    src = rng.uniform(0.3, 1.0) * rng.standard_normal(n)
    if metallic:
        m = _metal(rng, n, metal_scale)
        src = src + m / np.max(np.abs(m))
    return _band(src, lo, hi) * np.exp(-t / tau)


def synth_cymbal(rng, kind, metal_scale, metallic):
    length = {"closed": 0.2, "pedal": 0.2, "open": 1.0, "ride": 2.0, "bell": 2.0, "crash": 2.5,
              "splash": 1.0, "china": 2.0}[kind]
    n = int(length * SR)
    t = np.arange(n) / SR
    lo, hi, tau = {
        "closed": (rng.uniform(5000, 9000), 16000, rng.uniform(0.015, 0.06)),
        "pedal": (rng.uniform(5000, 9000), 14000, rng.uniform(0.015, 0.04)),
        "open": (rng.uniform(5000, 9000), 16000, rng.uniform(0.2, 0.6)),
        "ride": (rng.uniform(2500, 5000), 15000, rng.uniform(0.6, 1.6)),
        "bell": (rng.uniform(1500, 3000), 12000, rng.uniform(0.6, 1.6)),
        "crash": (rng.uniform(1500, 4000), 16000, rng.uniform(0.6, 2.0)),
        "splash": (rng.uniform(2500, 5000), 16000, rng.uniform(0.2, 0.6)),
        "china": (rng.uniform(800, 2000), 12000, rng.uniform(0.5, 1.5)),
    }[kind]
    x = _cymbal_noise(rng, n, lo, hi, tau, metallic, metal_scale)
    if kind in ("ride", "bell"):
        fb = rng.uniform(600, 1200)
        x += (0.6 if kind == "bell" else 0.15) * sum(
            np.sin(2 * np.pi * fb * r * t) for r in (1.0, 2.76, 5.4)) / 3 * np.exp(-t / rng.uniform(0.4, 1.0))
    k = int(0.002 * SR)
    x[:k] *= np.linspace(0, 1, k)  # no DC step
    return _finish(x)


def synth_kit(rng):
    """note -> (soft, hard, pan) arrays, levels, name."""
    electronic = bool(rng.random() < 0.4)
    metallic = bool(rng.random() < 0.5)
    mscale = rng.uniform(0.8, 2.0)
    kick = synth_kick(rng)
    kick2 = synth_kick(rng) if rng.random() < 0.3 else kick
    snare = synth_snare(rng, electronic)
    snare2 = synth_snare(rng, electronic) if rng.random() < 0.3 else snare
    rim = synth_rim(rng)
    base = rng.uniform(60, 130)
    step = rng.uniform(1.12, 1.35)
    kit = {35: (kick2, 0.0), 36: (kick, 0.0), 37: (rim, -0.05), 38: (snare, -0.1), 40: (snare2, -0.1)}
    for k, (note, pan) in enumerate(zip((41, 43, 45, 47, 48, 50), (-0.5, -0.35, -0.1, 0.1, 0.3, 0.45))):
        kit[note] = (synth_tom(rng, base * step ** k, electronic), pan)
    for note, kind, pan in ((42, "closed", 0.4), (44, "pedal", 0.4), (46, "open", 0.4), (51, "ride", -0.4),
                            (53, "bell", -0.4), (59, "ride", -0.4), (49, "crash", 0.3), (57, "crash", -0.3),
                            (55, "splash", 0.2), (52, "china", -0.2)):
        kit[note] = (synth_cymbal(rng, kind, mscale, metallic), pan)
    dark = rng.uniform(1500, 5000)
    out = {n: (_darken(x, dark), x, pan) for n, (x, pan) in kit.items()}
    levels = {35: 1.0, 36: 1.0, 37: 0.6, 38: 0.9, 40: 0.9, 42: 0.35, 44: 0.3, 46: 0.4, 51: 0.35, 53: 0.4,
              59: 0.35, 49: 0.55, 57: 0.55, 55: 0.45, 52: 0.5}
    for n in levels:  # kits are balanced differently
        levels[n] *= 10 ** (rng.uniform(-4, 4) / 20)
    name = ("elec" if electronic else "acou") + ("-metal" if metallic else "-noise")
    return out, levels, name


def synth_render(hits_s, kit, levels, n_samples):
    def sample_of(n, v):
        soft, hard, pan = kit[n]
        return (soft if v < 70 else hard), pan

    return _mix_hits(hits_s, levels, n_samples, sample_of)


# ---------------------------------------------------------------------------------------
# The "synth2" family (2026-11-24, issue 10): the synth family widened where the transcriber
# fails on unseen kits: snares (body tuning 110-500 Hz with 1-4 modes, wire noise of every
# colour and decay, delayed or buzzing wires, stick clicks, rim shots, cross-stick, brushes,
# three velocity layers so ghost notes are darker and wire-dominated), toms with stick noise
# and snare-wire buzz, snares with long tonal bodies, and hats / cymbals whose noise reaches
# down into the snare's range with stick attacks. Every hit picks one of two round-robin
# variants. `synth` is unchanged, so its songs stay reproducible.

SYNTH2_LAYERS = (45, 90, 127)  # velocity upper bounds of the ghost, medium and hard layers
SNARE_MODE_RATIOS = (1.59, 2.14, 2.30, 2.65, 2.92, 3.16)


def _logu(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _tilt(x, db_per_oct, pivot=2000.0):
    """Spectral tilt of `db_per_oct` around `pivot` Hz, unit peak."""
    X = np.fft.rfft(x)
    f = np.maximum(np.fft.rfftfreq(len(x), 1.0 / SR), 20.0)
    y = np.fft.irfft(X * (f / pivot) ** (db_per_oct / 6.02), len(x))
    return y / max(1e-9, float(np.max(np.abs(y))))


def _resonate(x, freqs, q):
    """x through a sum of resonant peaks (Gaussian on a log axis, width 1/q octave), unit peak."""
    X = np.fft.rfft(x)
    f = np.maximum(np.fft.rfftfreq(len(x), 1.0 / SR), 1.0)
    h = sum(np.exp(-0.5 * (np.log2(f / fr) * q) ** 2) for fr in freqs)
    y = np.fft.irfft(X * h, len(x))
    return y / max(1e-9, float(np.max(np.abs(y))))


def _coloured_noise(rng, n, p):
    """Wire / brush noise of colour `p` (drawn once per kit by `_noise_colour`)."""
    x = rng.standard_normal(n)
    if p["kind"] == "band":
        return _band(x, p["lo"], p["hi"])
    if p["kind"] == "tilt":
        return _band(_tilt(x, p["tilt"]), p["lo"], p["hi"])
    return _resonate(_band(x, p["lo"], p["hi"]), p["peaks"], p["q"])


def _noise_colour(rng, lo_range=(250, 4500)):
    kind = str(rng.choice(["band", "tilt", "res"]))
    p = {"kind": kind, "lo": _logu(rng, *lo_range), "hi": rng.uniform(5000, 16000)}
    p["tilt"] = rng.uniform(-6, 3)
    p["peaks"] = [_logu(rng, 800, 9000) for _ in range(int(rng.integers(2, 5)))]
    p["q"] = rng.uniform(1.5, 5)
    return p


def _click(rng, n, lo, hi, dur):
    k = max(8, int(dur * SR))
    c = np.zeros(n)
    c[:k] = _band_noise(rng, k, lo, hi) * np.exp(-np.arange(k) / (0.3 * k))
    return c


def synth2_snare_params(rng, brush):
    f0 = _logu(rng, 110, 500)
    nm = int(rng.integers(0, 4))
    return {
        "brush": brush,
        "len": rng.uniform(0.25, 0.6),
        "f0": f0,
        "sweep": rng.uniform(1.0, 1.5),
        "modes": [(1.0, 1.0)] + [(float(r), rng.uniform(0.15, 0.8))
                                 for r in rng.choice(SNARE_MODE_RATIOS, nm, replace=False)],
        # tonal snares (long body: piccolo, ringing, tuned electronic) half the time
        "tau_body": _logu(rng, 0.015, 0.08) if rng.random() < 0.5 else _logu(rng, 0.08, 0.3),
        "wires": _noise_colour(rng),
        "tau_wire": _logu(rng, 0.03, 0.45),
        "wire_level": _logu(rng, 0.15, 4.0),
        "wire_delay": rng.uniform(0, 0.006) if rng.random() < 0.5 else 0.0,
        "buzz": rng.uniform(0, 1) if rng.random() < 0.4 else 0.0,  # wires modulated by the body
        "click": rng.uniform(0, 0.8),
        "click_band": (rng.uniform(1500, 4000), rng.uniform(6000, 14000)),
        "swish_attack": rng.uniform(0.004, 0.03),
        "ghost_body": rng.uniform(0.15, 0.8),  # soft hits: less body relative to the wires
    }


def synth2_snare(rng, p, layer):
    """One snare hit of velocity layer 0 (ghost), 1 (medium) or 2 (hard)."""
    n = int(p["len"] * SR)
    t = np.arange(n) / SR
    if p["brush"]:
        a = min(n - 1, int(p["swish_attack"] * (1.5 if layer == 0 else 1.0) * SR))
        env = np.exp(-t / (p["tau_wire"] * (1.4 if layer == 0 else 1.0)))
        env[:a] *= np.linspace(0, 1, a) ** 2
        x = _coloured_noise(rng, n, p["wires"]) * env
        body = _sweep(p["f0"], p["f0"], 0.01, n) * np.exp(-t / p["tau_body"])
        x += rng.uniform(0.0, 0.3) * body
        return _finish(x)
    body = sum(g * _sweep(p["f0"] * r * p["sweep"], p["f0"] * r, 0.01, n) * np.exp(-t / (p["tau_body"] / r ** 0.5))
               for r, g in p["modes"])
    body = body / max(1e-9, float(np.max(np.abs(body))))
    d = int(p["wire_delay"] * SR)
    wires = np.zeros(n)
    wires[d:] = _coloured_noise(rng, n - d, p["wires"]) * np.exp(-np.arange(n - d) / SR / p["tau_wire"])
    if p["buzz"]:
        wires *= 1 + p["buzz"] * np.abs(body)
    bl = {0: p["ghost_body"], 1: 0.5 * (1 + p["ghost_body"]), 2: 1.0}[layer]
    x = bl * body + p["wire_level"] * wires / max(1e-9, float(np.max(np.abs(wires))))
    x += p["click"] * (0.3 if layer == 0 else 1.0) * _click(rng, n, *p["click_band"], rng.uniform(0.0005, 0.003))
    x = _finish(x)
    if layer == 0:
        x = _darken(x, rng.uniform(1500, 4000))
    elif layer == 1:
        x = _darken(x, rng.uniform(4000, 9000))
    return x


def synth2_rimshot(rng, p):
    """Stick on head and rim at once: the hard snare plus a ringing rim ping and a crack."""
    x = synth2_snare(rng, {**p, "brush": False}, 2)
    n = len(x)
    t = np.arange(n) / SR
    fp = rng.uniform(500, 1400)
    ping = sum(np.sin(2 * np.pi * fp * r * t) for r in (1.0, rng.uniform(1.4, 2.6))) * np.exp(-t / rng.uniform(0.01, 0.06))
    x = x + rng.uniform(0.3, 1.2) * ping / 2 + rng.uniform(0.5, 1.5) * _click(rng, n, 2000, 12000, 0.002)
    return _finish(x)


def synth2_cross_stick(rng):
    """Side stick: a woody knock (two or three short modes) and a click, no wires."""
    n = int(0.15 * SR)
    t = np.arange(n) / SR
    fs = [_logu(rng, 300, 2500) for _ in range(int(rng.integers(2, 4)))]
    tau = _logu(rng, 0.003, 0.03)
    x = sum(rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * f * t) * np.exp(-t / tau) for f in fs)
    x += rng.uniform(0.2, 1.0) * _click(rng, n, 1500, 10000, rng.uniform(0.0005, 0.003))
    return _finish(x)


def synth2_tom_params(rng, electronic, brush):
    return {
        "electronic": electronic,
        "brush": brush,
        "tau": _logu(rng, 0.1, 0.8),
        "sweep": rng.uniform(1.0, 1.8 if electronic else 1.35),
        "tau_sweep": rng.uniform(0.01, 0.12),
        "modes": [(rng.uniform(1.45, 1.75), rng.uniform(0.05, 0.5)), (rng.uniform(1.95, 2.4), rng.uniform(0.0, 0.3))],
        "stick": _logu(rng, 0.02, 0.7),  # stick attack noise (toms with a bright attack)
        "stick_band": (rng.uniform(600, 3000), rng.uniform(5000, 12000)),
        "buzz": rng.uniform(0.05, 0.35) if rng.random() < 0.5 else 0.0,  # sympathetic snare wires
        "buzz_colour": _noise_colour(rng),
        "noise_body": rng.uniform(0.1, 0.6) if electronic and rng.random() < 0.5 else 0.0,
    }


def synth2_tom(rng, f0, p, layer):
    n = int(min(1.0, 4 * p["tau"] + 0.1) * SR)
    t = np.arange(n) / SR
    x = _sweep(f0 * p["sweep"], f0, p["tau_sweep"], n) * np.exp(-t / p["tau"])
    for r, g in p["modes"]:
        x += g * _sweep(f0 * r * 1.05, f0 * r, 0.03, n) * np.exp(-t / (0.4 * p["tau"]))
    x = x / max(1e-9, float(np.max(np.abs(x))))
    stick = p["stick"] * (0.4 if layer == 0 else 1.0) * (0.3 if p["brush"] else 1.0)
    x += stick * _click(rng, n, *p["stick_band"], rng.uniform(0.002, 0.01))
    if p["buzz"]:
        x += p["buzz"] * _coloured_noise(rng, n, p["buzz_colour"]) * np.exp(-t / rng.uniform(0.04, 0.2))
    if p["noise_body"]:
        x += p["noise_body"] * _band_noise(rng, n, f0 * 2, f0 * 20) * np.exp(-t / (0.3 * p["tau"]))
    x = _finish(x)
    return _darken(x, rng.uniform(1500, 4000)) if layer == 0 else x


def synth2_cymbal(rng, kind, metal_scale, metallic, low):
    """Like synth_cymbal with wider colours: `low` kits let the noise reach down to 700 Hz
    (hats and crashes with energy in the snare's range), with a stick attack."""
    length = {"closed": 0.25, "pedal": 0.2, "open": 1.0, "ride": 2.0, "bell": 2.0, "crash": 2.5,
              "splash": 1.0, "china": 2.0}[kind]
    n = int(length * SR)
    t = np.arange(n) / SR
    lo_hat = (_logu(rng, 700, 4000) if low else _logu(rng, 3000, 10000))
    lo, hi, tau = {
        "closed": (lo_hat, rng.uniform(10000, 17000), _logu(rng, 0.01, 0.09)),
        "pedal": (lo_hat, rng.uniform(9000, 15000), _logu(rng, 0.01, 0.05)),
        "open": (lo_hat, rng.uniform(10000, 17000), _logu(rng, 0.15, 0.8)),
        "ride": (_logu(rng, 1200, 6000), 15000, _logu(rng, 0.5, 2.0)),
        "bell": (_logu(rng, 1000, 3000), 12000, _logu(rng, 0.5, 1.8)),
        "crash": (_logu(rng, 600 if low else 1500, 4500), 16000, _logu(rng, 0.5, 2.5)),
        "splash": (_logu(rng, 1000, 5000), 16000, _logu(rng, 0.15, 0.7)),
        "china": (_logu(rng, 500, 2000), 12000, _logu(rng, 0.4, 1.6)),
    }[kind]
    x = _cymbal_noise(rng, n, lo, hi, tau, metallic, metal_scale)
    if rng.random() < 0.5:
        x = _resonate(x, [_logu(rng, 2000, 12000) for _ in range(3)], rng.uniform(1, 3))
    if kind in ("ride", "bell"):
        fb = rng.uniform(500, 1300)
        x += (0.6 if kind == "bell" else 0.15) * sum(
            np.sin(2 * np.pi * fb * r * t) for r in (1.0, 2.76, 5.4)) / 3 * np.exp(-t / rng.uniform(0.4, 1.0))
    if kind in ("closed", "pedal", "ride") and rng.random() < 0.6:  # stick tip / chick
        x = x / max(1e-9, float(np.max(np.abs(x)))) + rng.uniform(0.1, 0.8) * _click(rng, n, 1000, 12000, 0.002)
    k = int(0.002 * SR)
    x[:k] *= np.linspace(0, 1, k)  # no DC step
    return _finish(x)


def synth2_kit(rng):
    """note -> {"layers": [[variant, variant] per velocity layer], "pan": p}, levels, name."""
    electronic = bool(rng.random() < 0.3)
    brush = bool(not electronic and rng.random() < 0.2)
    metallic = bool(rng.random() < 0.5)
    low = bool(rng.random() < 0.5)
    mscale = _logu(rng, 0.6, 2.5)

    def const(x):
        return [[x, x] for _ in SYNTH2_LAYERS]

    def layered(make):
        return [[make(l), make(l)] for l in range(len(SYNTH2_LAYERS))]

    kick, kick2 = synth_kick(rng), synth_kick(rng)
    dk = rng.uniform(1500, 5000)
    kit = {36: (layered(lambda l: _darken(kick, dk) if l == 0 else kick), 0.0),
           35: (layered(lambda l: _darken(kick2, dk) if l == 0 else kick2) if rng.random() < 0.3 else None, 0.0)}
    if kit[35][0] is None:
        kit[35] = kit[36]
    sp = synth2_snare_params(rng, brush)
    kit[38] = (layered(lambda l: synth2_snare(rng, sp, l)), -0.1)
    if rng.random() < 0.5:  # 40 as a rim shot
        kit[40] = ([[synth2_snare(rng, sp, 0)] * 2, [synth2_snare(rng, sp, 1)] * 2,
                    [synth2_rimshot(rng, sp), synth2_rimshot(rng, sp)]], -0.1)
    elif rng.random() < 0.5:  # 40 a second snare
        sp2 = synth2_snare_params(rng, brush)
        kit[40] = (layered(lambda l: synth2_snare(rng, sp2, l)), -0.1)
    else:
        kit[40] = kit[38]
    kit[37] = (const(synth2_cross_stick(rng)) if rng.random() < 0.7 else const(synth_rim(rng)), -0.05)
    tp = synth2_tom_params(rng, electronic, brush)
    base = _logu(rng, 55, 170)
    step = rng.uniform(1.1, 1.45)
    for k, (note, pan) in enumerate(zip((41, 43, 45, 47, 48, 50), (-0.5, -0.35, -0.1, 0.1, 0.3, 0.45))):
        f0 = base * step ** k
        kit[note] = (layered(lambda l: synth2_tom(rng, f0, tp, l)), pan)
    for note, kind, pan in ((42, "closed", 0.4), (44, "pedal", 0.4), (46, "open", 0.4), (51, "ride", -0.4),
                            (53, "bell", -0.4), (59, "ride", -0.4), (49, "crash", 0.3), (57, "crash", -0.3),
                            (55, "splash", 0.2), (52, "china", -0.2)):
        a, b = synth2_cymbal(rng, kind, mscale, metallic, low), synth2_cymbal(rng, kind, mscale, metallic, low)
        dc = rng.uniform(2000, 6000)
        kit[note] = ([[_darken(a, dc), _darken(b, dc)], [a, b], [a, b]], pan)
    levels = {35: 1.0, 36: 1.0, 37: 0.6, 38: 0.9, 40: 0.9, 42: 0.35, 44: 0.3, 46: 0.4, 51: 0.35, 53: 0.4,
              59: 0.35, 49: 0.55, 57: 0.55, 55: 0.45, 52: 0.5}
    for n in levels:
        levels[n] *= 10 ** (rng.uniform(-5, 5) / 20)
    if brush:
        levels[38] *= 0.7
        levels[40] *= 0.7
    name = ("elec" if electronic else "brush" if brush else "acou") + ("-metal" if metallic else "-noise") + \
        ("-low" if low else "")
    return kit, levels, name


def synth2_render(hits_s, kit, levels, n_samples, seed):
    rr = np.random.default_rng(seed ^ 0x5EED)

    def sample_of(n, v):
        layers, pan = kit[n]
        l = next(i for i, top in enumerate(SYNTH2_LAYERS) if v <= top)
        return layers[l][int(rr.integers(0, 2))], pan

    return _mix_hits(hits_s, levels, n_samples, sample_of)


def remix_render(rng, hits_s, remix, remix_db, sy_kit, sy_levels, n_samples, bpm, reverb, seed, tmp):
    """A kit of pieces from different training sources: each class's hits rendered by its
    source (a TimGM6mb or sf_GMbank preset through fluidsynth, or the synth2 kit), peak
    normalised, set to the class's level +-4 dB and summed."""
    y = np.zeros((n_samples, 2))
    exact = []
    for c, (src, preset) in remix.items():
        hs = [h for h in hits_s if DRUM_BANDS.get(h[1]) == c]
        if not hs:
            continue
        if src == "synth2":
            part, ex = synth2_render(hs, sy_kit, sy_levels, n_samples, seed + len(c))
            if reverb:
                part = simple_reverb(rng, part)
        else:
            mp_ = os.path.join(tmp, f"drums_{c}.mid")
            ex = write_drum_midi(mp_, hs, bpm, preset)
            x = fluid_render(os.path.join(SF2_DIR, FAMILY_SF2[src]), mp_, os.path.join(tmp, f"drums_{c}.wav"), reverb)
            part = np.zeros((n_samples, 2))
            part[: min(n_samples, len(x))] = x[:n_samples]
        part = part / max(1e-9, float(np.max(np.abs(part)))) * REMIX_LEVELS[c] * 10 ** (remix_db[c] / 20)
        y += part
        exact += ex
    return y, sorted(exact)


def choke_source(song):
    """The training source of a `choke` song (its name's first field), else None."""
    src = song.split("-", 1)[0]
    return src if src in CHOKE_SOURCES else None


def choke_plan(rng, index, snares=False):
    """A `choke` song's kit: every sound from one training source (cycling timgm, csound,
    sonicpi), a preset for the soundfonts, and the cymbal each hat is cut from; with `snares`
    (a `choke2` song) also a retuning and a tilt for its snares."""
    src = CHOKE_SOURCES[index % len(CHOKE_SOURCES)]
    plan = {"source": src}
    if src == "sonicpi":
        plan["closed"] = str(rng.choice(CHOKE_SP_CYMBALS))
        plan["pedal"] = str(rng.choice(CHOKE_SP_CYMBALS))
        tag = "sp"
    else:
        plan["preset"] = int(rng.choice(REMIX_PRESETS))
        plan["closed"] = int(rng.choice(CHOKE_SF2_CYMBALS))
        plan["pedal"] = int(rng.choice(CHOKE_SF2_CYMBALS))
        tag = f"{plan['preset']}"
    plan["closed_tau_s"] = round(_logu(rng, 0.012, 0.07), 4)
    plan["pedal_tau_s"] = round(_logu(rng, 0.008, 0.04), 4)
    plan["semitones"] = round(float(rng.uniform(-5, 5)), 2)
    plan["tilt_db_oct"] = round(float(rng.uniform(-3, 3)), 2)
    plan["hat_db"] = round(float(rng.uniform(-12, -3)), 2)
    if snares:
        plan["snare_semitones"] = round(float(rng.uniform(-4, 4)), 2)
        plan["snare_tilt_db_oct"] = round(float(rng.uniform(-3, 3)), 2)
    plan["name"] = f"{src}-{tag}-h{plan['closed']}".replace("drum_", "").replace("_", "")
    return plan


_SF2_HITS = {}


def sf2_hit(src, preset, note, velocity, tmp):
    """One hit of a soundfont kit, rendered alone (mono, dry, from its attack, unit peak)."""
    key = (src, preset, note, velocity)
    if key not in _SF2_HITS:
        mp_ = os.path.join(tmp, "hit.mid")
        ex = write_drum_midi(mp_, [(0.1, note, velocity)], 120, preset)
        x = fluid_render(os.path.join(SF2_DIR, FAMILY_SF2[src]), mp_, os.path.join(tmp, "hit.wav"), False)
        x = x.mean(axis=1)[int(round(ex[0][0] * SR)):]
        pk = max(1e-9, float(np.max(np.abs(x))))
        first = int(np.flatnonzero(np.abs(x) > 0.02 * pk)[0])
        x = x[max(0, first - int(0.001 * SR)):int(first + 2.0 * SR)]
        _SF2_HITS[key] = x / max(1e-9, float(np.max(np.abs(x))))
    return _SF2_HITS[key]


def recoloured(x, semitones, tilt):
    """A hit retuned by `semitones` (resampled) and tilted by `tilt` dB/octave, unit peak."""
    x = _retuned(x, semitones)
    return _finish(_tilt(x, tilt) if tilt else x, 0.003)


def choked(x, tau, semitones, tilt):
    """A cymbal cut short: retuned, an exponential decay of time constant tau, tilted."""
    x = _retuned(x, semitones)
    n = min(len(x), int((6 * tau + 0.005) * SR))
    y = x[:n] * np.exp(-np.arange(n) / SR / tau)
    return _finish(_tilt(y, tilt) if tilt else y, 0.003)


def choke_render(rng, hits_s, plan, n_samples, bpm, reverb, tmp):
    """A `choke` song's drums: everything but the hats from its source as the source plays it
    (a soundfont preset through fluidsynth, or a sonic-pi kit); the closed and pedal hats are
    the planned cymbals of the same source, choked (`choked`), the open hat is the source's
    own, cut at the next closed hat; the hats' part set `hat_db` under the rest's peak. A
    `choke2` plan (`snare_semitones` in it) also recolours the snares (`recoloured`): a
    sonic-pi kit's at its own levels, a soundfont's scaled to the peak the source's own snares
    have in the song."""
    src = plan["source"]
    widen = "snare_semitones" in plan
    snares = [h for h in hits_s if widen and h[1] in CHOKE2_SNARES]
    rest = [h for h in hits_s if h[1] not in HATS and not (widen and h[1] in CHOKE2_SNARES)]
    hats = [h for h in hits_s if h[1] in HATS]
    ex_sn = []
    if src == "sonicpi":
        kit, levels, _ = sonicpi_kit(rng)
        body, ex_rest = sonicpi_render(rest, kit, levels, n_samples)
        if snares:
            def snare_of(n, v):
                soft, hard, semis, pan = kit[n]
                x = load_sample(soft if v < 70 else hard, semis)
                return recoloured(x, plan["snare_semitones"], plan["snare_tilt_db_oct"]), pan

            sn_part, ex_sn = _mix_hits(snares, levels, n_samples, snare_of)
            body = body + sn_part
        if reverb:
            body = simple_reverb(rng, body)

        def raw(name_or_note, v):
            return load_sample(name_or_note)

        open_hat = lambda v: load_sample("drum_cymbal_open")  # noqa: E731
    else:
        mp_ = os.path.join(tmp, "drums_rest.mid")
        ex_rest = write_drum_midi(mp_, rest, bpm, plan["preset"])
        x = fluid_render(os.path.join(SF2_DIR, FAMILY_SF2[src]), mp_, os.path.join(tmp, "drums_rest.wav"), reverb)
        body = np.zeros((n_samples, 2))
        body[: min(n_samples, len(x))] = x[:n_samples]

        def raw(note, v):
            return sf2_hit(src, plan["preset"], note, 60 if v < 70 else 110, tmp)

        if snares:
            mp_ = os.path.join(tmp, "drums_snares.mid")
            write_drum_midi(mp_, snares, bpm, plan["preset"])
            own = fluid_render(os.path.join(SF2_DIR, FAMILY_SF2[src]), mp_, os.path.join(tmp, "drums_snares.wav"), False)
            recol = {}

            def snare_of(n, v):
                key = (n, v >= 70)
                if key not in recol:
                    recol[key] = recoloured(raw(n, v), plan["snare_semitones"], plan["snare_tilt_db_oct"])
                return recol[key], -0.1

            sn_part, ex_sn = _mix_hits(snares, {37: 0.6, 38: 1.0, 40: 1.0}, n_samples, snare_of)
            sn_part *= float(np.max(np.abs(own))) / max(1e-9, float(np.max(np.abs(sn_part))))
            if reverb:
                sn_part = simple_reverb(rng, sn_part)
            body = body + sn_part

        open_hat = lambda v: raw(46, v)  # noqa: E731
    cut = {}

    def sample_of(n, v):
        if n == 46:
            return open_hat(v), 0.4
        which = "closed" if n == 42 else "pedal"
        key = (which, v >= 70)
        if key not in cut:
            cut[key] = choked(raw(plan[which], v), plan[f"{which}_tau_s"], plan["semitones"], plan["tilt_db_oct"])
        return cut[key], 0.4

    part, ex_hats = _mix_hits(hats, {42: 1.0, 44: 0.85, 46: 1.0}, n_samples, sample_of)
    if reverb and len(hats):
        part = simple_reverb(rng, part)
    pk = max(1e-9, float(np.max(np.abs(body))))
    part = part / max(1e-9, float(np.max(np.abs(part)))) * pk * 10 ** (plan["hat_db"] / 20)
    return body + part, sorted(ex_rest + ex_sn + ex_hats)


def simple_reverb(rng, y):
    """Exponentially decaying noise IR (stereo, decorrelated), wet -18..-12 dB."""
    tau = rng.uniform(0.12, 0.35)
    n = int(tau * 5 * SR)
    t = np.arange(n) / SR
    out = y.copy()
    wet = 10 ** (rng.uniform(-18, -12) / 20)
    for c in range(2):
        ir = rng.standard_normal(n) * np.exp(-t / tau)
        ir[: int(0.01 * SR)] = 0
        ir *= wet / np.sqrt(np.sum(ir ** 2))
        m = len(y) + n - 1
        nfft = 1 << (m - 1).bit_length()
        out[:, c] += np.fft.irfft(np.fft.rfft(y[:, c], nfft) * np.fft.rfft(ir, nfft), nfft)[: len(y)]
    return out


def rms(x):
    return float(np.sqrt(np.mean(x ** 2))) + 1e-12


# ---------------------------------------------------------------------------------------


def song_plan(family, index):
    """Kit, style, seed for song `index` of `family` (deterministic)."""
    seed = seed_of("tactus-drums-v1", family, index)
    if family in ("sonicpi", "synth", "synth2", "remix", *CHOKE_FAMILIES):
        kit = None
    else:
        kit = KIT_ORDER[index] if index < len(KIT_ORDER) else ACOUSTIC_KITS[index % len(ACOUSTIC_KITS)]
    style = STYLE_ORDER[(index + FAMILIES.index(family) * 5) % len(STYLE_ORDER)] if index < 24 else None
    return seed, kit, style


def write_song_dir(parent, song, final, ints, mix_i, truth):
    """Writes a song folder: the 16-bit stems `ints`, the mix `mix_i` and truth.json go into
    a hidden staging folder in `parent`, which is then renamed to `final` (replacing it), so
    a song folder is either complete or absent."""
    stage = os.path.join(parent, f".{song}.tmp")
    shutil.rmtree(stage, ignore_errors=True)
    os.makedirs(stage)
    for k, v in list(ints.items()) + [("mix", mix_i)]:
        sf.write(os.path.join(stage, f"{k}.wav"), v.astype(np.int16), SR, subtype="PCM_16")
    with open(os.path.join(stage, "truth.json"), "w") as fh:
        json.dump(truth, fh, separators=(",", ":"))
        fh.write("\n")
    if os.path.exists(final):
        shutil.rmtree(final)
    os.rename(stage, final)


def build_song(args):
    family, index, out_dir, force = args
    seed, kit, style = song_plan(family, index)
    rng = np.random.default_rng(seed)
    if style is None:
        style = str(rng.choice(list(STYLES)))
    if kit in (24, 25) and style in ("swing", "train"):
        style = "rock8"
    if kit == 40 and rng.random() < 0.5:
        style = "train" if STYLES[style][1] == 4 else "swing"
    if family == "sonicpi":
        sp_kit, sp_levels, kit_name = sonicpi_kit(rng)
        song = f"{kit_name}_s{index:02d}"
    elif family == "synth":
        sy_kit, sy_levels, kit_name = synth_kit(rng)
        song = f"{kit_name}_s{index:02d}"
    elif family == "synth2":
        sy_kit, sy_levels, kit_name = synth2_kit(rng)
        song = f"{kit_name}_s{index:02d}"
    elif family == "remix":
        sy_kit, sy_levels, _ = synth2_kit(rng)
        remix = {c: (str(rng.choice(REMIX_SOURCES)), int(rng.choice(REMIX_PRESETS))) for c in CLASSES}
        remix_db = {c: float(rng.uniform(-4, 4)) for c in CLASSES}
        kit_name = "-".join(s[0][:2] + ("" if s[0] == "synth2" else str(s[1])) for s in remix.values())
        song = f"{kit_name}_s{index:02d}"
    elif family in CHOKE_FAMILIES:
        ch = choke_plan(rng, index, snares=family == "choke2")
        song = f"{ch['name']}_s{index:02d}"
    else:
        kit_name = f"{KIT_ABBR[kit]}{kit:02d}"
        song = f"{kit_name}_s{index:02d}"
    fam_dir = os.path.join(out_dir, family)
    final = os.path.join(fam_dir, song)
    if os.path.exists(os.path.join(final, "truth.json")) and not force:
        return family, song, final, "exists", 0.0
    t0 = time.time()
    bpb, sub, (lo, hi), meter = STYLES[style]
    bpm = int(rng.integers(max(70, lo), min(180, hi) + 1))
    target_s = float(rng.uniform(20.0, 30.0))
    hits_b, flams, n_bars, end_beat = groove(rng, style, bpm, kit, target_s)
    hits_s = humanise(rng, hits_b, flams, bpm)
    hits_s = [h for h in hits_s if h[0] > 0.01]
    parts, harmony = backing(rng, style, n_bars, bpm, hits_b)
    progs = {"bass": int(rng.choice(BASS_PROGRAMS)), "other": int(rng.choice(CHORD_PROGRAMS)),
             "vocals": int(rng.choice(LEAD_PROGRAMS))}
    reverb = bool(rng.random() < 0.5)
    duration = end_beat * 60.0 / bpm + TAIL_S
    n_samples = int(round(duration * SR))
    n_frames = int(math.ceil(duration / HOP_S))

    tmp = tempfile.mkdtemp(prefix="tactus-drums-")
    try:
        audio, mids = {}, {}
        if family == "sonicpi":
            y, exact = sonicpi_render(hits_s, sp_kit, sp_levels, n_samples)
            if reverb:
                y = simple_reverb(rng, y)
            audio["drums"] = y
            kit_desc = {"samples": {str(n): list(v[:3]) for n, v in sorted(sp_kit.items())}, "dir": SONICPI_DIR}
        elif family == "synth":
            y, exact = synth_render(hits_s, sy_kit, sy_levels, n_samples)
            if reverb:
                y = simple_reverb(rng, y)
            audio["drums"] = y
            kit_desc = {"synthesised": kit_name, "seed": seed}
        elif family == "synth2":
            y, exact = synth2_render(hits_s, sy_kit, sy_levels, n_samples, seed)
            if reverb:
                y = simple_reverb(rng, y)
            audio["drums"] = y
            kit_desc = {"synthesised2": kit_name, "seed": seed}
        elif family in CHOKE_FAMILIES:
            y, exact = choke_render(rng, hits_s, ch, n_samples, bpm, reverb, tmp)
            audio["drums"] = y
            kit_desc = {"choke": {k: v for k, v in ch.items() if k != "name"}, "seed": seed}
        elif family == "remix":
            y, exact = remix_render(rng, hits_s, remix, remix_db, sy_kit, sy_levels, n_samples, bpm, reverb,
                                    seed, tmp)
            audio["drums"] = y
            kit_desc = {"remix": {c: {"source": s, "preset": k if s != "synth2" else None,
                                      "level_db": round(remix_db[c], 2)} for c, (s, k) in remix.items()},
                        "seed": seed}
        else:
            sf2 = os.path.join(SF2_DIR, FAMILY_SF2[family])
            mp_ = os.path.join(tmp, "drums.mid")
            exact = write_drum_midi(mp_, hits_s, bpm, kit)
            x = fluid_render(sf2, mp_, os.path.join(tmp, "drums.wav"), reverb)
            y = np.zeros((n_samples, 2))
            y[: min(n_samples, len(x))] = x[:n_samples]
            audio["drums"] = y
            kit_desc = {"soundfont": FAMILY_SF2[family], "bank": 128, "preset": kit}
        chans = {"vocals": 0, "bass": 1, "other": 2}
        bends = vibrato_bends(parts["vocals"], bpm, seed)
        for stem in ("bass", "other", "vocals"):
            mp_ = os.path.join(tmp, f"{stem}.mid")
            mids[stem] = write_midi(mp_, parts[stem], bpm, chans[stem], progs[stem],
                                    bends if stem == "vocals" else None)
            x = fluid_render(BACKING_SF2, mp_, os.path.join(tmp, f"{stem}.wav"), reverb)
            y = np.zeros((n_samples, 2))
            y[: min(n_samples, len(x))] = x[:n_samples]
            audio[stem] = y
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    # relative levels: each backing stem at its RMS times a random gain, drums -3..+3 dB
    # around the backing's RMS; then one gain for all so that the mix peaks at -1 dBFS
    gains_db = {"bass": float(rng.uniform(-4, 0)), "other": float(rng.uniform(-7, -1)),
                "vocals": float(rng.uniform(-4, 0)), "drums_vs_backing": float(rng.uniform(-3, 3))}
    for stem in ("bass", "other", "vocals"):
        audio[stem] = audio[stem] / rms(audio[stem]) * 10 ** (gains_db[stem] / 20)
    back = audio["bass"] + audio["other"] + audio["vocals"]
    audio["drums"] = audio["drums"] / rms(audio["drums"]) * rms(back) * 10 ** (gains_db["drums_vs_backing"] / 20)
    mix = back + audio["drums"]
    gain = (10 ** (-1 / 20)) / max(1e-9, float(np.max(np.abs(mix))))
    ints = {k: np.round(v * gain * 32767.0).astype(np.int32) for k, v in audio.items()}
    mix_i = sum(ints.values())
    assert np.max(np.abs(mix_i)) <= 32767, "mix clips"

    hits = [{"time_s": round(t, 9), "velocity": int(v), "note": int(n), "class": DRUM_BANDS[n]}
            for t, n, v in sorted(exact)]
    onsets = class_onsets(hits)
    truth = {
        "format": "tactus-truth",
        "version": 1,
        "song": f"{family}/{song}",
        "source": "corpus/drums.py",
        "family": family,
        "held_out": family in HELD_OUT,
        "kit": kit_desc,
        "style": style,
        "meter": meter,
        "tempo_bpm": bpm,
        "reverb": reverb,
        "harmony": harmony,
        "gains_db": {k: round(v, 2) for k, v in gains_db.items()},
        "programs": progs,
        "sample_rate": SR,
        "channels": 2,
        "duration_s": n_samples / SR,
        "hop_s": HOP_S,
        "audio_format": "wav",
        "f0_hz": {
            "vocals": [round(v, 4) for v in f0_track(mids["vocals"], n_frames)],
            "bass": [round(v, 4) for v in f0_track(mids["bass"], n_frames)],
            "other": [round(v, 4) for v in f0_track(mids["other"], n_frames, top_line=True)],
        },
        "f0_notes": {"other": "top line of the polyphonic chords", "vocals": "the lead melody"},
        "onsets": onsets,
        "onsets_rule": ONSETS_RULE,
        "hits": hits,
    }
    os.makedirs(fam_dir, exist_ok=True)
    write_song_dir(fam_dir, song, final, ints, mix_i, truth)
    return family, song, final, f"{style} {meter} {bpm} bpm {duration:.1f} s, " + \
        " ".join(f"{c}={len(onsets[c])}" for c in CLASSES), time.time() - t0


def kit_similarity(tmp):
    """Prints how alike the soundfont families' drum sounds are: peak normalised
    cross-correlation of single hits (velocity 100, first 180 ms, mono) between families."""
    pairs = [("fluid", "musescore"), ("timgm", "csound"), ("fluid", "timgm"), ("musescore", "csound")]
    print("kit note " + " ".join(f"{a}~{b}" for a, b in pairs))
    win = int(0.18 * SR)
    for kit in (0, 8, 16, 25, 32, 40):
        for n in (36, 38, 37, 41, 45, 48, 42, 46, 51, 49, 57):
            xs = {}
            for fam in ("fluid", "musescore", "timgm", "csound"):
                mp_ = os.path.join(tmp, "sim.mid")
                ex = write_drum_midi(mp_, [(0.5, n, 100)], 120, kit)
                x = fluid_render(os.path.join(SF2_DIR, FAMILY_SF2[fam]), mp_, os.path.join(tmp, "sim.wav"), False)
                i = int(round(ex[0][0] * SR))
                x = x.mean(axis=1)[i : i + win]
                xs[fam] = x / max(1e-12, float(np.linalg.norm(x)))
            row = [float(np.max(np.abs(np.correlate(xs[a], xs[b], "full")))) for a, b in pairs]
            print(f"{kit:3d} {n:3d} " + " ".join(f"{v:.3f}" for v in row), flush=True)


MERGE_S = 0.030
ONSETS_RULE = (f"onsets.<class>: the class's hits with those less than {MERGE_S * 1000:g} ms after the previous "
               "kept hit of the same class merged into it (time of the first, velocity and note of the loudest): "
               "flam grace notes, pedal hat under the ride, hat under a crash; `hits` lists every MIDI hit")


def class_onsets(hits):
    """Per-class onsets from the per-hit list: same-class hits closer than MERGE_S to the
    previous kept one are merged (one perceived onset; a class-level detector can fire once)."""
    out = {c: [] for c in CLASSES}
    for h in sorted(hits, key=lambda h: (h["time_s"], -h["velocity"])):
        lst = out[h["class"]]
        if lst and h["time_s"] - lst[-1]["time_s"] < MERGE_S:
            if h["velocity"] > lst[-1]["velocity"]:
                lst[-1] = {"time_s": lst[-1]["time_s"], "velocity": h["velocity"], "note": h["note"]}
            continue
        lst.append({"time_s": h["time_s"], "velocity": h["velocity"], "note": h["note"]})
    return out


def update_truth(out):
    """Recompute `onsets` from the per-hit list in every truth.json under out (audio untouched)."""
    for d in song_dirs(out):
        path = os.path.join(d, "truth.json")
        truth = json.load(open(path))
        hits = truth.get("hits") or sorted(
            ({**h, "class": c} for c, hs in truth["onsets"].items() for h in hs),
            key=lambda h: (h["time_s"], h["note"]))
        truth["onsets"] = class_onsets(hits)
        truth["onsets_rule"] = ONSETS_RULE
        truth["hits"] = hits
        tmp = path + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(truth, fh, separators=(",", ":"))
            fh.write("\n")
        os.replace(tmp, path)
        print(d, {c: f"{len(v)}/{sum(1 for h in hits if h['class'] == c)}" for c, v in truth["onsets"].items()})


def song_dirs(out):
    res = []
    for fam in sorted(os.listdir(out)) if os.path.isdir(out) else []:
        d = os.path.join(out, fam)
        if not os.path.isdir(d):
            continue
        for s in sorted(os.listdir(d)):
            if not s.startswith(".") and os.path.exists(os.path.join(d, s, "truth.json")):
                res.append(os.path.join(d, s))
    return res


def write_ready(out):
    dirs = song_dirs(out)
    tmp = os.path.join(out, "READY.tmp")
    with open(tmp, "w") as fh:
        fh.write("\n".join(dirs) + "\n")
    os.replace(tmp, os.path.join(out, "READY"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--songs", type=int, default=12, help="songs per family (default 12)")
    ap.add_argument("--first", type=int, default=0,
                    help="render only song indices from this one up to --songs (default 0)")
    ap.add_argument("--families", default=",".join(DEFAULT_FAMILIES))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--force", action="store_true", help="re-render songs that exist")
    ap.add_argument("--ready-at", type=int, default=6,
                    help="write OUT/READY once every family has this many songs (and again at the end)")
    ap.add_argument("--similarity", action="store_true",
                    help="print how alike the soundfont families' drum samples are, then exit")
    ap.add_argument("--update-truth", action="store_true",
                    help="recompute onsets (merge rule) in every truth.json under --out; audio untouched")
    args = ap.parse_args()
    if args.update_truth:
        update_truth(args.out)
        return
    if args.similarity:
        tmp = tempfile.mkdtemp(prefix="tactus-drums-")
        try:
            kit_similarity(tmp)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return
    fams = [f for f in args.families.split(",") if f]
    for f in fams:
        if f not in FAMILIES:
            sys.exit(f"unknown family {f!r}; known: {', '.join(FAMILIES)}")
    os.makedirs(args.out, exist_ok=True)
    tasks = [(f, i, args.out, args.force) for i in range(args.first, args.songs) for f in fams]
    counts = {f: 0 for f in fams}
    ready_written = False
    t0 = time.time()
    with mp.Pool(args.jobs) as pool:
        for k, (fam, song, path, info, dt) in enumerate(pool.imap(build_song, tasks)):
            counts[fam] += 1
            print(f"[{k + 1}/{len(tasks)} {time.time() - t0:6.1f}s] {fam}/{song}: {info} ({dt:.1f} s)", flush=True)
            if not ready_written and all(c >= args.ready_at for c in counts.values()):
                write_ready(args.out)
                ready_written = True
                print(f"wrote {os.path.join(args.out, 'READY')}", flush=True)
    write_ready(args.out)
    print(f"done: {len(song_dirs(args.out))} songs under {args.out} ({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
