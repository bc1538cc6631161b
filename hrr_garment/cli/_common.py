"""Shared plumbing for the command-line tools: error reporting and exit codes."""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

from ..errors import HRRError

EXIT_ERROR = 2


def add_fps_option(p: argparse.ArgumentParser) -> None:
    """``--fps``: the motion file's own frame rate, for files that carry none (or a wrong one)."""
    p.add_argument("--fps", type=float, default=None, metavar="RATE",
                   help="frame rate the motion file was captured at (for npz files without a rate key; "
                        "overrides a BVH's frame time)")


def run_cli(body: Callable[[Sequence[str] | None], int], argv: Sequence[str] | None, prog: str) -> int:
    """Run a command body; expected errors become one line on stderr and a non-zero exit."""
    try:
        return body(argv)
    except HRRError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except ImportError as exc:  # optional extras name themselves in the message
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
