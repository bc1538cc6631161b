"""Running a script in Blender, for what only Blender reads or writes (FBX in, .blend out).

Blender's Python cannot be this package's: the ``bpy`` module pins its own numpy (1.x for Blender
4.5), so Blender runs as a program of its own and the two exchange files. Which Blender:
``HRR_BLENDER`` (the ``blender`` program, 4.2 or later, or a Python that has ``pip install
bpy``), else ``blender`` on PATH. Each run starts from Blender's factory settings, never the user's
add-ons or preferences.
"""

from __future__ import annotations

import os
import shutil
import subprocess
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


def run_blender_script(script: Path, arguments: list[str], *, subject: str | Path, what: str) -> None:
    """Run ``script`` in Blender with ``arguments``; an :class:`~hrr_garment.errors.InputError`
    naming ``subject`` (the file being read or written) and ``what`` was being done when Blender is
    missing, fails or reports an error."""
    command = blender_command()
    if command is None:
        raise InputError(subject, f"{what} {MISSING}")
    try:
        done = subprocess.run(
            [*command, str(script), "--", *arguments],
            capture_output=True,
            text=True,
            timeout=BLENDER_TIMEOUT_S,
            stdin=subprocess.DEVNULL,
        )
    except FileNotFoundError:
        raise InputError(subject, f"{what} {MISSING} ({command[0]} is not there)") from None
    except subprocess.TimeoutExpired:
        raise InputError(subject, f"{what}: Blender did not finish in {BLENDER_TIMEOUT_S} s") from None
    reported = [
        line[len(ERROR_PREFIX) :] for line in done.stdout.splitlines() if line.startswith(ERROR_PREFIX)
    ]
    if reported:
        raise InputError(subject, reported[0])
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or done.stdout.strip().splitlines() or ["no output"])[-1]
        raise InputError(subject, f"{what}: Blender failed (exit {done.returncode}): {last[:300]}")
