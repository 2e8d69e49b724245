#!/usr/bin/env sh
# Installs the ONNX Runtime shared library (CPU, 1.31.1) into vendor/ without internet
# access beyond PyPI: the library is taken from the official `onnxruntime` wheel.
# Idempotent: does nothing when the library is already there.
#
#   models/setup_onnxruntime.sh
#   export ORT_DYLIB_PATH=$PWD/vendor/onnxruntime/capi/libonnxruntime.so.1.31.1
#
# ort 2.0.0-rc.15 (feature `api-31`) needs exactly this major.minor; mismatched pairs fail
# or crash inside C++ (see /work/shared/NOTES.md).
set -eu
VERSION=1.31.1
ROOT=$(cd "$(dirname "$0")/.." && pwd)
LIB="$ROOT/vendor/onnxruntime/capi/libonnxruntime.so.$VERSION"
if [ ! -f "$LIB" ]; then
    mkdir -p "$ROOT/wheels" "$ROOT/vendor"
    if ! ls "$ROOT"/wheels/onnxruntime-$VERSION-*.whl >/dev/null 2>&1; then
        python3 -m pip download --no-deps --only-binary=:all: \
            "onnxruntime==$VERSION" -d "$ROOT/wheels"
    fi
    WHL=$(ls "$ROOT"/wheels/onnxruntime-$VERSION-*.whl | head -n 1)
    python3 - "$WHL" "$ROOT/vendor" <<'PY'
import sys, zipfile
whl, dest = sys.argv[1], sys.argv[2]
with zipfile.ZipFile(whl) as z:
    names = [n for n in z.namelist() if n.startswith("onnxruntime/capi/libonnxruntime.so")]
    if not names:
        sys.exit("no libonnxruntime.so in " + whl)
    for n in names:
        z.extract(n, dest)
PY
fi
test -f "$LIB" || { echo "ONNX Runtime library missing after install: $LIB" >&2; exit 1; }
echo "ONNX Runtime $VERSION is in $LIB"
echo "export ORT_DYLIB_PATH=$LIB"
