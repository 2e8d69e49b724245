"""The Python package against the CLI: frames byte for byte, features, errors with the CLI's
messages, the GIL released while rendering, the metrics."""

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import tactus
from tactus import eval as te

from conftest import cli, song, write_wav


@pytest.fixture()
def wav(tmp_path: Path) -> Path:
    p = tmp_path / "song.wav"
    write_wav(p, song(4.0, 3))
    return p


def cli_render(tactus_bin, wav: Path, *opts: str):
    pat, feat = wav.with_suffix(".pattern.json"), wav.with_suffix(".features.json")
    r = cli(tactus_bin, "render", str(wav), "-o", str(pat), "--features", str(feat), *opts,
            cwd=wav.parent)
    assert r.returncode == 0, r.stderr
    return pat.read_text(), json.loads(feat.read_text())


def frames_of(pattern_text: str) -> np.ndarray:
    hexes = json.loads(pattern_text)["frames"]
    return np.array([list(bytes.fromhex(h)) for h in hexes], dtype=np.uint8).reshape(-1, 10)


@pytest.mark.parametrize("opts", [{}, {"bin_ms": 50, "levels": 4, "drums": "bands"}, {"kit_mask": "off"}])
def test_frames_and_features_equal_the_cli(tactus_bin, wav, opts):
    flags = []
    for k, v in opts.items():
        flags += [f"--{k.replace('_', '-')}", str(v)]
    pattern_text, feats = cli_render(tactus_bin, wav, *flags)
    r = tactus.render(wav, **opts)
    assert r.frames.dtype == np.uint8 and r.frames.shape[1] == 10
    assert r.frames.tobytes() == frames_of(pattern_text).tobytes()
    assert r.pattern_json == pattern_text
    assert r.bin_s == feats["bin_s"]
    for stem, v in feats["pitch_hz"].items():
        assert np.array_equal(r.pitch_hz[stem], np.array(v, dtype=np.float32)), stem
    for group in ("levels", "beats"):
        for k, v in feats[group].items():
            assert np.array_equal(getattr(r, group)[k], np.array(v, dtype=np.uint8)), k
    for k, v in feats["onsets_s"].items():
        assert np.array_equal(r.onsets_s[k], np.array(v, dtype=np.float64)), k
    assert set(r.onsets_s) == set(feats["onsets_s"])
    assert r.latency_ms and r.stages_s[-1][0] == "total (wall)"
    assert "latency budget" in r.report()


def test_render_array_equals_the_file_render(tactus_bin, wav):
    pattern_text, _ = cli_render(tactus_bin, wav)
    x = song(4.0, 3)
    for samples in (x, x.T, x.astype(np.float32) / 32768.0):
        r = tactus.render_array(samples, 44100)
        assert r.frames.tobytes() == frames_of(pattern_text).tobytes()
    # Another rate goes through the same resampler as a file at that rate.
    wav2 = wav.with_name("song22.wav")
    write_wav(wav2, x[::2], rate=22050)
    p2, _ = cli_render(tactus_bin, wav2)
    assert tactus.render_array(x[::2], 22050).frames.tobytes() == frames_of(p2).tobytes()


def test_errors_carry_the_cli_message(tactus_bin, tmp_path):
    missing = tmp_path / "missing.wav"
    junk = tmp_path / "junk.mp3"
    junk.write_bytes(b"\x00not audio" * 100)
    for path, extra in ((missing, {}), (junk, {})):
        flags = []
        for k, v in extra.items():
            flags += [f"--{k}", str(v)]
        r = cli(tactus_bin, "render", str(path), *flags, cwd=tmp_path)
        assert r.returncode != 0
        line = r.stderr.strip().removeprefix("tactus: error: ").removesuffix(
            " (see tactus --help)")
        with pytest.raises(tactus.TactusError) as e:
            tactus.render(path, **extra)
        assert str(e.value) == line, (extra, r.stderr)
    with pytest.raises(TypeError, match="unexpected keyword argument 'bogus'"):
        tactus.render(missing, bogus=1)


@pytest.mark.parametrize("extra, message", [
    ({"levels": 9}, "invalid value '9' for keyword argument 'levels': 9 is not in 1..=8"),
    ({"bin_ms": 0}, "invalid value '0' for keyword argument 'bin_ms': 0 is not in 1..=10000"),
    ({"separator": "xyz"}, "invalid value 'xyz' for keyword argument 'separator' "
                           "[possible values: spectral, htdemucs, spleeter, none]"),
    ({"levels_rule": "x"}, "invalid value 'x' for keyword argument 'levels_rule' "
                           "[possible values: follow, paper]"),
    ({"separator": "spleeter"}, "separator=spleeter needs model=PATH"),
    ({"drums": "adtlib"}, "drums=adtlib needs drum_model=PATH"),
    ({"drums": "bands", "drum_model": "m.onnx"}, "drum_model is for drums=classes, "),
    ({"levels": "8"}, "invalid value for keyword argument 'levels': invalid type: string"),
])
def test_option_errors_name_keyword_arguments(tmp_path, extra, message):
    # The CLI says '--levels <LEVELS>'; Python names the keyword argument. Options are
    # checked before the file is read, and the same way by render and render_array.
    for call in (lambda: tactus.render(tmp_path / "missing.wav", **extra),
                 lambda: tactus.render_array(np.zeros(4410, dtype=np.float32), 44100, **extra)):
        with pytest.raises(tactus.TactusError) as e:
            call()
        assert str(e.value).startswith(message), (extra, str(e.value))
        assert "--" not in str(e.value) and "<" not in str(e.value), str(e.value)


def test_the_gil_is_released_while_rendering(wav):
    done = threading.Event()
    spans = []

    def work():
        t = time.perf_counter()
        tactus.render(wav)
        spans.append((t, time.perf_counter()))
        done.set()

    th = threading.Thread(target=work)
    ticks = []
    th.start()
    while not done.is_set():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    th.join()
    (t0, t1), = spans
    inside = [t for t in ticks if t0 + 0.05 < t < t1 - 0.05]
    # Holding the GIL would stop this loop for the whole render (no tick inside it);
    # released, it ticks about once per millisecond.
    assert len(inside) > 0.2 * (t1 - t0 - 0.1) * 1000, (len(inside), t1 - t0)


def test_eval_metrics():
    s = te.onset_scores([1.0, 2.0, 3.0], [1.01, 2.2])
    assert s["matched"] == 1
    assert s["precision"] == pytest.approx(0.5) and s["recall"] == pytest.approx(1 / 3)
    m = te.melody_scores([0, 220, 220, 440], [0, 221, 440, 440])
    assert m["raw_pitch_accuracy"] == pytest.approx(2 / 3)
    assert m["raw_chroma_accuracy"] == pytest.approx(1.0)
    assert te.level_accuracy([1, 2, 3, 4], [1, 3, 5, 4]) == (0.5, 0.75)
    ref = np.sin(np.arange(1000) * 0.1)
    assert te.sdr_db(ref, ref + 0.01 * np.cos(np.arange(1000) * 0.37)) > 30
    with pytest.raises(tactus.TactusError):
        te.onset_scores([float("nan")], [1.0])
