"""Atomic file writing (write to a temporary file beside the target, then rename: a failed or
interrupted run never leaves a half-written file under the target name), and strict JSON."""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Iterable, Iterator

import h5py

from .errors import InputError, OutputError
from .input_files import read_by_this_command

# Errors of the storage itself (full, over quota, read-only, no permission, failing), as opposed to a
# bug or bad input inside the writing code: these become one-line OutputErrors naming the target. An
# OSError without an errno counts too: writers such as numpy's zip report a short write that way.
_STORAGE_ERRNOS = {
    errno.ENOSPC,
    errno.EDQUOT,
    errno.EROFS,
    errno.EFBIG,
    errno.EACCES,
    errno.EPERM,
    errno.EIO,
    errno.ENOENT,
    errno.ENOTDIR,
    errno.EISDIR,
    errno.EXDEV,
    errno.ENAMETOOLONG,
}


def storage_error(path: str | Path, exc: OSError) -> OutputError:
    """The one-line error for an output that the storage refused (``exc`` from the OS or HDF5)."""
    reason = os.strerror(exc.errno) if exc.errno else str(exc)
    return OutputError(path, f"cannot write the output: {reason}")


def is_storage_error(exc: OSError) -> bool:
    """Whether ``exc`` is the storage refusing (full, read-only, no permission, missing folder)
    rather than a bug or a broken pipe in the code that met it."""
    return exc.errno is None or exc.errno in _STORAGE_ERRNOS


def require_writable_place(path: str | Path) -> None:
    """Refuse, before any long work, an output whose nearest existing folder cannot take new files
    (read-only, no permission, immutable, or a file where a folder is needed). The writer still
    reports what the storage says later (a disk that fills meanwhile)."""
    path = Path(path).absolute()
    place = path.parent
    while not place.exists() and place != place.parent:
        place = place.parent
    if path.exists() and path.is_dir():  # an output folder that exists: its own entries are written
        place = path
    if not place.is_dir() or not os.access(place, os.W_OK | os.X_OK):
        raise OutputError(path, f"cannot write here: {place} is not a writable folder")


def require_suffix(path: str | Path, suffixes: tuple[str, ...], what: str) -> None:
    """Refuse an output whose extension names another format than the one written (``suffixes``,
    lower case, with the dot; ``""`` for a folder): a file called clip.bvh holding npz bytes
    breaks whatever opens it next."""
    suffix = Path(path).suffix.lower()
    if suffix not in suffixes:
        names = " or ".join(f"a {s} file" if s else "a folder" for s in suffixes)
        raise OutputError(
            path,
            f"{what} is written as {names}; this output's extension ({suffix or 'none'}) names "
            "another format: rename the output",
        )


def refuse_input_as_output(output: str | Path, inputs: Iterable[str | Path | None]) -> None:
    """Refuse an output that is one of the command's inputs (the same file by any path, a link
    included): writing it would replace what is being read."""
    out = Path(output)
    try:
        if not out.exists():
            return
        for source in inputs:
            if source is not None and Path(source).exists() and os.path.samefile(out, source):
                raise OutputError(
                    out,
                    f"is the input {source}: writing it would destroy the input; give another output path",
                )
    except (
        OSError
    ) as exc:  # a name the system cannot hold (ENAMETOOLONG) and the like: the writer will say so
        raise storage_error(out, exc) from None


def refuse_inputs_as_outputs(*outputs: str | Path) -> None:
    """Refuse outputs that are files the running command read (:mod:`hrr_garment.input_files`); a
    writer of several files asks for all of them before it writes the first."""
    for output in outputs:
        source = read_by_this_command(output)
        if source is not None:
            raise OutputError(
                output,
                f"is the input {source}: writing it would destroy the input; give another output path",
            )


@contextlib.contextmanager
def atomic_path(path: str | Path, private: bool = False) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success
    (``private``: readable by its owner only, as a key must be).

    A target that exists and is not a regular file (a folder, a device such as /dev/full), or that is
    a file the running command read (:mod:`hrr_garment.input_files`: an output never destroys an
    input), is refused before anything is written, and storage failures (disk full, read-only or
    missing folder, special file systems such as /proc) raise :class:`OutputError` naming ``path``;
    the temporary file is removed either way."""
    path = Path(path)
    try:
        if path.exists() and not path.is_file():
            raise OutputError(
                path, "exists and is not a regular file (a folder or a device); give a file path"
            )
        refuse_inputs_as_outputs(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise storage_error(path, exc) from None
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if not private:  # mkstemp makes the file private (0600); give it the permissions a plain open() would
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp_path, 0o666 & ~umask)
        os.replace(tmp_path, path)
    except OSError as exc:
        if not is_storage_error(exc):
            raise  # e.g. a broken pipe: not the storage, so not reported as if it were
        raise storage_error(path, exc) from None
    finally:
        with contextlib.suppress(OSError):
            tmp_path.unlink(missing_ok=True)


class _DeferredErrorFile:
    """A binary file for h5py's file-object driver that keeps the first write error for later.

    HDF5 does not survive I/O errors well: after a failed write (a full disk, a file-size limit),
    closing the file prints tracebacks from h5py's clean-up and can crash the interpreter. So this
    file tells HDF5 every write succeeded, drops the writes after the first failure, and
    :func:`atomic_h5` raises the kept error once HDF5 has closed the file cleanly."""

    def __init__(self, fh):
        self._fh = fh
        self.error: OSError | None = None

    def write(self, data) -> int:
        view = memoryview(data).cast("B")
        done = 0
        while self.error is None and done < len(view):
            try:
                written = self._fh.write(view[done:])
            except OSError as exc:
                self.error = exc
                break
            if not written:
                self.error = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            done += written or 0
        return len(view)

    def truncate(self, size: int | None = None) -> int | None:
        if self.error is None:
            try:
                return self._fh.truncate(size)
            except OSError as exc:
                self.error = exc
        return size

    def readinto(self, buffer) -> int:
        return self._fh.readinto(buffer)

    def read(self, size: int = -1) -> bytes:
        return self._fh.read(size)

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._fh.seek(offset, whence)

    def tell(self) -> int:
        return self._fh.tell()

    def flush(self) -> None:  # unbuffered: nothing is held here
        pass


@contextlib.contextmanager
def atomic_h5(path: str | Path) -> Iterator[h5py.File]:
    """An HDF5 file written atomically (see :func:`atomic_path`). A storage failure while writing
    it raises :class:`OutputError` naming ``path`` after the file is closed (see
    :class:`_DeferredErrorFile` for why HDF5 must not see the error itself)."""
    with atomic_path(path) as tmp, open(tmp, "w+b", buffering=0) as fh:
        sink = _DeferredErrorFile(fh)
        with h5py.File(sink, "w") as f:
            yield f
        if sink.error is not None:
            raise sink.error


def remove_empty_folders(root: str | Path) -> None:
    """Remove ``root`` and the folders under it that hold no file (deepest first); keep the rest."""
    root = Path(root)
    if not root.is_dir():
        return
    for folder in sorted((p for p in root.rglob("*") if p.is_dir()), key=lambda p: -len(p.parts)) + [root]:
        with contextlib.suppress(OSError):
            folder.rmdir()  # fails, as it should, on a folder that is not empty


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

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+", encoding="utf-8") as fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            raise InputError(
                resource, f"{busy} (process {fh.read().strip() or 'unknown'} holds {path})"
            ) from None
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
