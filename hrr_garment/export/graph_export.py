"""Every graph the package writes as ONNX (a step's, the skin collider's) goes through
:func:`export_graph`: torch's dynamo exporter, then :func:`~.graph_optimiser.optimise_graph`'s one
pass; a module with loops captured by torch's strict (dynamo) trace first.

Why the capture can be chosen here: the exporter tries ``torch.export``'s non-strict trace first
and the strict one only after it fails. A step's push-out loops over lists of data-dependent length
(the strain limit's edges near a tear, the points a round moved), and the non-strict trace of its
loops' bodies fails on a guard between two such lengths, after a full minute on the 1,046-vertex
dress's step on a character's own mesh (59 of that export's 273 s under a profiler); the strict
trace then gives the graph. Straight-line code (the skin collider's query alone) the non-strict
trace takes, a few seconds sooner than the strict one, so it keeps the exporter's order. Where the
strict trace fails, the exporter's own order runs after it.
"""

from __future__ import annotations

import logging
import warnings
from contextlib import contextmanager
from typing import Callable

import torch

from .graph_optimiser import optimise_graph


def export_graph(
    module: torch.nn.Module,
    example: tuple[torch.Tensor, ...],
    *,
    input_names: list[str],
    output_names: list[str],
    dynamic_shapes: tuple,
    opset: int,
    strict_first: bool = False,
    traced: Callable[[], None] | None = None,
):
    """The ONNX program (torch's ``ONNXProgram``, optimised) of ``module`` called on ``example``,
    its inputs and outputs named, ``dynamic_shapes`` as ``torch.export`` takes them; captured by the
    strict trace first where ``strict_first`` (a module with loops: above). ``traced`` is called
    between torch's export and the optimisation (a progress bar's next stage). Without gradients,
    and without the exporter's and optimiser's own logs and warnings (:func:`_quiet`)."""
    with torch.no_grad(), _quiet():
        program = torch.onnx.export(
            strict_capture(module, example, dynamic_shapes) if strict_first else module,
            example,
            dynamo=True,
            input_names=input_names,
            output_names=output_names,
            dynamic_shapes=dynamic_shapes,
            opset_version=opset,
            optimize=False,  # optimise_graph's one pass instead: the same graph in a fraction of the time
            verbose=False,
        )
        if traced is not None:
            traced()
        optimise_graph(program.model)
    return program


def strict_capture(module: torch.nn.Module, example: tuple, dynamic_shapes: tuple):
    """``module`` as a ``torch.export.ExportedProgram`` by the exporter's own strict capture (its
    settings for dynamic shapes), or ``module`` itself where that fails or this torch has no such
    capture: the exporter then tries its own order."""
    try:
        from torch.onnx._internal.exporter._capture_strategies import TorchExportStrictStrategy
    except ImportError:
        return module
    result = TorchExportStrictStrategy(verbose=False)(module, example, None, dynamic_shapes=dynamic_shapes)
    return result.exported_program if result.success and result.exported_program is not None else module


@contextmanager
def _quiet():
    """Torch's exporter and its optimiser log and warn about their own internals (a missing
    torchvision, deprecations, constant folding skipped) on every export: none of it is the user's."""
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(previous)
