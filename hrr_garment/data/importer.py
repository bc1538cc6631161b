"""Import a user's own garment simulation (template OBJ + motion + per-frame vertices) into a dataset.

Frames are a folder of OBJ files (one per frame, sorted by the number in the name; same vertex
order as the template) or an npz with ``vertices`` (T, V, 3). They must be in the motion's world
frame, Y up, in metres (``frames_scale`` converts). Frames recorded at another rate than the
dataset's 30 fps are resampled linearly, and then must match the motion's frame count.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..garment.mesh import GarmentMesh
from ..garment.obj import read_obj_vertices, write_obj
from ..motion.motion import FPS, Motion
from ..motion.resample import resample_linear, resample_times
from .dataset import GarmentDataset, SequenceRecord, write_dataset
from .splits import split_names


def _frame_number(path: Path) -> tuple[int, str]:
    numbers = re.findall(r"\d+", path.stem)
    return (int(numbers[-1]) if numbers else -1, path.name)


def read_frames(source: str | Path) -> np.ndarray:
    """(T, V, 3) float64 from a folder of OBJ frames or an npz holding ``vertices``."""
    source = Path(source)
    if source.is_dir():
        files = sorted(source.glob("*.obj"), key=_frame_number)
        if not files:
            raise InputError(source, "no .obj frames in this folder")
        frames = [read_obj_vertices(f) for f in files]
        counts = {len(f) for f in frames}
        if len(counts) > 1:
            bad = next(f for f, v in zip(files, frames) if len(v) != len(frames[0]))
            raise InputError(
                bad, f"has {len(read_obj_vertices(bad))} vertices; {files[0].name} has {len(frames[0])}"
            )
        return np.stack(frames)
    if source.suffix.lower() == ".npz" and source.is_file():
        try:
            with np.load(source, allow_pickle=False) as z:
                if "vertices" not in z:
                    raise InputError(source, f"npz lacks 'vertices' (has {sorted(z.files)})")
                v = z["vertices"].astype(np.float64)
        except (OSError, ValueError) as exc:
            raise InputError(source, f"not a readable npz ({exc})") from None
        if v.ndim != 3 or v.shape[2] != 3:
            raise InputError(source, f"'vertices' must be (T, V, 3), got {v.shape}")
        return v
    raise InputError(source, "frames must be a folder of .obj files or an .npz with 'vertices'")


def frames_to_sequence(
    name: str,
    template: GarmentMesh,
    motion: Motion,
    frames: np.ndarray,
    source: str,
    frames_fps: float = FPS,
    frames_scale: float = 1.0,
) -> SequenceRecord:
    """Check frames against the template and motion; resample to the motion's rate."""
    frames = frames * frames_scale
    if frames.shape[1] != template.num_vertices:
        raise InputError(
            source, f"frames have {frames.shape[1]} vertices; the template has {template.num_vertices}"
        )
    if not np.isfinite(frames).all():
        t = int(np.argwhere(~np.isfinite(frames))[0, 0])
        raise InputError(source, f"frame {t} contains NaN or infinity")
    if abs(frames_fps - motion.fps) > 1e-6:
        frames = resample_linear(frames, resample_times(len(frames), frames_fps, motion.fps))
    if len(frames) != motion.num_frames:
        raise InputError(
            source,
            f"{len(frames)} frames (at {motion.fps:g} fps) but the motion has "
            f"{motion.num_frames}; give --frames-fps if the frames use another rate",
        )
    # A different vertex order shows as wildly wrong edge lengths in the first frame.
    edges = template.edges()
    rest = np.linalg.norm(template.vertices[edges[:, 0]] - template.vertices[edges[:, 1]], axis=1)
    first = np.linalg.norm(frames[0, edges[:, 0]] - frames[0, edges[:, 1]], axis=1)
    ratio = float(np.median(first / np.maximum(rest, 1e-12)))
    if not 0.5 < ratio < 2.0:
        raise InputError(
            source,
            f"frame 0's edges are {ratio:.2f}x the template's (median): the vertex order or "
            "units differ from the template (see --frames-scale)",
        )
    return SequenceRecord(
        name, frames.astype(np.float32), motion, info={"kind": "import", "source": str(source)}
    )


def import_sequence(out: str | Path, template: GarmentMesh, record: SequenceRecord, seed: int = 0) -> Path:
    """Add ``record`` to dataset ``out`` (created if missing; the template must match), atomically."""
    out = Path(out)
    records, bodies = [], {}
    if out.exists():
        existing = GarmentDataset(out)
        same = (
            existing.template.vertices.shape == template.vertices.shape
            and np.allclose(existing.template.vertices, template.vertices, atol=1e-6)
            and np.array_equal(existing.template.faces, template.faces)
        )
        if not same:
            raise InputError(out, "this dataset was made for another template; write to a new file")
        records = [existing.sequence(n) for n in existing.names if n != record.name]
        bodies = existing.bodies
    records.append(record)
    names = [r.name for r in records]
    return write_dataset(
        out,
        template,
        records,
        splits=split_names(names, 0.1, 0.1, seed=seed),
        info={"imported": True},
        bodies=bodies,
    )


def export_obj_frames(folder: str | Path, vertices: np.ndarray, faces: np.ndarray) -> list[Path]:
    """Write frame_0000.obj, frame_0001.obj... (one mesh per frame) into ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    width = max(4, len(str(len(vertices) - 1)))
    return [write_obj(folder / f"frame_{t:0{width}d}.obj", v, faces) for t, v in enumerate(vertices)]
