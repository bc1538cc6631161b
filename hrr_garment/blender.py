"""Running a script in Blender, for what only Blender reads or writes (FBX in, .blend out).

Blender's Python cannot be this package's: the ``bpy`` module pins its own numpy (1.x for Blender
4.5), so Blender runs as a program of its own and the two exchange files. Which Blender:
``HRR_BLENDER`` (the ``blender`` program, 4.2 or later, or a Python that has ``pip install
bpy``), else ``blender`` on PATH. Each run starts from Blender's factory settings, never the user's
add-ons or preferences.
"""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from .errors import InputError

BLENDER_TIMEOUT_S = 600
MISSING = (
    "needs Blender (4.2 or later): put `blender` on PATH or set HRR_BLENDER to it "
    "(or to a Python 3.11 with `pip install bpy`)"
)
ERROR_PREFIX = "HRR-ERROR: "  # how a script run in Blender names what went wrong, on stdout


def blender_command() -> list[str] | None:
    """The command that runs a script in Blender (the script and ``--`` and its arguments follow),
    or None where there is no Blender."""
    given = os.environ.get("HRR_BLENDER") or shutil.which("blender")
    if not given:
        return None
    if Path(given).name.lower().startswith("blender"):
        return [given, "-b", "--factory-startup", "-P"]
    return [given]


PROBE_TIMEOUT_S = 120  # Blender's first start on a cold disk takes seconds, not minutes
OUTPUT_LIMIT_BYTES = 16 << 20  # what a run may print before it is stopped (a script prints lines)
PROBE_MARK = "HRR-BLENDER "


def _run_bounded(arguments: list[str], timeout_s: float) -> tuple[int | None, str]:
    """Run ``arguments`` with no input; (exit status, or None where it ran past ``timeout_s`` or
    printed more than :data:`OUTPUT_LIMIT_BYTES` and was stopped; its output, decoded leniently).
    Output goes to a temporary file watched while the program runs, so a program that prints
    forever fills neither memory nor disk."""
    with tempfile.TemporaryFile() as sink:
        process = subprocess.Popen(arguments, stdin=subprocess.DEVNULL, stdout=sink, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout_s
        try:
            while process.poll() is None:
                if time.monotonic() > deadline or os.fstat(sink.fileno()).st_size > OUTPUT_LIMIT_BYTES:
                    process.kill()
                    process.wait()
                    status = None
                    break
                time.sleep(0.1)
            else:
                status = process.returncode
        except BaseException:  # Ctrl-C: never leave Blender running behind
            process.kill()
            process.wait()
            raise
        sink.seek(0)
        return status, sink.read(OUTPUT_LIMIT_BYTES).decode("utf-8", errors="replace")


@functools.cache
def _checked_blender(command: tuple[str, ...]) -> None:
    """Refuse a ``HRR_BLENDER`` (or ``blender`` on PATH) that is not Blender: it must run Python
    with ``bpy`` within :data:`PROBE_TIMEOUT_S` (once a process)."""
    expression = f"import bpy; print({PROBE_MARK!r} + bpy.app.version_string)"
    is_blender = Path(command[0]).name.lower().startswith("blender")
    probe = [*command[:-1], "--python-expr", expression] if is_blender else [command[0], "-c", expression]
    try:
        status, output = _run_bounded(probe, PROBE_TIMEOUT_S)
    except OSError as exc:
        raise InputError(
            "HRR_BLENDER", f"{command[0]} is not there or cannot run ({exc.strerror or exc}): {MISSING}"
        ) from None
    if status is None or PROBE_MARK not in output:
        raise InputError(
            "HRR_BLENDER", f"{command[0]} is not Blender (it did not print bpy's version): {MISSING}"
        )


def run_blender_script(script: Path, arguments: list[str], *, subject: str | Path, what: str) -> None:
    """Run ``script`` in Blender with ``arguments``; an :class:`~hrr_garment.errors.InputError`
    naming ``subject`` (the file being read or written) and ``what`` was being done when Blender is
    missing, is not Blender, fails or reports an error."""
    command = blender_command()
    if command is None:
        raise InputError(subject, f"{what} {MISSING}")
    _checked_blender(tuple(command))
    try:
        status, output = _run_bounded([*command, str(script), "--", *arguments], BLENDER_TIMEOUT_S)
    except OSError as exc:
        raise InputError(subject, f"{what} {MISSING} ({command[0]}: {exc.strerror or exc})") from None
    if status is None:
        raise InputError(subject, f"{what}: Blender did not finish in {BLENDER_TIMEOUT_S} s") from None
    reported = [line[len(ERROR_PREFIX) :] for line in output.splitlines() if line.startswith(ERROR_PREFIX)]
    if reported:
        raise InputError(subject, reported[0])
    if status != 0:
        last = (output.strip().splitlines() or ["no output"])[-1]
        raise InputError(subject, f"{what}: Blender failed (exit {status}): {last[:300]}")
