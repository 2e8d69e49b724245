#!/usr/bin/env python3
"""Writes a deliberately broken Spleeter stand-in for the tests (needs `pip install onnx`).

Its ports pass the loader's checks (input `mag` and outputs `vocals`, `accompaniment`,
all float32 [?, 2, ?, 1024]), but `vocals` keeps only the first frame of the segment, so
every network call returns an output of the wrong shape at run time. The separator must
report that (`Separator::take_error`) and the render must fail with one line.

    python3 models/make_broken_spleeter.py crates/tactus-separate/tests/fixtures/onnx/spleeter_wrong_output.onnx
"""
import sys

import onnx
from onnx import TensorProto, helper


def main(out):
    mag = helper.make_tensor_value_info("mag", TensorProto.FLOAT, ["n", 2, "t", 1024])
    voc = helper.make_tensor_value_info("vocals", TensorProto.FLOAT, ["n", 2, "t2", 1024])
    acc = helper.make_tensor_value_info("accompaniment", TensorProto.FLOAT, ["n", 2, "t", 1024])
    consts = [
        helper.make_tensor(name, TensorProto.INT64, [1], [v])
        for name, v in [("starts", 0), ("ends", 1), ("axes", 2)]
    ]
    nodes = [
        helper.make_node("Slice", ["mag", "starts", "ends", "axes"], ["vocals"]),
        helper.make_node("Identity", ["mag"], ["accompaniment"]),
    ]
    graph = helper.make_graph(nodes, "spleeter_wrong_output", [mag], [voc, acc], consts)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, out)


if __name__ == "__main__":
    main(sys.argv[1])
