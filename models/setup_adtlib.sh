#!/usr/bin/env sh
# Builds models/adtlib.onnx (ADTLib 2.1.2 kick / snare / hi-hat onset networks) from the
# TensorFlow checkpoints in the ADTLib sdist on PyPI. Needs python3 (3.9+) and PyPI access
# (pip download / pip install); no TensorFlow, no madmom. See models/README.md ("ADTLib").
# Idempotent: an existing model is kept (delete it, or pass --force, to rebuild).
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT="$ROOT/models/adtlib.onnx"
# Cache check, ONNX Runtime wheel, venv with numpy + onnx + onnxruntime.
. "$ROOT/models/convert_venv.sh"
"$VENV/bin/python" "$ROOT/models/convert_adtlib.py" --out "$OUT" --sdist-dir "$ROOT/wheels" --check
