"""hrr-make: your character and your garment in one command, within a time budget: the body fitted,
the garment placed, a motion library chosen for coverage and simulated on the character, a model
trained, and the ONNX graph, the character's clips with the garment, a preview and a report written.

    hrr-make hero.glb --garment hero_dress.obj -o hero/               # 60 minutes on this machine
    hrr-make hero.glb --garment hero_dress.obj -o hero/ --budget 2h   # more data, longer training
    hrr-make hero.glb --garment dress -o hero/                        # the built-in dress, carried onto hero
    hrr-make body.json --garment skirt -o out/ --library real-quick   # Bandai motion: non-commercial
    hrr-make hero.glb --garment dress -o hero/ --material denim --air-drag 1.2   # in denim, in air

Writes into OUT: body.json, dataset.h5, model/, outputs/ (NAME.onnx, NAME_CLIP.glb for each of the
character's animations, preview.png, report/, summary.json) and make.json, the record of every stage:
what it was made from, how long it took against the plan, and the commands that remake it. The plan
is printed before the long work: the first minutes measure this machine's simulator, and the
budget decides how many frames to simulate and how long to train. Ctrl-C stops it; the same
command goes on where it stopped. Run again with another garment into the same OUT, it keeps the
body and the motion library's features and makes the rest again. See docs/make.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..errors import InputError
from ..garment.fabrics import FABRICS
from ..garment.material import parse_material
from ..io_utils import require_writable_place
from ..pipeline.make_budget import OUTPUT_STAGES, BudgetTooSmall, parse_budget
from ..pipeline.make_library import SELECTIONS
from ..sim.preset import preset_names
from ._common import add_cloth_options, run_cli

DEFAULT_LIBRARY = "real-quick-commercial"  # motion a studio may ship (docs/licences.md)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-make", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("character", type=Path, help="a skinned .glb / .gltf character, or a body.json")
    p.add_argument(
        "--garment",
        required=True,
        help="an OBJ modelled on the character (Y up, metres, its frame), or a built-in garment's name",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="the folder to write (and resume)")
    p.add_argument("--budget", default="60m", help="wall-clock budget for the whole run: 60m, 2h, 1h30m")
    p.add_argument(
        "--library",
        default=DEFAULT_LIBRARY,
        help=f"the motion library preset ({', '.join(preset_names())}; default {DEFAULT_LIBRARY}: CMU "
        "and procedural motion, which a commercial product may use)",
    )
    p.add_argument(
        "--attached",
        default="auto",
        metavar="GROUP",
        help="the OBJ's group that follows the body (default auto: the top band lying on the torso)",
    )
    p.add_argument(
        "--fit", action="store_true", help="the OBJ is in another convention: detect its unit and up axis"
    )
    p.add_argument(
        "--made-for",
        type=Path,
        default=None,
        metavar="BODY",
        help="the body the OBJ was modelled on, when not the character: a body.json, or a body mesh OBJ "
        "without a rig (the nearest parametric body is fitted to it)",
    )
    p.add_argument(
        "--selection",
        choices=SELECTIONS,
        default="coverage",
        help="which library clips the budget takes: coverage (default) or random",
    )
    add_cloth_options(p, FABRICS)
    p.add_argument("--jobs", type=int, default=None, help="simulation workers (default: one per core)")
    p.add_argument(
        "--device",
        default=None,
        help="the simulator's device, cpu or cuda:0 (default: auto); on CUDA the autoencoder trains there",
    )
    p.add_argument(
        "--batch",
        type=int,
        default=0,
        metavar="N",
        help="simulate up to N sequences together in one model (for a GPU, with --device cuda:0)",
    )
    p.add_argument("--seed", type=int, default=0, help="the random selection's seed")
    p.add_argument(
        "--skip",
        nargs="+",
        default=[],
        choices=OUTPUT_STAGES,
        help="outputs not to make (their time goes to data and training)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress display")
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..pipeline.make_record import MakeRequest
    from .make_run import MakeRun  # torch and the simulator: after the arguments

    try:
        budget = parse_budget(args.budget)
    except ValueError as exc:
        raise InputError("--budget", str(exc)) from None
    if args.output.exists() and not args.output.is_dir():
        raise InputError(args.output, "is a file; hrr-make writes a folder")
    require_writable_place(args.output)
    if args.material is not None:  # a typo refused now, not after the body's fit
        parse_material(args.material, "--material")
    if args.air_drag is not None and not 0.0 <= args.air_drag <= 10.0:
        raise InputError(
            "--air-drag", f"a drag coefficient is between 0 and 10 (a sheet: about 1.2), got {args.air_drag}"
        )
    if args.cloth_viscosity is not None and not 0.0 <= args.cloth_viscosity <= 1.0:
        raise InputError(
            "--cloth-viscosity",
            f"a viscosity is between 0 and 1 m^2/s (0.02: a dress settles), got {args.cloth_viscosity}",
        )
    request = MakeRequest(
        character=args.character,
        garment=args.garment,
        out=args.output,
        budget_s=budget,
        library=args.library,
        attached=args.attached,
        fit=args.fit,
        made_for=args.made_for,
        selection=args.selection,
        jobs=args.jobs,
        device=args.device,
        batch=args.batch,
        progress=not args.quiet,
        seed=args.seed,
        skip=tuple(args.skip),
        material=args.material,
        air_drag=args.air_drag,
        cloth_viscosity=args.cloth_viscosity,
    )
    try:
        MakeRun(request).run()
    except BudgetTooSmall as exc:
        raise InputError("--budget", str(exc)) from None
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-make``; returns the exit status."""
    return run_cli(_main, argv, "hrr-make")


if __name__ == "__main__":
    sys.exit(main())
