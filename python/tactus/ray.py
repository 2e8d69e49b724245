"""A music library rendered on a Ray cluster with Ray Data, the same job as
``tactus render INPUT... --out-dir DIR``: the same plan (files, directories walked for
audio by content, globs), the same output layout (``DIR/a/b.pattern.json``, +
``.features.json``), the same ``DIR/manifest.jsonl`` and the same resume rule (a song whose
outputs exist with the same source SHA-256 and options is skipped). Each song is one Ray
task running :mod:`tactus`'s native batch job, so the bytes are the CLI's.

From Python::

    from tactus.ray import render_library
    summary = render_library(["music/"], "patterns/", address="auto", features=True)

From the shell (``tactus-ray`` is installed with the package; ``python -m tactus.ray`` too)::

    tactus-ray music/ --out-dir patterns/ --address ray://head:10001 --with-features

``--address`` is passed to ``ray.init``: leave it out to start a local cluster on this
machine (loopback), ``auto`` to join the cluster this machine belongs to (``ray start``),
``ray://HOST:10001`` for a remote cluster's client port. Every worker must see the inputs
and the output directory at the same paths (a shared file system) and have this package
installed (e.g. ``runtime_env={"pip": [...]}`` or the cluster's image).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from typing import Any, Dict, Iterable, List, Optional

from . import _native, _options_json

__all__ = ["render_library", "main"]


def _render_row(row: Dict[str, Any], out_dir: str, opts: str, features: bool,
                job_threads: int) -> Dict[str, Any]:
    record = _native.batch_job(
        row["source"], row["base"], out_dir, opts, features, job_threads,
        row["earlier"] or None,
    )
    return {"index": row["index"], "record": record}


def render_library(
    inputs: Iterable[str],
    out_dir: str,
    *,
    features: bool = False,
    address: Optional[str] = None,
    job_threads: int = 1,
    ray_init: Optional[Dict[str, Any]] = None,
    on_record: Any = None,
    **options: Any,
) -> Dict[str, int]:
    """Renders a library on Ray; returns ``{"ok": n, "skipped": n, "failed": n}``.

    Args:
        inputs: files, directories and globs, as for ``tactus render --out-dir``.
        out_dir: the output directory (shared by every worker).
        features: also write ``a/b.features.json``.
        address: the Ray cluster (``ray.init(address=...)``); ``None`` starts a local one
            unless Ray is already initialised.
        job_threads: CPUs (and engine threads) per song; 1 renders one song per core.
        ray_init: further ``ray.init`` keyword arguments.
        on_record: called with each finished record (a dict), on the driver.
        **options: the render options (see :data:`tactus.OPTIONS`; not ``stems``).
    """
    import ray

    opts = _options_json("render_library", options)
    out_dir = os.path.abspath(os.fspath(out_dir))
    inputs = [os.path.abspath(os.fspath(p)) for p in inputs]
    key = _native.batch_key(opts)  # checks the options before anything starts
    del key
    jobs, rejected = _native.batch_plan(inputs, out_dir)
    os.makedirs(out_dir, exist_ok=True)
    earlier = {str(p): r for p, r in _native.batch_read_manifest(out_dir)}
    records: List[Optional[str]] = [None] * len(jobs)
    failed_first = [_native.batch_rejected(p, why, opts) for p, why in rejected]
    summary = {"ok": 0, "skipped": 0, "failed": 0}

    def note(line: str, app: Any) -> None:
        r = json.loads(line)
        summary[r["status"]] += 1
        app.write(line + "\n")
        app.flush()
        if on_record is not None:
            on_record(r)

    with open(os.path.join(out_dir, "manifest.jsonl"), "a", encoding="utf-8") as app:
        for line in failed_first:
            note(line, app)
        if jobs:
            started = False
            if not ray.is_initialized():
                ray.init(address=address, **(ray_init or {}))
                started = True
            try:
                items = [
                    {"index": i, "source": str(s), "base": str(b),
                     "earlier": earlier.get(str(s), "")}
                    for i, (s, b) in enumerate(jobs)
                ]
                ds = ray.data.from_items(items, override_num_blocks=len(items))
                ds = ds.map(
                    _render_row,
                    fn_kwargs={"out_dir": out_dir, "opts": opts, "features": features,
                               "job_threads": job_threads},
                    num_cpus=job_threads,
                )
                for row in ds.iter_rows():
                    records[row["index"]] = row["record"]
                    note(row["record"], app)
            finally:
                if started:
                    ray.shutdown()
    done = [r for r in records if r is not None] + failed_first
    _native.batch_finish(out_dir, done)
    return summary


def main(argv: Optional[List[str]] = None) -> int:
    """``tactus-ray INPUT... --out-dir DIR [--address ADDR] [options]``."""
    p = argparse.ArgumentParser(
        prog="tactus-ray",
        description="Render a music library on a Ray cluster (the same outputs and manifest "
        "as `tactus render INPUT... --out-dir DIR`).",
    )
    p.add_argument("inputs", nargs="+", metavar="INPUT")
    p.add_argument("--out-dir", required=True, metavar="DIR")
    p.add_argument("--address", help="Ray cluster: auto, ray://HOST:10001, ... "
                   "(default: a local cluster)")
    p.add_argument("--num-cpus", type=int, help="CPUs of a local cluster")
    p.add_argument("--job-threads", type=int, default=1)
    p.add_argument("--with-features", action="store_true")
    for flag in ("separator", "model", "map", "pitch", "drums", "drum-model",
                 "levels-rule", "note-onsets", "kit-mask", "mode"):
        p.add_argument(f"--{flag}")
    p.add_argument("--bin-ms", type=int)
    p.add_argument("--levels", type=int)
    a = p.parse_args(argv)
    options = {k: getattr(a, k) for k in ("separator", "model", "map", "pitch", "drums",
                                           "drum_model", "levels_rule", "note_onsets", "kit_mask", "mode", "bin_ms",
                                           "levels")}
    init: Dict[str, Any] = {}
    if not a.address:
        # A local cluster for this job only: no dashboard (it costs CPU the songs need).
        init["include_dashboard"] = False
        if a.num_cpus:
            init["num_cpus"] = a.num_cpus
    t = time.monotonic()
    try:
        s = render_library(
            a.inputs, a.out_dir, features=a.with_features, address=a.address,
            job_threads=a.job_threads, ray_init=init,
            on_record=lambda r: r["status"] == "failed"
            and print(f"tactus: error: {r['error']}", file=sys.stderr),
            **options,
        )
    except _native.TactusError as e:
        print(f"tactus: error: {e}", file=sys.stderr)
        return 1
    secs = time.monotonic() - t
    n = sum(s.values())
    print(f"tactus: {n} songs in {secs:.1f} s ({n * 60 / max(secs, 1e-9):.1f} songs/min): "
          f"{s['ok']} rendered, {s['skipped']} up to date, {s['failed']} failed; manifest "
          f"{os.path.join(a.out_dir, 'manifest.jsonl')}", file=sys.stderr)
    return 1 if s["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
