"""Atomic file writing (write to a temporary file beside the target, then rename: a failed or
interrupted run never leaves a half-written file under the target name), and strict JSON."""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Iterator


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        # mkstemp makes the file private (0600); give it the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp_path, 0o666 & ~umask)
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def _json_ready(value):
    """numpy scalars to Python, non-finite floats to None: strict JSON has no NaN or Infinity."""
    if isinstance(value, dict):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if hasattr(value, "item") and callable(value.item) and getattr(value, "ndim", None) == 0:
        value = value.item()  # a numpy scalar
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return value


def strict_json(value, **kwargs) -> str:
    """``json.dumps`` that writes non-finite numbers as ``null`` instead of NaN / Infinity."""
    return json.dumps(_json_ready(value), allow_nan=False, **kwargs)


@contextlib.contextmanager
def exclusive_lock(path: str | Path, resource: object, busy: str) -> Iterator[Path]:
    """Hold an exclusive advisory lock on ``path`` (created if missing) for the block, or raise
    :class:`~hrr_garment.errors.InputError` at once for ``resource``, saying ``busy`` and the
    holder's pid, when another process holds it. The operating system releases the lock when its
    holder exits, however it exits, so no stale lock outlives a killed run."""
    import fcntl

    from .errors import InputError

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+", encoding="utf-8") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            raise InputError(resource, f"{busy} (process {fh.read().strip() or 'unknown'} holds {path})") from None
        fh.seek(0)
        fh.truncate()
        fh.write(str(os.getpid()))
        fh.flush()
        try:
            yield path
        finally:
            fh.seek(0)
            fh.truncate()
            fcntl.flock(fh, fcntl.LOCK_UN)
