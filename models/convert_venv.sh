# Sourced (not run) by setup_adtlib.sh and setup_models.sh, with ROOT and OUT set and the
# caller's arguments: keeps a cached $OUT (unless --force), makes sure the ONNX Runtime
# wheel is downloaded (setup_onnxruntime.sh), and leaves $VENV with numpy + onnx (which
# build the graph) and onnxruntime (which runs the self-check against a numpy forward
# pass) installed.
VENV="$ROOT/models/.venv"
if [ -f "$OUT" ] && [ "${1:-}" != "--force" ]; then
    echo "cached: $OUT"
    exit 0
fi
"$ROOT/models/setup_onnxruntime.sh" >/dev/null
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
fi
"$VENV/bin/pip" install -q "numpy>=1.24" "onnx>=1.16,<2" \
    "$(ls "$ROOT"/wheels/onnxruntime-1.31.1-*.whl | head -n 1)"
