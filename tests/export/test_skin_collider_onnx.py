"""The visible body's collider as ONNX (export/skin_collider_onnx.py): onnxruntime gives what the
numpy reference gives on a limb bent up to 135 degrees, two characters in one batch; to rounding in
float64, within the torch graph's stated bound in float32 (tests/models/test_skin_collider_graph.py)."""

import numpy as np
import pytest
import torch

pytest.importorskip("onnxruntime")
pytest.importorskip("onnxscript")

from hrr_garment.body.skin_collider import SkinColliderSettings, skin_collider  # noqa: E402
from tests.body.limb import bent, probes, skinned_limb  # noqa: E402

pytestmark = pytest.mark.slow  # an export takes 10 to 20 s


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_onnxruntime_gives_the_reference(tmp_path, dtype):
    import onnxruntime

    from hrr_garment.export.skin_collider_onnx import export_skin_collider

    limb = skinned_limb()
    collider = skin_collider(limb, SkinColliderSettings(voxel_m=0.01, padding_m=0.03))
    path = export_skin_collider(collider, tmp_path / "limb.onnx", dtype=dtype)
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    real = np.float64 if dtype == torch.float64 else np.float32
    for pair in [(0.0, 135.0), (45.0, 90.0)]:
        poses = [bent(degrees) for degrees in pair]
        points = np.stack(
            [probes(limb, limb.pose(r[None], p[None])[0], seed=k) for k, (r, p) in enumerate(poses)]
        )
        feed = {
            "points": points.astype(real),
            "rotations": np.stack([r for r, _ in poses]).astype(real),
            "positions": np.stack([p for _, p in poses]).astype(real),
        }
        distance, normal = session.run(None, feed)
        assert distance.dtype == real and distance.shape == points.shape[:2] and normal.shape == points.shape
        for k, (r, p) in enumerate(poses):
            ref, ref_normal = collider.query(points[k], r, p)
            if dtype == torch.float64:
                assert np.abs(distance[k] - ref).max() < 1e-9 and np.abs(normal[k] - ref_normal).max() < 1e-9
            else:
                assert np.abs(distance[k] - ref).max() < 1e-6
                assert (np.sign(distance[k]) == np.sign(ref))[np.abs(ref) > 1e-6].all()
                off = np.abs(ref) > 1e-3
                assert np.mean(np.abs(normal[k] - ref_normal).max(1)[off] < 0.01) > 0.99
