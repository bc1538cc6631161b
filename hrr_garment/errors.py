"""Error types. Every user-facing error names the file (or object) and the problem."""

from __future__ import annotations

import re
import sys


class HRRError(Exception):
    """Base class for errors the command-line tools report without a traceback."""


class FileProblem(HRRError):
    """An error about one file: the message is ``PATH: problem``."""

    def __init__(self, path: object, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class InputError(FileProblem, ValueError):
    """Bad user input: names the offending file (or argument) and says what is wrong with it. A
    ValueError too, so that an API caller's ``except ValueError`` sees every refused value."""


class OutputError(FileProblem):
    """An output that cannot be written (disk full, read-only folder, a device or folder in the way)."""


class MotionError(InputError):
    """A motion file or array that cannot be used."""


class SkeletonMappingError(MotionError):
    """A source skeleton whose joints cannot be mapped onto the canonical skeleton."""


class UnsupportedHardware(HRRError, RuntimeError):
    """An option this machine's processor (or its build of the kernels) cannot run."""


_INTERNAL = re.compile(r"(hrr_garment|torch)(\.|$)")  # the modules a warning's user line lies beyond


def user_stacklevel() -> int:
    """The ``stacklevel`` for a warning raised by the function that calls this one that points at the
    first frame outside the package and torch (whose decorators wrap some of the package's entry
    points): the user's line, however many of the package's frames lie between."""
    frame, level = sys._getframe(1), 1
    while frame is not None and _INTERNAL.match(str(frame.f_globals.get("__name__", ""))):
        frame, level = frame.f_back, level + 1
    return level


class TeleportWarning(UserWarning):
    """A streamed character's pelvis jumped faster than a body moves (a respawn, a cut): its garment
    was started afresh there rather than dragged across the jump."""


class SkeletonWarning(UserWarning):
    """A source skeleton that does not look like its joint names (swapped or mislabelled joints)."""
