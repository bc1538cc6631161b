"""Reading an npz safely: every array's declared size and dtype checked from its header before it is
allocated (numbers and strings only, never objects; a size limit against huge shapes and
compression bombs), and the checks a motion's arrays pass (real numbers, finite, within bounds)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..errors import MotionError
from ..input_files import input_file
from .limits import max_npz_bytes

NPZ_KINDS = "biufUS"  # dtype kinds an npz may hold: numbers and strings (bool only where it is read as such)


def read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of an npz, after checking each one's declared size and dtype from its header:
    numbers and strings only (never objects), and at most ``max_npz_bytes()`` in all, so a huge
    declared shape or a compression bomb is refused before it is allocated."""
    limit, total, arrays = max_npz_bytes(), 0, {}
    input_file(path, "a motion file")
    try:
        with zipfile.ZipFile(path) as archive:
            for member in archive.infolist():
                name = member.filename[:-4] if member.filename.endswith(".npy") else member.filename
                with archive.open(member) as fh:
                    version = np.lib.format.read_magic(fh)
                    read_header = (
                        np.lib.format.read_array_header_1_0
                        if version == (1, 0)
                        else np.lib.format.read_array_header_2_0
                    )
                    shape, _, dtype = read_header(fh)
                if dtype.hasobject or dtype.kind not in NPZ_KINDS:
                    raise MotionError(
                        path, f"array {name!r} has dtype {dtype}; motion files hold numbers and strings only"
                    )
                total += max(int(np.prod(shape, dtype=np.float64)) * dtype.itemsize, member.file_size)
                if total > limit:
                    raise MotionError(
                        path,
                        f"its arrays take over {limit:,} bytes uncompressed (array {name!r} has shape "
                        f"{shape}); set HRR_MAX_NPZ_BYTES to raise the limit",
                    )
            with np.load(path, allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
    # NotImplementedError: a damaged header naming a compression zipfile lacks; RuntimeError: "encrypted"
    except (
        OSError,
        ValueError,
        zipfile.BadZipFile,
        EOFError,
        KeyError,
        NotImplementedError,
        RuntimeError,
    ) as exc:
        raise MotionError(path, f"not a readable npz file ({exc})") from None
    return arrays


def numeric_array(
    path: Path, data: dict[str, np.ndarray], key: str, *, bound: float, dtype: type = np.float64
) -> np.ndarray:
    """``data[key]`` as ``dtype``: real numbers (not bool, complex, dates or text), finite and within
    +-``bound``."""
    values = data[key]
    if values.dtype.kind not in "iuf":
        raise MotionError(path, f"{key} has dtype {values.dtype}; expected real numbers")
    values = values.astype(dtype, copy=False)
    if values.size and values.ndim:
        check_finite(path, values)
    if values.size and not (np.abs(values) <= bound).all():
        frame = (
            int(np.argmax(~(np.abs(values.reshape(len(values), -1)) <= bound).all(1))) if values.ndim else 0
        )
        raise MotionError(
            path,
            f"{key} has a value beyond +-{bound:g} (first at frame {frame}): a wrong unit or a corrupt file",
        )
    return values


def check_finite(path: Path, *arrays: np.ndarray) -> None:
    """Raise :class:`MotionError` naming ``path`` where a frame of an array has NaN or inf."""
    for a in arrays:
        ok = np.isfinite(a.reshape(a.shape[0], -1)).all(1)
        if not ok.all():
            raise MotionError(
                path,
                f"non-finite values (NaN or inf) in {int((~ok).sum())} frame(s), first at frame "
                f"{int(np.argmin(ok))}",
            )
