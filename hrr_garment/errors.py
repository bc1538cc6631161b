"""Error types. Every user-facing error names the file (or object) and the problem."""

from __future__ import annotations


class HRRError(Exception):
    """Base class for errors the command-line tools report without a traceback."""


class InputError(HRRError):
    """Bad user input: names the offending file and says what is wrong with it."""

    def __init__(self, path: object, problem: str):
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class MotionError(InputError):
    """A motion file or array that cannot be used."""


class SkeletonMappingError(MotionError):
    """A source skeleton whose joints cannot be mapped onto the canonical skeleton."""
