"""Error types. Every user-facing error names the file (or object) and the problem."""

from __future__ import annotations


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


class TeleportWarning(UserWarning):
    """A streamed character's pelvis jumped faster than a body moves (a respawn, a cut): its garment
    was started afresh there rather than dragged across the jump."""


class SkeletonWarning(UserWarning):
    """A source skeleton that does not look like its joint names (swapped or mislabelled joints)."""
