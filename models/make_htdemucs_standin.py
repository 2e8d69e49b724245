#!/usr/bin/env python3
"""Write a STAND-IN for the htdemucs ONNX graph: same input/output names and shapes as
models/export_htdemucs.py produces, but NOT Demucs: a few Mul nodes, no weights.

    freq[s] = g[s] * mag      (g = 0.1, 0.2, 0.3, 0.4)
    time[s] = h[s] * mix      (h = 0.05, -0.1, 0.15, 0.2)

so that, if the Rust STFT -> graph -> iSTFT + time path is right, stem s is exactly
(g[s] + h[s]) * mix. Used by crates/tactus-separate/tests/onnx_htdemucs.rs to check the
Rust side's framing, inversion, segment blending and streaming without torch.

Usage: python make_htdemucs_standin.py OUT.onnx
"""
import sys

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

L, BINS, FRAMES = 343980, 2048, 336
G = np.array([0.1, 0.2, 0.3, 0.4], np.float32).reshape(1, 4, 1, 1, 1)
H = np.array([0.05, -0.1, 0.15, 0.2], np.float32).reshape(1, 4, 1, 1)

nodes = [
    helper.make_node("Unsqueeze", ["mag", "axis1"], ["mag5"]),
    helper.make_node("Mul", ["mag5", "g"], ["freq"]),
    helper.make_node("Unsqueeze", ["mix", "axis1"], ["mix4"]),
    helper.make_node("Mul", ["mix4", "h"], ["time"]),
]
inits = [numpy_helper.from_array(np.array([1], np.int64), "axis1"),
         numpy_helper.from_array(G, "g"), numpy_helper.from_array(H, "h")]
graph = helper.make_graph(
    nodes, "htdemucs_standin",
    [helper.make_tensor_value_info("mix", TensorProto.FLOAT, [1, 2, L]),
     helper.make_tensor_value_info("mag", TensorProto.FLOAT, [1, 4, BINS, FRAMES])],
    [helper.make_tensor_value_info("freq", TensorProto.FLOAT, [1, 4, 4, BINS, FRAMES]),
     helper.make_tensor_value_info("time", TensorProto.FLOAT, [1, 4, 2, L])],
    inits)
model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8)
model.doc_string = "STAND-IN with htdemucs's I/O contract; not Demucs (see make_htdemucs_standin.py)"
onnx.checker.check_model(model)
onnx.save(model, sys.argv[1])
