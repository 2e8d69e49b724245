"""tactus.ray on a local Ray cluster that the test starts (loopback): the same outputs
and manifest as the CLI batch, resumable the same way, a broken file reported."""

import json
import os
from pathlib import Path

import pytest

from conftest import cli, skip

try:
    import ray
except ImportError:  # pragma: no cover
    ray = None


def files(d: Path):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.is_file())


def records(d: Path):
    out = []
    for line in (d / "manifest.jsonl").read_text().splitlines():
        r = json.loads(line)
        r.pop("seconds")
        out.append(r)
    return out


@pytest.fixture(scope="module")
def cluster():
    if ray is None:
        skip("ray is not installed (pip install 'ray[data]')")
    ray.init(num_cpus=2, include_dashboard=False, configure_logging=False)
    ray.data.DataContext.get_current().enable_progress_bars = False
    yield
    ray.shutdown()


def test_ray_outputs_equal_the_cli_batch(cluster, tactus_bin, library, tmp_path):
    from tactus.ray import render_library

    r = cli(tactus_bin, "render", str(library), "--out-dir", "cli", "--with-features",
            cwd=tmp_path)
    assert r.returncode == 1 and "broken.mp3" in r.stderr, r.stderr
    s = render_library([str(library)], str(tmp_path / "ray"), features=True)
    assert s == {"ok": 3, "skipped": 0, "failed": 1}
    a, b = tmp_path / "cli", tmp_path / "ray"
    assert files(a) == files(b)
    assert "sub/deeper/three.pattern.json" in files(a)
    for f in files(a):
        if f != "manifest.jsonl":
            assert (a / f).read_bytes() == (b / f).read_bytes(), f
    assert records(a) == records(b)
    # Resume: nothing changed, nothing renders; a changed option renders everything.
    stamp = os.stat(b / "one.pattern.json").st_mtime_ns
    s = render_library([str(library)], str(b), features=True)
    assert s == {"ok": 0, "skipped": 3, "failed": 1}
    assert os.stat(b / "one.pattern.json").st_mtime_ns == stamp
    s = render_library([str(library)], str(b), features=True, levels=4)
    assert s == {"ok": 3, "skipped": 0, "failed": 1}
    # The CLI resumes from the Ray job's manifest (same records, same rule).
    r = cli(tactus_bin, "render", str(library), "--out-dir", str(b), "--with-features",
            "--levels", "4", cwd=tmp_path)
    assert "0 rendered, 3 up to date, 1 failed" in r.stderr, r.stderr
