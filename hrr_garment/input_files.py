"""Opening what a user hands the package, and remembering it.

Only regular files are read: a pipe would hang the command, a device such as ``/dev/zero`` never
ends, and a symlink is resolved before anything is decided, so a link to either is the device it
names. Sizes are bounded before reading, and the read takes the size the file had (a file that
grows while it is read is refused), so memory follows the file's real content.

While a command runs (:func:`guarding_inputs`, which the command-line wrapper holds), every file read
through here is remembered, and :func:`~hrr_garment.io_utils.atomic_path` refuses to replace one:
an output never destroys an input, whichever option named it (a joint map, a key, a clip given as
``--check``) or however the input reached the command (a glTF's external buffer)::

    data = read_input(path, limit=MAX_TEXT_BYTES, what="a body file")   # bytes, or InputError
    path = input_file(path, what="an npz")                               # for readers that open it
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import stat
from pathlib import Path
from typing import Iterator

from .errors import InputError

MAX_TEXT_BYTES = 64 << 20  # a JSON, YAML or key file (a body.json of the largest kept mesh is ~25 MB)
MAX_BINARY_BYTES = 8 << 30  # a GLB, a BVH, an npz, an HDF5 file: far past any character or capture

# (device, inode) -> the path it was read as, for the command that runs (None: no command running)
_READ: contextvars.ContextVar[dict[tuple[int, int], str] | None] = contextvars.ContextVar(
    "hrr_inputs_read", default=None
)


def input_file(path: str | Path, what: str = "file") -> Path:
    """``path`` resolved (symlinks followed) after checking that it names a regular file, which is
    remembered as read (:func:`guarding_inputs`); an :class:`InputError` naming ``path`` if not.
    For readers that open the file themselves (HDF5, numpy's zip)."""
    path = Path(path)
    try:
        target = path.resolve(strict=True)
        info = target.stat()
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, RuntimeError) as exc:  # a symlink loop is a RuntimeError on some Pythons
        raise InputError(path, f"cannot open {what} ({getattr(exc, 'strerror', None) or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a pipe, a socket or a device"
        shown = f" (a link to {target})" if target != path.absolute() else ""
        raise InputError(path, f"is {kind}{shown}, not a regular file: give {what} as a file")
    read = _READ.get()
    if read is not None:
        read.setdefault((info.st_dev, info.st_ino), str(path))
    return target


def read_input(path: str | Path, *, limit: int, what: str = "file") -> bytes:
    """The bytes of the regular file ``path`` (:func:`input_file`), at most ``limit`` of them: a
    larger file is an :class:`InputError` naming the limit, refused before it is read."""
    target = input_file(path, what)
    size = target.stat().st_size
    if size > limit:
        raise InputError(path, f"is {size:,} bytes, more than {what} may be ({limit:,} bytes)")
    try:
        with open(target, "rb") as fh:
            data = fh.read(size)  # a buffer of the file's size: read(limit) would allocate the limit
            grew = fh.read(1)
    except OSError as exc:
        raise InputError(path, f"cannot read {what} ({exc.strerror or exc})") from None
    if grew:  # it grew while being read
        raise InputError(path, f"grew while it was read: {what} must stay still")
    return data


def read_input_text(path: str | Path, *, limit: int = MAX_TEXT_BYTES, what: str = "file") -> str:
    """:func:`read_input` decoded as UTF-8; an :class:`InputError` for bytes that are not text."""
    data = read_input(path, limit=limit, what=what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"is not UTF-8 text, as {what} must be (byte {exc.start})") from None


@contextlib.contextmanager
def guarding_inputs() -> Iterator[None]:
    """Remember, for the block (a command's run), every file read through this module, so that
    :func:`read_by_this_command` can name it. Nested blocks share the outer one's record."""
    if _READ.get() is not None:
        yield
        return
    token = _READ.set({})
    try:
        yield
    finally:
        _READ.reset(token)


def read_by_this_command(path: str | Path) -> str | None:
    """The name under which the running command read the file at ``path`` (the same file by any
    path or hard link), or None: not read, no such file, or no command running."""
    read = _READ.get()
    if not read:
        return None
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return None
    return read.get((info.st_dev, info.st_ino))
