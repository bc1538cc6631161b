"""Shared plumbing for the command-line tools: error reporting, exit codes, shared options."""

from __future__ import annotations

import argparse
import sys
from typing import Callable, Sequence

from ..artifacts.manifest import DETAIL_BASES, MAX_DETAIL_STRENGTH, valid_detail_strength
from ..errors import HRRError, InputError

EXIT_ERROR = 2


def add_fps_option(p: argparse.ArgumentParser) -> None:
    """``--fps``: the motion file's own frame rate, for files that carry none (or a wrong one)."""
    p.add_argument("--fps", type=float, default=None, metavar="RATE",
                   help="frame rate the motion file was captured at (for npz files without a rate key; "
                        "overrides a BVH's frame time)")


def add_detail_options(p: argparse.ArgumentParser) -> None:
    """``--detail-strength`` and ``--detail-base``: the detail mode's look, instead of the model's
    calibrated one (bundle.json ``auto``)."""
    p.add_argument("--detail-strength", type=float, default=None, metavar="S",
                   help=f"the detail mode's simulated folds at S x their simulated size, in (0, {MAX_DETAIL_STRENGTH:g}] "
                        "(default: the strength the model was calibrated to; 1: the folds as simulated)")
    p.add_argument("--detail-base", choices=DETAIL_BASES, default=None,
                   help="what the detail mode's folds ride on: the regression's shape or the residual mode's, which "
                        "brings the matched window's swing (default: the model's calibrated choice)")


def detail_options(args: argparse.Namespace) -> dict:
    """``--detail-strength`` / ``--detail-base`` as keyword arguments of ``Animator.animate`` (empty
    where they ask nothing); an InputError for a strength out of range."""
    if args.detail_strength is not None and not valid_detail_strength(args.detail_strength):
        raise InputError("--detail-strength", f"must be in (0, {MAX_DETAIL_STRENGTH:g}], got {args.detail_strength:g}")
    return {k: v for k, v in (("detail_base", args.detail_base), ("detail_strength", args.detail_strength)) if v is not None}


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
