"""The exported graphs' one optimisation pass (export/graph_optimiser.py): onnxscript's
``optimize_ir`` once, byte for byte where the slow two-rooted rule it leaves out finds nothing (as on
the step's graphs), and that rule alone left out."""

import numpy as np
import pytest

pytest.importorskip("onnxscript")
onnxruntime = pytest.importorskip("onnxruntime")

import onnx  # noqa: E402
import onnx_ir as ir  # noqa: E402
from onnx import TensorProto, helper  # noqa: E402
from onnxscript import optimizer  # noqa: E402

from hrr_garment.export.graph_optimiser import SLOW_UNUSED_RULES, optimise_graph  # noqa: E402


def _graph(cut: int) -> onnx.ModelProto:
    """x (2, 6): the last axis cut at ``cut`` into two slices, their products with a constant sum
    (folded): y (2, cut), through an identity transpose (a rule removes it), and z (2, 6 - cut)."""

    def ints(name, values):
        return helper.make_tensor(name, TensorProto.INT64, [len(values)], values)

    nodes = [
        helper.make_node("Add", ["one", "one"], ["two"]),
        helper.make_node("Slice", ["x", "start0", "end0", "axis"], ["left"]),
        helper.make_node("Slice", ["x", "start1", "end1", "axis"], ["right"]),
        helper.make_node("Mul", ["left", "two"], ["doubled"]),
        helper.make_node("Transpose", ["doubled"], ["y"], perm=[0, 1]),
        helper.make_node("Mul", ["right", "two"], ["z"]),
    ]
    graph = helper.make_graph(
        nodes,
        "cut",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [2, 6])],
        [
            helper.make_tensor_value_info("y", TensorProto.FLOAT, None),
            helper.make_tensor_value_info("z", TensorProto.FLOAT, None),
        ],
        initializer=[
            helper.make_tensor("one", TensorProto.FLOAT, [], [1.0]),
            ints("start0", [0]),
            ints("end0", [cut]),
            ints("start1", [cut]),
            ints("end1", [6]),
            ints("axis", [-1]),
        ],
    )
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])


def _optimised(proto: onnx.ModelProto, optimise) -> onnx.ModelProto:
    model = ir.serde.deserialize_model(proto)
    optimise(model)
    return ir.serde.serialize_model(model)


def _run(proto: onnx.ModelProto, x: np.ndarray) -> list[np.ndarray]:
    session = onnxruntime.InferenceSession(proto.SerializeToString(), providers=["CPUExecutionProvider"])
    return session.run(None, {"x": x})


def test_it_writes_what_optimize_ir_writes_where_no_axis_is_halved():
    proto = _graph(cut=2)
    ours = _optimised(proto, optimise_graph)
    theirs = _optimised(proto, lambda model: optimizer.optimize_ir(model, num_iterations=1))
    assert ours.SerializeToString() == theirs.SerializeToString()
    ops = [node.op_type for node in ours.graph.node]
    assert "Transpose" not in ops and ops.count("Add") == 0  # the pass did its work: a rule and the folding
    x = np.arange(12, dtype=np.float32).reshape(2, 6)
    y, z = _run(ours, x)
    np.testing.assert_array_equal(y, 2 * x[:, :2])
    np.testing.assert_array_equal(z, 2 * x[:, 2:])


def test_only_the_slow_rule_is_left_out():
    """Guards the fallback: were onnxscript to rename or move its rules, the pass would quietly be
    ``optimize_ir`` again (correct, slower); this says so instead."""
    from onnxscript import rewriter

    names = [getattr(rule, "name", None) for rule in rewriter._DEFAULT_REWRITE_RULES]
    assert set(SLOW_UNUSED_RULES) <= set(names)
