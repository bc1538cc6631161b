"""The collider of the body the viewer sees (:class:`~hrr_garment.body.skin_collider.SkinCollider`)
as an ONNX graph of its own, for an engine's push-out or a check of one's own:

    path = export_skin_collider(skin_collider(visible), "body.onnx")
    distance, normal = onnxruntime.InferenceSession(str(path)).run(
        None, {"points": points, "rotations": global_rotations, "positions": joint_positions})

Inputs (float32, or float64 where asked): ``points`` (B, N, 3) for B characters, ``rotations``
(B, J, 3, 3) the joints' global rotations and ``positions`` (B, J, 3) their positions (forward
kinematics' output, as the reference's ``query`` takes them); outputs ``distance`` (B, N), < 0
inside, and ``normal`` (B, N, 3), outward. B and N are dynamic. The graph is
:class:`~hrr_garment.models.skin_collider_graph.SkinColliderGraph`, its grid held as constants
(24 MB for an anny body in float32). Needs the ``onnx`` extra.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ..io_utils import atomic_path, require_suffix
from ..models.skin_collider_graph import SkinColliderGraph
from .graph_export import export_graph
from .onnx_model import OPSET, _require_onnx

INPUTS = ("points", "rotations", "positions")
OUTPUTS = ("distance", "normal")


def export_skin_collider(collider, path: str | Path, *, dtype: torch.dtype = torch.float32) -> Path:
    """Write ``path`` (.onnx, atomically): the query of ``collider`` (a
    :class:`~hrr_garment.body.skin_collider.SkinCollider`) in ``dtype``."""
    onnx = _require_onnx()
    path = Path(path)
    require_suffix(path, (".onnx",), "an ONNX model")
    graph = SkinColliderGraph(collider, dtype).eval()
    joints = graph.joints
    example = (
        torch.zeros((2, 5, 3), dtype=dtype),
        torch.as_tensor(np.broadcast_to(collider.body.rest_rotations, (2, joints, 3, 3)).copy(), dtype=dtype),
        torch.as_tensor(np.broadcast_to(collider.body.rest_positions, (2, joints, 3)).copy(), dtype=dtype),
    )
    characters = torch.export.Dim("characters", min=1, max=4096)
    points = torch.export.Dim("points", min=1, max=1 << 22)
    program = export_graph(
        graph,
        example,
        input_names=list(INPUTS),
        output_names=list(OUTPUTS),
        dynamic_shapes=({0: characters, 1: points}, {0: characters}, {0: characters}),
        opset=OPSET,
    )
    with atomic_path(path) as tmp:
        onnx.save_model(program.model_proto, str(tmp))
    return path
