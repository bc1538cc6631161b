"""Every graph's export (export/graph_export.py): a module with loops captured by torch's strict
trace first, whose graph onnxruntime runs as torch does; a module the strict trace refuses still
exported, by the exporter's own order."""

import numpy as np
import pytest
import torch

pytest.importorskip("onnxscript")
onnxruntime = pytest.importorskip("onnxruntime")

from hrr_garment.export.graph_export import export_graph, strict_capture  # noqa: E402
from hrr_garment.models.graph_loops import exportable_while  # noqa: E402

OPSET = 18


class HalvedUntilShort(torch.nn.Module):
    """Each row of x (N, 3) halved until its length is under 1, the rows of length over 0.5 alone
    (a list of data-dependent length inside a loop, as a push-out's)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        rows = torch.nonzero((x * x).sum(-1) > 0.25)[:, 0]
        picked = torch.index_select(x, 0, rows)

        def halve(k, p):
            long = ((p * p).sum(-1, keepdim=True) >= 1.0).to(p.dtype)
            return k + 1, p * (1.0 - 0.5 * long)

        def going(k, p):
            return (k < 40) & ((p * p).sum(-1) >= 1.0).any()

        start = torch.zeros((), dtype=torch.int64)
        return x.index_copy(0, rows, exportable_while(going, halve, (start, picked))[1])


class WithGraphBreak(torch.nn.Module):
    """What dynamo's whole-graph trace refuses (a graph break) and the non-strict trace takes."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = x * 2.0
        torch._dynamo.graph_break()
        return y + 1.0


def _run(module: torch.nn.Module, x: np.ndarray, tmp_path) -> np.ndarray:
    n = torch.export.Dim("n", min=1, max=4096)
    example = (torch.from_numpy(x),)
    program = export_graph(
        module,
        example,
        input_names=["x"],
        output_names=["y"],
        dynamic_shapes=({0: n},),
        opset=OPSET,
        strict_first=True,
    )
    path = tmp_path / "graph.onnx"
    program.save(str(path))
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    return session.run(None, {"x": x})[0]


def test_a_module_with_a_loop_is_captured_strictly_and_runs_as_torch(tmp_path):
    rng = np.random.default_rng(0)
    x = (rng.normal(size=(7, 3)) * 3.0).astype(np.float32)
    module = HalvedUntilShort().eval()
    example = (torch.from_numpy(x[:2].copy()),)
    captured = strict_capture(module, example, ({0: torch.export.Dim("n", min=1, max=4096)},))
    assert isinstance(captured, torch.export.ExportedProgram)
    expected = module(torch.from_numpy(x)).numpy()
    assert (np.linalg.norm(expected, axis=-1) < 1.0 + 1e-6).all()  # every row brought under 1 ...
    assert not np.allclose(expected, x)  # ... having been longer
    # the graph, exported on two rows, on seven
    np.testing.assert_allclose(_run(module, x, tmp_path), expected, atol=1e-6)


def test_a_module_the_strict_trace_refuses_is_exported_in_the_exporters_order(tmp_path):
    module = WithGraphBreak().eval()
    x = np.arange(6, dtype=np.float32).reshape(3, 2)
    example = (torch.from_numpy(x),)
    assert strict_capture(module, example, ({0: torch.export.Dim("n", min=1, max=4096)},)) is module
    np.testing.assert_allclose(_run(module, x, tmp_path), x * 2.0 + 1.0)
