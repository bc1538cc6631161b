"""Loops and conditionals that are ONNX ``Loop`` and ``If`` when a module is exported and Python's
when it runs (torch's own would compile every batch shape on a GPU crowd): the push-out's rounds,
the strain limit's passes, the skin collider's fixed-point steps. A loop's body is traced once
where an unrolled one is traced each time, which is most of an export's time (docs/export.md)."""

from __future__ import annotations

import torch
from torch._higher_order_ops.while_loop import while_loop


def exportable_while(condition, body, state: tuple) -> tuple:
    """``body(*state)`` while ``condition(*state)`` holds: an ONNX ``Loop`` when exporting, a Python
    loop when running."""
    if torch.compiler.is_compiling():
        return while_loop(condition, body, state)
    while bool(condition(*state)):
        state = body(*state)
    return state


def exportable_cond(predicate: torch.Tensor, then, otherwise, *, operands: tuple):
    """``then(*operands)`` where ``predicate`` holds, else ``otherwise(*operands)``: an ONNX ``If``
    when exporting (the branches' outputs may not alias their inputs), a Python branch when running."""
    if torch.compiler.is_compiling():
        return torch.cond(predicate, then, otherwise, operands)
    return then(*operands) if bool(predicate) else otherwise(*operands)
