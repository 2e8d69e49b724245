#!/usr/bin/env sh
# Builds models/adtlib.onnx (ADTLib 2.1.2 kick / snare / hi-hat onset networks) from the
# TensorFlow checkpoints in the ADTLib sdist on PyPI. Needs python3 (3.9+) and PyPI access
# (pip download / pip install); no TensorFlow, no madmom. See models/README.md ("ADTLib").
# Idempotent: an existing model is kept (delete it, or pass --force, to rebuild).
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV="$ROOT/models/.venv"
OUT="$ROOT/models/adtlib.onnx"
if [ -f "$OUT" ] && [ "${1:-}" != "--force" ]; then
    echo "cached: $OUT"
    exit 0
fi
"$ROOT/models/setup_onnxruntime.sh" >/dev/null
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
# numpy + onnx build the graph; the onnxruntime wheel (already downloaded by
# setup_onnxruntime.sh) runs the self-check against a plain numpy forward pass.
"$VENV/bin/pip" install -q "numpy>=1.24" "onnx>=1.16,<2" \
    "$(ls "$ROOT"/wheels/onnxruntime-1.31.1-*.whl | head -n 1)"
"$VENV/bin/python" "$ROOT/models/convert_adtlib.py" --out "$OUT" --sdist-dir "$ROOT/wheels" --check
