"""Shared fixtures: songs written with the standard library's ``wave`` module, and the
``tactus`` binary these tests compare against (``TACTUS_BIN``, default
``target/release/tactus``). Under ``CI=true`` a missing binary or Ray is a failure, not a
skip."""

import os
import subprocess
import wave
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def in_ci() -> bool:
    return os.environ.get("CI") in ("true", "1")


def skip(what: str) -> None:
    if in_ci():
        pytest.fail(f"CI=true and a stand-in is missing, so this is a failure: {what}")
    pytest.skip(what)


def song(seconds: float, seed: int, rate: int = 44100) -> np.ndarray:
    """A bass tone, a melody and clicks: int16 stereo, shape (n, 2)."""
    t = np.arange(int(seconds * rate)) / rate
    note = (t * 2).astype(int) + seed
    f = 220.0 * 2.0 ** ((note % 7) / 12.0)
    phase = 2 * np.pi * np.cumsum(f) / rate
    x = 0.2 * np.sin(2 * np.pi * 55.0 * (1 + seed % 3) * t) + 0.2 * np.sin(phase)
    x += np.where(np.arange(len(t)) % (rate // 2) < 150, 0.4, 0.0)
    s = (x * 20000).astype(np.int16)
    return np.stack([s, s], axis=1)


def write_wav(path: Path, samples: np.ndarray, rate: int = 44100) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with wave.open(str(path), "wb") as w:
        w.setnchannels(samples.shape[1])
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(samples.astype("<i2").tobytes())


@pytest.fixture(scope="session")
def tactus_bin() -> Path:
    p = Path(os.environ.get("TACTUS_BIN", ROOT / "target" / "release" / "tactus"))
    if not p.is_file():
        skip(f"the tactus binary {p} is missing (cargo build --release --bin tactus)")
    return p


def cli(tactus_bin: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(tactus_bin), *args], cwd=cwd, capture_output=True, text=True)


@pytest.fixture()
def library(tmp_path: Path) -> Path:
    """lib/one.wav, lib/sub/two (no extension), lib/sub/deeper/three.wav, lib/notes.txt,
    lib/sub/broken.mp3 (random bytes)."""
    lib = tmp_path / "lib"
    write_wav(lib / "one.wav", song(3.0, 0))
    write_wav(lib / "sub" / "two.wav", song(2.5, 1))
    (lib / "sub" / "two.wav").rename(lib / "sub" / "two")
    write_wav(lib / "sub" / "deeper" / "three.wav", song(2.0, 2))
    (lib / "notes.txt").write_text("liner notes\n")
    (lib / "sub" / "broken.mp3").write_bytes(np.random.default_rng(1).bytes(4000))
    return lib
