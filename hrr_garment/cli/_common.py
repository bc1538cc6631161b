"""Shared plumbing for the command-line tools: error reporting, exit codes, shared options."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from typing import Callable, Sequence

from ..artifacts.manifest import DETAIL_BASES, MAX_DETAIL_STRENGTH
from ..errors import HRRError, InputError
from ..inference.run_settings import DECODERS, PUSH_BODIES, PUSHES, DetailLook, RunSettings
from ..input_files import guarding_inputs
from ..io_utils import is_storage_error

EXIT_ERROR = 2


def add_fps_option(p: argparse.ArgumentParser) -> None:
    """``--fps``: the motion file's own frame rate, for files that carry none (or a wrong one)."""
    p.add_argument(
        "--fps",
        type=float,
        default=None,
        metavar="RATE",
        help="frame rate the motion file was captured at (for npz files without a rate key; "
        "overrides a BVH's frame time)",
    )


def add_cloth_options(p: argparse.ArgumentParser, fabrics: Sequence[str]) -> None:
    """``--material``, ``--air-drag`` and ``--cloth-viscosity``: the cloth a simulation runs in
    (hrr-simulate, hrr-make)."""
    p.add_argument(
        "--material",
        default=None,
        metavar="FABRIC",
        help="the cloth: a fabric (" + ", ".join(fabrics) + "), a fabric with values changed "
        "(denim,bend=4e-5), values (density=0.2,stretch=5000,shear=2000,bend=1e-5,damping=0.1: kg/m^2, "
        "N/m, N/m, N m, s) or a YAML file of them; default: the preset's, else the project's cloth "
        "(docs/materials.md)",
    )
    p.add_argument(
        "--air-drag",
        type=float,
        default=None,
        metavar="CD",
        help="the air's drag on the cloth, as a drag coefficient (about 1.2 for a sheet; 0: none); "
        "default: the preset's, else none",
    )
    p.add_argument(
        "--cloth-viscosity",
        type=float,
        default=None,
        metavar="NU",
        help="the cloth's internal friction, a viscosity in m^2/s that lets the cloth come to rest "
        "(0.02: a dress settles after a stop; 0: none); default: the preset's, else none",
    )


def add_decoder_option(p: argparse.ArgumentParser) -> None:
    """``--decoder``: the full mesh decoder or the bundle's fast (subspace) decoder."""
    p.add_argument(
        "--decoder",
        choices=DECODERS,
        default=None,
        help="mesh decoder: full (the autoencoder's; default) or fast (its distilled subspace decoder, "
        "several times cheaper; where the model has one: hrr-train --stage subspace)",
    )


def add_sample_options(p: argparse.ArgumentParser) -> None:
    """``--seed`` and ``--sample-steps``: the sample mode's draw."""
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="the sample mode's seed: the same seed draws the same cloth, another seed another cloth as "
        "likely (default 0)",
    )
    p.add_argument(
        "--sample-steps",
        type=int,
        default=None,
        help="the sample mode's integration steps a frame (network evaluations; default: the model's)",
    )


def add_no_push_out_option(p: argparse.ArgumentParser, help: str) -> None:
    """``--no-push-out`` (its old name ``--no-collision`` still read): the run without the push-out."""
    p.add_argument("--no-push-out", "--no-collision", dest="no_push_out", action="store_true", help=help)


def add_push_option(p: argparse.ArgumentParser) -> None:
    """``--push``: how the push-out takes the cloth out of the body."""
    p.add_argument(
        "--push",
        choices=PUSHES,
        default=None,
        help="the collision push-out: mesh (each vertex to the nearest surface; default) or subspace (first "
        "the whole garment along the fast decoder's components: fewer tears, about 2.5 x the push-out's "
        "cost; where the model has a fast decoder)",
    )
    p.add_argument(
        "--push-body",
        choices=PUSH_BODIES,
        default=None,
        help="what the push-out pushes the cloth out of: visible (the mesh the viewer sees, where the body "
        "has one: an anny body's, a character's own; default) or "
        "capsules (the collision capsules: cheaper, but skin shows through where the mesh lies outside)",
    )


def add_detail_options(p: argparse.ArgumentParser) -> None:
    """``--detail-strength`` and ``--detail-base``: the detail mode's look, instead of the model's
    calibrated one (bundle.json ``auto``)."""
    p.add_argument(
        "--detail-strength",
        type=float,
        default=None,
        metavar="S",
        help="the detail mode's simulated folds at S x their simulated size, in (0, "
        f"{MAX_DETAIL_STRENGTH:g}] (default: the strength the model was calibrated to; 1: the folds as "
        "simulated)",
    )
    p.add_argument(
        "--detail-base",
        choices=DETAIL_BASES,
        default=None,
        help="what the detail mode's folds ride on: the regression's shape or the residual mode's, which "
        "brings the matched window's swing (default: the model's calibrated choice)",
    )
    p.add_argument(
        "--swing",
        type=float,
        default=None,
        metavar="GAIN",
        help="the free cloth's swing restored: GAIN on the latents' departure from their recent course "
        "(1: as predicted; default: the model's calibrated gain in the auto mode, 1 in a mode named)",
    )
    p.add_argument(
        "--settle",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="the cloth settling after a stop: the time constant of the garment's lag towards the "
        "model's prediction, fading out over four of them (default 0: none; docs/materials.md has "
        "its measured trade)",
    )


def detail_look(args: argparse.Namespace) -> DetailLook:
    """``--detail-strength`` / ``--detail-base`` as a :class:`DetailLook` (nothing chosen where
    neither is given); an InputError naming the flag for a value it cannot take."""
    try:
        return DetailLook(args.detail_base, args.detail_strength)
    except (TypeError, ValueError) as exc:
        raise InputError("--detail-strength", str(exc)) from None


def run_settings_of(args: argparse.Namespace, prog: str, **fields) -> RunSettings:
    """``--mode`` (where the command has it), ``--gate`` and ``--tau`` and ``fields`` as
    :class:`RunSettings`; an InputError for values or combinations they cannot take."""
    try:
        return RunSettings(
            **({"mode": args.mode} if hasattr(args, "mode") else {}),
            gate=args.gate,
            tau=args.tau,
            decoder=getattr(args, "decoder", None),
            swing=getattr(args, "swing", None),
            settle=getattr(args, "settle", 0.0),
            push=getattr(args, "push", None),
            push_body=getattr(args, "push_body", None),
            **{k: getattr(args, k) for k in ("seed", "sample_steps") if hasattr(args, k)},
            **fields,
        )
    except (TypeError, ValueError) as exc:
        raise run_settings_error(exc) from None


# the RunSettings fields a command's flags set, by the name their errors begin with
RUN_FLAGS = ("tau", "gate", "mode", "swing", "settle", "push_body", "seed", "sample_steps")


def run_settings_error(exc: Exception) -> InputError:
    """An InputError naming the flag a :class:`RunSettings` error is about (its message begins with
    the field's name), or the run settings as a whole."""
    message = str(exc)
    flag = next(
        (f"--{name.replace('_', '-')}" for name in RUN_FLAGS if message.startswith(name)), "the run settings"
    )
    return InputError(flag, message)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the command is: it unwinds as Ctrl-C does (temporary files removed,
    worker pools shut down) instead of ending the process on the spot."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def run_cli(body: Callable[[Sequence[str] | None], int], argv: Sequence[str] | None, prog: str) -> int:
    """Run a command body; expected errors become one line on stderr and a non-zero exit; SIGINT and
    SIGTERM end it cleanly (exit 130 and 143)."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        with guarding_inputs():  # what the command reads, no output of it may replace
            return body(argv)
    except HRRError as exc:
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except ImportError as exc:  # optional extras name themselves in the message
        print(f"{prog}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except OSError as exc:
        # The storage refusing a path no writer wrapped (a folder made for an output, a lock file):
        # still one line naming the path. Anything else is a bug and keeps its traceback.
        if exc.filename is None or not is_storage_error(exc):
            raise
        reason = os.strerror(exc.errno) if exc.errno else str(exc)
        print(f"{prog}: error: {exc.filename}: {reason}", file=sys.stderr)
        return EXIT_ERROR
    except Terminated:
        print(f"{prog}: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    finally:
        if main_thread:  # a caller's own handler back (tests and scripts call mains in-process)
            signal.signal(signal.SIGTERM, previous)
