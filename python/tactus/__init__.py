"""Tactus from Python: songs (files or NumPy arrays) to haptic glove patterns.

The same engine as the ``tactus`` command line, in-process::

    import tactus
    r = tactus.render("song.mp3")                 # options as the CLI's: separator=, bin_ms=, ...
    r.frames.shape                                # (bins, 10): one byte per cell, uint8
    r.pitch_hz["bass"], r.onsets_s["kick"]        # NumPy arrays per stem / drum class
    print(r.report())                             # stage costs and the latency budget

    r2 = tactus.render_array(samples, 44100)      # samples: (n,), (n, channels) or (channels, n)

``r.frames`` equals the CLI pattern file's ``frames`` byte for byte. Errors raise
:class:`TactusError` with the CLI's one-line message, naming options as keyword arguments
(``levels``, not ``--levels``). The GIL is released while rendering,
so threads render in parallel. :mod:`tactus.eval` has the metrics, :mod:`tactus.ray` the
library job on a Ray cluster.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Tuple, Union

import numpy as np

from . import _native
from ._native import TactusError

__all__ = ["render", "render_array", "Result", "TactusError", "OPTIONS", "__version__"]
__version__: str = _native.__version__

#: The keyword options of :func:`render` and :func:`render_array`, named as the CLI's flags
#: (``bin_ms`` is ``--bin-ms``). Defaults are the CLI's ``render`` defaults.
OPTIONS: Tuple[str, ...] = (
    "separator",  # "spectral" (default) | "htdemucs" | "spleeter" | "none"
    "model",  # ONNX model path for htdemucs / spleeter
    "bin_ms",  # bin length in ms, default 100
    "levels",  # pitch levels per melodic stem, 1..8, default 8
    "map",  # built-in map name or TOML map path
    "pitch",  # "auto" (default) | "auto-shs" | "yin" | "pyin" | "shs"
    "drums",  # "classes" (default) | "classes-live" | "bands" | "adtlib"
    "drum_model",  # drums="adtlib": the ONNX file; "classes"/"classes-live": a Tactus drum model file
    "levels_rule",  # "follow" (default) | "paper"
    "note_onsets",  # "attack" (default) | "legato" | "pitch"
    "kit_mask",  # "on" (default) | "off": the separator's learned kit mask
    "mode",  # "offline" (default) | "streaming"
    "stems",  # {"drums"|"bass"|"vocals"|"other": path}: supplied stems (render only)
    "threads",  # ONNX Runtime intra-op threads
)

PathLike = Union[str, "os.PathLike[str]"]


def _options_json(fn: str, options: Mapping[str, Any]) -> str:
    out: Dict[str, Any] = {}
    for k, v in options.items():
        if k not in OPTIONS:
            raise TypeError(f"{fn}() got an unexpected keyword argument {k!r}")
        if v is None:
            continue
        if k == "stems":
            out[k] = [[str(name), os.fspath(p)] for name, p in dict(v).items()]
        elif k in ("model", "drum_model", "map"):
            out[k] = os.fspath(v)
        else:
            out[k] = v
    return json.dumps(out)


@dataclass
class Result:
    """What a render returns.

    Attributes:
        frames: ``uint8`` array of shape ``(bins, 10)``: the 10 cell bytes of each bin
            (thumb cell 0, thumb cell 1, index cell 0, ...; bit k is dot k+1), equal to
            the pattern file's ``frames``.
        bin_s: seconds per bin.
        hop_s: seconds between pitch values.
        duration_s: length of the rendered audio in seconds.
        pitch_hz: per melodic stem, ``float32`` pitch per hop (0 = unvoiced).
        levels: per melodic stem, ``uint8`` level per bin (0 = silent).
        onsets_s: per drum class / band or stem, ``float64`` onset times in seconds.
        beats: per drum class / band or stem, ``uint8`` 0/1 per bin.
        latency_ms: the streaming latency budget, ``(stage, ms)`` in pipeline order.
        stages_s: wall time per stage, ``(stage, seconds)``; the last is the total.
        warnings: what the CLI prints as warnings.
        separator: the separator that ran, if any.
        stems: the stems the engine computed.
        pattern_json: the pattern file's text (what ``render -o`` writes).
        features_json: the features file's text (what ``render --features`` writes).
    """

    frames: np.ndarray
    bin_s: float
    hop_s: float
    duration_s: float
    pitch_hz: Dict[str, np.ndarray]
    levels: Dict[str, np.ndarray]
    onsets_s: Dict[str, np.ndarray]
    beats: Dict[str, np.ndarray]
    latency_ms: List[Tuple[str, float]] = field(default_factory=list)
    stages_s: List[Tuple[str, float]] = field(default_factory=list)
    warnings: List[str] = field(default_factory=list)
    separator: Optional[str] = None
    stems: List[str] = field(default_factory=list)
    pattern_json: str = field(default="", repr=False)
    features_json: str = field(default="", repr=False)
    report_text: str = field(default="", repr=False)

    def report(self) -> str:
        """What ran, the stage costs, the speed and the latency budget: the report that
        ``tactus render --verbose`` prints (the same Rust code)."""
        return self.report_text

    def save(self, pattern: PathLike, features: Optional[PathLike] = None) -> None:
        """Writes the pattern (and features) files, as ``render -o`` / ``--features``."""
        for path, text in ((pattern, self.pattern_json), (features, self.features_json)):
            if path is None:
                continue
            path = os.fspath(path)
            tmp = f"{path}.tmp-{os.getpid()}"
            with open(tmp, "w", encoding="utf-8") as f:
                f.write(text)
            os.replace(tmp, path)


def _result(d: Dict[str, Any]) -> Result:
    def group(name: str, dtype: Any) -> Dict[str, np.ndarray]:
        return {k: np.frombuffer(v, dtype=dtype).copy() for k, v in d[name].items()}

    frames = np.frombuffer(d["frames"], dtype=np.uint8).reshape(-1, 10).copy()
    return Result(
        frames=frames,
        bin_s=d["bin_s"],
        hop_s=d["hop_s"],
        duration_s=d["duration_s"],
        pitch_hz=group("pitch_hz", "<f4"),
        levels=group("levels", np.uint8),
        onsets_s=group("onsets_s", "<f8"),
        beats=group("beats", np.uint8),
        latency_ms=[tuple(x) for x in d["latency_ms"]],
        stages_s=[tuple(x) for x in d["stages_s"]],
        warnings=list(d["warnings"]),
        separator=d["separator"],
        stems=list(d["stems"]),
        pattern_json=d["pattern_json"],
        features_json=d["features_json"],
        report_text=d["report"],
    )


def render(path: PathLike, **options: Any) -> Result:
    """Renders a song file (WAV, FLAC, MP3, OGG/Vorbis, AAC/M4A) to a glove pattern.

    Args:
        path: the song.
        **options: see :data:`OPTIONS` (the CLI's flags; ``stems`` is a dict).

    Raises:
        TactusError: with the CLI's one-line message (unreadable file, bad option named by
            its keyword, ...).
        TypeError: an unknown keyword.
    """
    opts = _options_json("render", options)
    return _result(_native.render(os.fspath(path), opts))


def _to_interleaved(samples: Any) -> Tuple[np.ndarray, int]:
    x = np.asarray(samples)
    if x.ndim == 1:
        channels = 1
    elif x.ndim == 2:
        # (channels, n) as librosa returns it, or (n, channels) as soundfile does.
        if x.shape[0] <= 8 and x.shape[1] > x.shape[0]:
            x = x.T
        channels = x.shape[1]
    else:
        raise TactusError(f"samples: expected 1 or 2 dimensions, got shape {x.shape}")
    if x.dtype == np.int16:
        x = x.astype(np.float32) / 32768.0
    elif x.dtype == np.int32:
        x = (x.astype(np.float64) / 2147483648.0).astype(np.float32)
    elif x.dtype == np.uint8:
        x = (x.astype(np.float32) - 128.0) / 128.0
    elif not np.issubdtype(x.dtype, np.floating):
        raise TactusError(f"samples: unsupported dtype {x.dtype} (use float or int16/int32)")
    return np.ascontiguousarray(x, dtype="<f4"), channels


def render_array(samples: Any, sample_rate: int, **options: Any) -> Result:
    """Renders samples held in memory.

    Args:
        samples: float (or int16/int32/uint8 PCM) array of shape ``(n,)``, ``(n, channels)``
            or ``(channels, n)`` (up to 8 channels; the first two are used as left/right).
        sample_rate: in Hz.
        **options: see :data:`OPTIONS` (not ``stems``).

    The same samples as a file's give the same frames as :func:`render` of that file.
    """
    opts = _options_json("render_array", options)
    x, channels = _to_interleaved(samples)
    return _result(_native.render_array(x.tobytes(), channels, int(sample_rate), opts))


from . import eval  # noqa: E402,F401  (tactus.eval without a separate import)
