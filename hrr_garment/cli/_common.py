"""Shared plumbing for the command-line tools: error reporting, exit codes, shared options."""

from __future__ import annotations

import argparse
import contextlib
import sys
from typing import TYPE_CHECKING, Callable, ContextManager, Sequence

from ..artifacts.manifest import DETAIL_BASES, MAX_DETAIL_STRENGTH, valid_detail_strength
from ..errors import HRRError, InputError

if TYPE_CHECKING:
    from ..artifacts.bundle import Bundle

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


def detail_setting(args: argparse.Namespace, bundle: "Bundle") -> ContextManager[None]:
    """The detail mode as ``--detail-strength`` / ``--detail-base`` ask, for a ``with`` block (the
    model's calibrated setting where they ask nothing): an InputError for a strength out of range or
    a residual base the model cannot run."""
    if args.detail_strength is None and args.detail_base is None:
        return contextlib.nullcontext()
    if args.detail_strength is not None and not valid_detail_strength(args.detail_strength):
        raise InputError("--detail-strength", f"must be in (0, {MAX_DETAIL_STRENGTH:g}], got {args.detail_strength:g}")
    bundle.require_folds()
    base = args.detail_base or bundle.detail_base
    if base == "residual":
        bundle.require_residual()
        if bundle.residual_weight <= 0:
            raise InputError(bundle.folder, "its residual weight is calibrated to 0, so the residual mode is the "
                                            "regression: use --detail-base regression")
    return bundle.detail_on(base, args.detail_strength)


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
