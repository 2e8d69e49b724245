#!/usr/bin/env python3
"""Convert ADTLib 2.1.2's drum transcription networks (Southall et al.) to one ONNX graph.

ADTLib (PyPI `ADTLib==2.1.2`, sdist only) ships three TensorFlow 1.2 checkpoints,
`ADTLib/files/{Kick,Snare,Hihat}ADTLibAll.{index,data-00000-of-00001}`. They are read here
WITHOUT TensorFlow: the `.index` file is a LevelDB-style SSTable whose values are
serialized `BundleEntryProto` messages (dtype, shape, shard, offset, size); both formats
are parsed below by hand, and numpy reads each tensor's bytes from the data file. The
Adam optimiser's slot variables (`.../Adam`, `.../Adam_1`, `beta1_power`, ...) are skipped.

Network (Southall, Stables, Hockman, "Automatic drum transcription for polyphonic
recordings using soft attention mechanisms and convolutional neural networks", ISMIR 2017;
the ADTLib "SA" class, configuration 'B'), one per instrument:
  block 1: bidirectional RNN, each direction a 2-layer stack of TF `LSTMCell(20)`
           (no peepholes, no projection, forget bias 1.0), input 1024 -> output 40
           (forward and backward outputs concatenated);
  block 2: the same on block 1's 40-dim output -> 40;
  soft attention over 7 neighbouring frames (block 2's output zero-padded by [3, 3]):
      m_j = tanh([pad(out2)[t+j], out1[t]] @ A_j)      A_j: [80, 40]
      s   = softmax_j(m_j @ S_j)                        S_j: [40, 40], per feature
      z   = sum_j s_j * pad(out2)[t+j]
  dense 40 -> 2, softmax; class 0 is the onset activation.
The training graph (in the `.meta`) and the checkpoints have 7 attention taps; ADTLib's
own inference code builds 5 (attention_number=2) and would restore only part of them. We
use all 7, as trained.

Gate conversion: TF's LSTMCell kernel is [input + 20, 80] over gates (i, j, f, o) with
new_c = sigmoid(f + 1.0) * c + sigmoid(i) * tanh(j). ONNX's LSTM wants W [4H, input],
R [4H, H] in gate order (i, o, f, c) and a bias [8H] (Wb then Rb); the forget bias 1.0 is
folded into the f part of Wb.

Graph contract (written to models/adtlib.onnx, opset 17):
  input  `spec`   float32 [1, T, 1024]   magnitude spectrogram (see models/README.md)
  output `kick`   float32 [1, T]         onset activation (softmax class 0), in [0, 1]
  output `snare`  float32 [1, T]
  output `hihat`  float32 [1, T]

`--check` runs the graph with ONNX Runtime on random input and compares it with a plain
numpy forward pass (explicit per-time-step loops) of the same weights; it fails unless the
max abs difference is < 1e-5. `--fixture DIR` writes the small test fixtures used by
crates/tactus-separate/tests/onnx_adtlib.rs (spectrogram of a synthetic signal computed
with numpy exactly as madmom's `Spectrogram` does, and onnxruntime's activations on it).

Usage: python convert_adtlib.py [--out models/adtlib.onnx] [--sdist-dir wheels] [--check]
                                [--fixture DIR]
"""

import argparse
import os
import struct
import subprocess
import sys
import tarfile
import time

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

PACKAGE = "ADTLib==2.1.2"
SDIST = "ADTLib-2.1.2.tar.gz"
INSTRUMENTS = [("kick", "Kick"), ("snare", "Snare"), ("hihat", "Hihat")]
HIDDEN = 20
TAPS = 7
PAD = TAPS // 2
FORGET_BIAS = 1.0
N_BINS = 1024
FRAME = 2048
HOP = 512

# ---------------------------------------------------------------------------------------
# Fetching


def fetch_sdist(sdist_dir):
    """The ADTLib 2.1.2 sdist from PyPI through pip (cached in sdist_dir)."""
    os.makedirs(sdist_dir, exist_ok=True)
    path = os.path.join(sdist_dir, SDIST)
    if not os.path.isfile(path):
        subprocess.check_call([sys.executable, "-m", "pip", "download", "--no-deps",
                               "--no-binary", ":all:", PACKAGE,
                               "-d", sdist_dir])
    if not os.path.isfile(path):
        sys.exit(f"pip did not leave {path}")
    return path


def read_members(sdist):
    """{name: bytes} for the checkpoint files and PPParams.npy in the sdist (no extraction)."""
    out = {}
    with tarfile.open(sdist, "r:gz") as tar:
        for m in tar.getmembers():
            if m.isfile() and "/ADTLib/files/" in m.name:
                out[m.name.rsplit("/", 1)[1]] = tar.extractfile(m).read()
    return out


# ---------------------------------------------------------------------------------------
# TensorFlow checkpoint V2 reader (SSTable + BundleEntryProto), numpy only


def _varint(buf, pos):
    result = shift = 0
    while True:
        b = buf[pos]
        pos += 1
        result |= (b & 0x7F) << shift
        if b < 0x80:
            return result, pos
        shift += 7


def _proto_fields(buf):
    """Yields (field number, wire type, value) of a protobuf message (no nesting)."""
    pos = 0
    while pos < len(buf):
        key, pos = _varint(buf, pos)
        field, wire = key >> 3, key & 7
        if wire == 0:
            val, pos = _varint(buf, pos)
        elif wire == 1:
            val = buf[pos:pos + 8]
            pos += 8
        elif wire == 2:
            n, pos = _varint(buf, pos)
            val = buf[pos:pos + n]
            pos += n
        elif wire == 5:
            val = buf[pos:pos + 4]
            pos += 4
        else:
            raise ValueError(f"unsupported protobuf wire type {wire}")
        yield field, wire, val


def _block_entries(data, offset, size):
    """Key/value pairs of one LevelDB block (prefix-compressed keys, restart array)."""
    block = data[offset:offset + size]
    if data[offset + size] != 0:
        raise ValueError("compressed SSTable blocks are not supported")
    n_restarts = struct.unpack_from("<I", block, len(block) - 4)[0]
    end = len(block) - 4 - 4 * n_restarts
    pos, key = 0, b""
    while pos < end:
        shared, pos = _varint(block, pos)
        unshared, pos = _varint(block, pos)
        vlen, pos = _varint(block, pos)
        key = key[:shared] + block[pos:pos + unshared]
        pos += unshared
        yield key, block[pos:pos + vlen]
        pos += vlen


def _handle(buf, pos):
    off, pos = _varint(buf, pos)
    size, pos = _varint(buf, pos)
    return off, size, pos


DTYPES = {1: np.float32, 2: np.float64, 3: np.int32, 9: np.int64}


def read_checkpoint(index, data):
    """{variable name: numpy array} of a TF V2 checkpoint given .index and .data bytes."""
    footer = index[-48:]
    if struct.unpack_from("<Q", footer, 40)[0] != 0xDB4775248B80FB57:
        raise ValueError("not an SSTable (bad magic)")
    _, _, pos = _handle(footer, 0)  # metaindex handle (unused)
    idx_off, idx_size, _ = _handle(footer, pos)
    tensors = {}
    for _, handle in _block_entries(index, idx_off, idx_size):
        off, size, _ = _handle(handle, 0)
        for key, value in _block_entries(index, off, size):
            if key == b"":
                continue  # BundleHeaderProto
            dtype, shape, shard, offset, nbytes = None, [], 0, 0, 0
            for f, _, v in _proto_fields(value):
                if f == 1:
                    dtype = v
                elif f == 2:
                    for df, _, dv in _proto_fields(v):
                        if df == 2:
                            size_ = 0
                            for sf, _, sv in _proto_fields(dv):
                                if sf == 1:
                                    size_ = sv
                            shape.append(size_)
                elif f == 3:
                    shard = v
                elif f == 4:
                    offset = v
                elif f == 5:
                    nbytes = v
                elif f == 7:
                    raise ValueError(f"{key!r}: sliced tensors are not supported")
            if shard != 0 or dtype not in DTYPES:
                raise ValueError(f"{key!r}: shard {shard}, dtype {dtype} not supported")
            arr = np.frombuffer(data[offset:offset + nbytes], dtype=DTYPES[dtype])
            tensors[key.decode()] = arr.reshape(shape).copy()
    return tensors


def trainable(tensors):
    """Drops the optimiser state (Adam slots and power accumulators)."""
    return {k: v for k, v in tensors.items()
            if not (k.endswith("/Adam") or k.endswith("/Adam_1") or "power" in k)}


# ---------------------------------------------------------------------------------------
# Weights


def network_weights(tensors):
    """The weights of one instrument's network, named by role (float32)."""
    w = {}
    for block in (1, 2):
        for d in ("fw", "bw"):
            for layer in (0, 1):
                base = f"{block}/bidirectional_rnn/{d}/multi_rnn_cell/cell_{layer}/lstm_cell/"
                w[f"b{block}_{d}_l{layer}_kernel"] = tensors[base + "kernel"]
                w[f"b{block}_{d}_l{layer}_bias"] = tensors[base + "bias"]
    # tf.Variable creation order in ADTLib's SA.create(): biases, dense weights, then for
    # each attention tap j an attention matrix [80, 40] and a softmax matrix [40, 40].
    w["dense_b"] = tensors["Variable"]
    w["dense_w"] = tensors["Variable_1"]
    for j in range(TAPS):
        w[f"att{j}"] = tensors[f"Variable_{2 + 2 * j}"]
        w[f"sm{j}"] = tensors[f"Variable_{3 + 2 * j}"]
    expect = {"dense_b": (2,), "dense_w": (2 * HIDDEN, 2)}
    for j in range(TAPS):
        expect[f"att{j}"] = (4 * HIDDEN, 2 * HIDDEN)
        expect[f"sm{j}"] = (2 * HIDDEN, 2 * HIDDEN)
    for k, s in expect.items():
        if w[k].shape != s:
            raise ValueError(f"{k}: shape {w[k].shape}, expected {s}")
    if f"Variable_{2 + 2 * TAPS}" in tensors:
        raise ValueError("more attention taps in the checkpoint than expected")
    return {k: v.astype(np.float32) for k, v in w.items()}


def onnx_lstm_params(kernel, bias):
    """TF LSTMCell kernel [in + H, 4H] (gates i, j, f, o) and bias [4H] -> ONNX W [1, 4H, in],
    R [1, 4H, H], B [1, 8H] in gate order (i, o, f, c), forget bias folded into B."""
    h = HIDDEN
    n_in = kernel.shape[0] - h
    gi, gj, gf, go = (slice(k * h, (k + 1) * h) for k in range(4))
    order = [gi, go, gf, gj]
    wx, wh = kernel[:n_in], kernel[n_in:]
    W = np.concatenate([wx[:, g].T for g in order], 0)[None]
    R = np.concatenate([wh[:, g].T for g in order], 0)[None]
    b = bias.copy()
    b[gf] += FORGET_BIAS
    Wb = np.concatenate([b[g] for g in order])
    B = np.concatenate([Wb, np.zeros(4 * h, np.float32)])[None]
    return W.astype(np.float32), R.astype(np.float32), B.astype(np.float32)


# ---------------------------------------------------------------------------------------
# ONNX graph


def build_graph(weights_by_inst):
    nodes, inits = [], []

    def const(name, arr):
        inits.append(numpy_helper.from_array(np.asarray(arr), name))
        return name

    def node(op, inputs, name, **attrs):
        nodes.append(helper.make_node(op, inputs, [name], name=name, **attrs))
        return name

    const("axes0", np.array([0], np.int64))
    const("axes1", np.array([1], np.int64))
    # [1, T, 1024] -> [T, 1, 1024] (ONNX LSTM layout 0: seq, batch, feature)
    x = node("Transpose", ["spec"], "x_tbf", perm=[1, 0, 2])
    outputs = []
    for inst, w in weights_by_inst:
        p = inst + "_"
        block_in = x
        block_outs = []
        for block in (1, 2):
            dirs = []
            for d in ("fw", "bw"):
                h = block_in
                for layer in (0, 1):
                    key = f"b{block}_{d}_l{layer}"
                    W, R, B = onnx_lstm_params(w[key + "_kernel"], w[key + "_bias"])
                    names = [const(p + key + s, a) for s, a in (("_W", W), ("_R", R), ("_B", B))]
                    y = node("LSTM", [h] + names, p + key + "_Y", hidden_size=HIDDEN,
                             direction="forward" if d == "fw" else "reverse")
                    # Y: [T, 1, 1, H] -> [T, 1, H]
                    h = node("Squeeze", [y, "axes1"], p + key + "_h")
                dirs.append(h)
            block_in = node("Concat", dirs, f"{p}b{block}_out", axis=2)  # [T, 1, 40]
            block_outs.append(block_in)
        out1 = node("Squeeze", [block_outs[0], "axes1"], p + "out1")  # [T, 40]
        out2 = node("Squeeze", [block_outs[1], "axes1"], p + "out2")
        const(p + "pads", np.array([PAD, 0, PAD, 0], np.int64))
        zp = node("Pad", [out2, p + "pads"], p + "zp")  # [T + 6, 40]
        logits, windows = [], []
        for j in range(TAPS):
            end = j - 2 * PAD  # negative: zp[j : len - (2*PAD - j)]
            const(f"{p}st{j}", np.array([j], np.int64))
            const(f"{p}en{j}", np.array([end if end < 0 else 2**62], np.int64))
            win = node("Slice", [zp, f"{p}st{j}", f"{p}en{j}", "axes0"], f"{p}win{j}")
            cat = node("Concat", [win, out1], f"{p}cat{j}", axis=1)  # [T, 80]
            mm = node("MatMul", [cat, const(f"{p}att{j}", w[f"att{j}"])], f"{p}attmm{j}")
            m = node("Tanh", [mm], f"{p}m{j}")
            lg = node("MatMul", [m, const(f"{p}sm{j}", w[f"sm{j}"])], f"{p}lg{j}")
            logits.append(node("Unsqueeze", [lg, "axes0"], f"{p}lgu{j}"))
            windows.append(node("Unsqueeze", [win, "axes0"], f"{p}winu{j}"))
        s = node("Softmax", [node("Concat", logits, p + "lgs", axis=0)], p + "s", axis=0)
        wins = node("Concat", windows, p + "wins", axis=0)  # [7, T, 40]
        z = node("ReduceSum", [node("Mul", [s, wins], p + "sw"), "axes0"], p + "z", keepdims=0)
        pre = node("Add", [node("MatMul", [z, const(p + "dw", w["dense_w"])], p + "zw"),
                           const(p + "db", w["dense_b"])], p + "pre")  # [T, 2]
        prob = node("Softmax", [pre], p + "prob", axis=1)
        const(p + "c0", np.array([0], np.int64))
        act = node("Gather", [prob, p + "c0"], p + "act", axis=1)  # [T, 1]
        nodes.append(helper.make_node("Transpose", [act], [inst], name=inst, perm=[1, 0]))
        outputs.append(helper.make_tensor_value_info(inst, TensorProto.FLOAT, [1, "T"]))
    graph = helper.make_graph(
        nodes, "adtlib",
        [helper.make_tensor_value_info("spec", TensorProto.FLOAT, [1, "T", N_BINS])],
        outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)],
                              producer_name="tactus convert_adtlib.py")
    model.ir_version = 8
    model.doc_string = ("ADTLib 2.1.2 (Southall et al.) kick/snare/hi-hat onset networks, "
                        "converted from the PyPI sdist's TensorFlow checkpoints")
    onnx.checker.check_model(model)
    return model


# ---------------------------------------------------------------------------------------
# Plain numpy reference (per-time-step loops, TF semantics, no ONNX conversion involved)


def _sigmoid(x):
    return 1.0 / (1.0 + np.exp(-x))


def ref_lstm_stack(x, cells):
    """A TF MultiRNNCell of LSTMCells over x [T, in], forward in time; cells = [(kernel, bias)]."""
    for kernel, bias in cells:
        h = np.zeros(HIDDEN, np.float64)
        c = np.zeros(HIDDEN, np.float64)
        out = np.zeros((len(x), HIDDEN), np.float64)
        for t in range(len(x)):
            g = np.concatenate([x[t], h]) @ kernel.astype(np.float64) + bias
            i, j, f, o = np.split(g, 4)
            c = c * _sigmoid(f + FORGET_BIAS) + _sigmoid(i) * np.tanh(j)
            h = _sigmoid(o) * np.tanh(c)
            out[t] = h
        x = out
    return x


def ref_network(spec, w):
    """One instrument's onset activation [T] for spec [T, 1024], in float64."""
    x = spec.astype(np.float64)
    outs = []
    for block in (1, 2):
        cells = lambda d: [(w[f"b{block}_{d}_l{k}_kernel"], w[f"b{block}_{d}_l{k}_bias"])
                           for k in (0, 1)]
        fw = ref_lstm_stack(x, cells("fw"))
        bw = ref_lstm_stack(x[::-1], cells("bw"))[::-1]
        x = np.concatenate([fw, bw], 1)
        outs.append(x)
    out1, out2 = outs
    T = len(spec)
    act = np.zeros(T)
    for t in range(T):
        taps, logits = [], []
        for j in range(TAPS):
            k = t + j - PAD
            v = out2[k] if 0 <= k < T else np.zeros(2 * HIDDEN)
            m = np.tanh(np.concatenate([v, out1[t]]) @ w[f"att{j}"])
            logits.append(m @ w[f"sm{j}"])
            taps.append(v)
        logits = np.array(logits)
        e = np.exp(logits - logits.max(0))
        s = e / e.sum(0)
        z = (s * np.array(taps)).sum(0)
        pre = z @ w["dense_w"] + w["dense_b"]
        p = np.exp(pre - pre.max())
        act[t] = p[0] / p.sum()
    return act


# ---------------------------------------------------------------------------------------
# Front end (madmom's Spectrogram with ADTLib's settings), for the fixtures


def spectrogram(x):
    """|STFT| of mono float x: symmetric Hann 2048 (np.hanning), hop 512, frame i centred on
    sample i*512 (zeros outside the signal), ceil(len/512) frames, bins 0..1023."""
    n = int(np.ceil(len(x) / HOP))
    win = np.hanning(FRAME)
    out = np.zeros((n, N_BINS), np.float32)
    for i in range(n):
        frame = np.zeros(FRAME)
        lo = i * HOP - FRAME // 2
        for k in range(FRAME):
            if 0 <= lo + k < len(x):
                frame[k] = x[lo + k]
        out[i] = np.abs(np.fft.rfft(frame * win))[:N_BINS]
    return out


def click_signal(seconds=0.5, sr=44100):
    """A deterministic test signal: decaying noise-free clicks plus a low tone."""
    n = int(seconds * sr)
    t = np.arange(n) / sr
    x = 0.1 * np.sin(2 * np.pi * 110.0 * t)
    for k, start in enumerate(range(1000, n, 5000)):
        m = np.arange(n - start)
        x[start:] += (0.8 - 0.05 * k) * np.exp(-m / 200.0) * np.sin(2 * np.pi * 1000.0 * m / sr)
    return x.astype(np.float32)


# ---------------------------------------------------------------------------------------


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--out", default=os.path.join(root, "models", "adtlib.onnx"))
    ap.add_argument("--sdist-dir", default=os.path.join(root, "wheels"))
    ap.add_argument("--check", action="store_true",
                    help="compare onnxruntime with the numpy forward pass (max abs diff < 1e-5)")
    ap.add_argument("--fixture", help="write test fixtures into this directory")
    args = ap.parse_args()

    sdist = fetch_sdist(args.sdist_dir)
    members = read_members(sdist)
    weights = []
    for inst, stem in INSTRUMENTS:
        t = read_checkpoint(members[f"{stem}ADTLibAll.index"],
                            members[f"{stem}ADTLibAll.data-00000-of-00001"])
        w = network_weights(trainable(t))
        print(f"{stem}: {len(t)} tensors, {sum(v.size for v in w.values())} parameters used")
        weights.append((inst, w))
    model = build_graph(weights)
    tmp = args.out + ".tmp"
    onnx.save(model, tmp)
    os.replace(tmp, args.out)
    print(f"wrote {args.out} ({os.path.getsize(args.out) / 1e6:.1f} MB)")

    if args.check or args.fixture:
        import onnxruntime as ort
        sess = ort.InferenceSession(args.out, providers=["CPUExecutionProvider"])
    if args.check:
        rng = np.random.default_rng(0)
        worst = 0.0
        for T in (1, 5, 40):
            spec = np.abs(rng.normal(0, 2.0, (1, T, N_BINS))).astype(np.float32)
            t0 = time.perf_counter()
            got = sess.run(None, {"spec": spec})
            dt = time.perf_counter() - t0
            for (inst, w), g in zip(weights, got):
                ref = ref_network(spec[0], w)
                d = float(np.max(np.abs(g[0] - ref)))
                worst = max(worst, d)
                print(f"check T={T:3d} {inst:5s}: max |onnx - numpy| = {d:.2e} "
                      f"(activations {ref.min():.3f}..{ref.max():.3f})")
            print(f"  onnxruntime {dt * 1e3:.1f} ms for {T} frames")
        if not worst < 1e-5:
            sys.exit(f"FAILED: max abs difference {worst:.2e} >= 1e-5")
        print(f"check passed: max abs difference {worst:.2e} < 1e-5")
    if args.fixture:
        os.makedirs(args.fixture, exist_ok=True)
        x = click_signal()
        spec = spectrogram(x.astype(np.float64))
        acts = sess.run(None, {"spec": spec[None]})
        # Fixture: little-endian f32 files with a tiny text header in the README.
        x.astype("<f4").tofile(os.path.join(args.fixture, "signal.f32"))
        spec.astype("<f4").tofile(os.path.join(args.fixture, "spec.f32"))
        np.stack([a[0] for a in acts]).astype("<f4").tofile(
            os.path.join(args.fixture, "acts.f32"))
        print(f"fixture: {len(x)} samples, spec {spec.shape}, acts {len(acts)} x {spec.shape[0]}"
              f" -> {args.fixture}")


if __name__ == "__main__":
    main()
