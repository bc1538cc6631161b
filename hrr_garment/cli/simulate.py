"""hrr-simulate: build a garment dataset by cloth simulation (resumable; needs the ``sim`` extra).

Examples::

    hrr-simulate --garment dress --preset quick            # -> hrr_work/datasets/dress-quick.h5
    hrr-simulate --garment skirt --preset tiny --motions walk spin ../shared/data/mocap/cmu/02_01.bvh
    hrr-simulate --template my_dress.obj --attached waistband --preset quick
    hrr-simulate --template artist_dress.obj --fit --attached auto --preset quick   # another convention
    hrr-simulate --garment dress --preset real-quick --executor ray --address HEAD:6379
    hrr-simulate --garment dress --preset real-quick --body hero.json        # on your character's body
    hrr-simulate --template hero_dress.obj --made-for hero.json --attached auto --preset real-quick
    hrr-simulate --garment dress --preset real-quick-bodies                  # on 16 sampled bodies
    hrr-simulate --garment dress --preset quick --material denim --air-drag 1.2   # a fabric, in air
    hrr-simulate --garment skirt --preset quick --material jersey,bend=2e-5  # a fabric, one value changed

Re-running the same command skips sequences already simulated (kept in DATASET.parts/).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path
from typing import Sequence

from ..body.body_file import body_to_dict, read_body
from ..errors import InputError
from ..garment.fabrics import FABRICS
from ..garment.material import material_file, parse_material
from ..io_utils import refuse_input_as_output, require_suffix, require_writable_place
from ..paths import workspace
from ..sim.plan import build_options, plan_sequences
from ..sim.preset import load_preset, preset_names
from ._common import add_cloth_options, add_fps_option, run_cli
from .build_summary import print_build_report
from .garment_options import add_garment_options, resolve_garment


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-simulate", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_garment_options(p)
    p.add_argument(
        "--preset", default="quick", help=f"{', '.join(preset_names())} or a YAML file (default quick)"
    )
    p.add_argument(
        "--motions",
        nargs="+",
        default=None,
        metavar="KIND_OR_FILE",
        help="instead of the preset's clips: one clip per kind named (repeat for more) plus motion files",
    )
    p.add_argument(
        "--seconds", type=float, default=None, help="length of each procedural clip (default: the preset's)"
    )
    add_fps_option(p)
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="worker processes (default: one per core); with "
        "--executor ray and no --address, the CPUs of the local Ray instance",
    )
    p.add_argument(
        "--executor",
        choices=("local", "ray"),
        default="local",
        help="local process pool (default), or one Ray task per sequence (extra 'cluster')",
    )
    p.add_argument(
        "--address", default=None, help="Ray cluster to join (with --executor ray; e.g. HEAD:6379 or auto)"
    )
    p.add_argument("--substeps", type=int, default=None, help="override the preset's substeps per frame")
    p.add_argument("--iterations", type=int, default=None, help="override the preset's solver iterations")
    p.add_argument("--device", default=None, help="warp device: auto (default), cpu, cuda:0")
    add_cloth_options(p, FABRICS)
    p.add_argument(
        "--batch",
        type=int,
        default=0,
        metavar="N",
        help="simulate up to N sequences of similar length together in one model, each in its own world "
        "(one batch per worker or Ray task; for a GPU: --device cuda:0); 0 or 1: one at a time (default)",
    )
    p.add_argument(
        "--body",
        type=Path,
        default=None,
        metavar="BODY_JSON",
        help="simulate every sequence on this body (hrr-body make / fit / nearest) instead of the mannequin "
        "or the preset's bodies",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="dataset .h5 (default: hrr_work/datasets/GARMENT-PRESET.h5)",
    )
    p.add_argument(
        "--retry-rejected",
        action="store_true",
        help="simulate sequences an earlier run rejected again (after upgrading the simulator)",
    )
    p.add_argument("--no-preview", action="store_true", help="skip the preview image")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _sim_overrides(args, preset) -> dict:
    """The command line's simulator settings over the preset's: the solver's, the air's and the cloth
    (which, on a preset that gives each sequence its own, takes the place of its materials section:
    :func:`_preset`)."""
    overrides = {
        k: v
        for k, v in (
            ("substeps", args.substeps),
            ("iterations", args.iterations),
            ("device", args.device),
            ("air_drag", args.air_drag),
            ("cloth_viscosity", args.cloth_viscosity),
        )
        if v is not None
    }
    if args.material is not None:
        overrides["material"] = parse_material(args.material, "--material")
    elif preset.materials and preset.sim.get("material") is not None:
        print(f"preset {preset.name}: its materials section gives each sequence its cloth, not sim.material")
    return overrides


def _preset(args):
    """The preset named, and whether ``--material`` took the place of its materials section (its
    clips and solver in that one cloth: a specialist's data)."""
    preset = load_preset(args.preset)
    if args.material is not None and preset.materials:
        print(f"preset {preset.name} in one cloth: --material takes the place of its materials section")
        return replace(preset, materials={}), True
    return preset, False


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..export.preview import write_dataset_preview
    from ..sim.body_plan import choose_bodies
    from ..sim.build import BuildSettings, build_dataset
    from ..sim.material_plan import choose_materials
    from ..sim.simulator import SimSettings

    preset, one_cloth = _preset(args)
    if args.made_for and args.fit:
        raise InputError(
            "--fit",
            "moves a garment onto the mannequin; a garment declared --made-for its body is carried, not "
            "moved",
        )
    made_for = read_body(args.made_for) if args.made_for else None
    garment = resolve_garment(args, preset.vertices, made_for)
    specs = plan_sequences(preset, args.motions, args.seconds, source_fps=args.fps)
    choice = choose_bodies(
        specs,
        garment,
        preset_bodies=preset.bodies,
        where=args.preset,
        body_file=args.body,
        made_for=made_for,
        progress=not args.quiet,
    )
    for note in choice.notes:
        print(note)
    cloths = choose_materials(choice.specs, preset.materials, args.preset)
    overrides = _sim_overrides(args, preset)
    config = SimSettings.from_dict({**preset.sim, **overrides})
    out = args.output
    if out is None:
        suffix = f"-{args.vertices}v" if args.vertices else ""
        on = f"-on-{Path(args.body).stem}" if args.body else ""
        cloth = f"-{config.material.name}" if args.material is not None else ""
        out = workspace() / "datasets" / f"{garment.name}-{preset.name}{suffix}{on}{cloth}.h5"
    require_suffix(out, (".h5", ".hdf5"), "a dataset")
    cloth_file = material_file(args.material) if args.material is not None else None
    inputs = [*(args.motions or []), args.template, args.body, args.made_for, args.attached_file, cloth_file]
    refuse_input_as_output(out, inputs)
    require_writable_place(out)
    options = build_options(preset, cloths.specs, args.motions)
    options["info"]["garment_vertices"] = garment.num_vertices
    if choice.bodies:
        options["info"]["bodies"] = choice.info
    if cloths.materials:
        options["info"]["materials"] = cloths.info
    if one_cloth:  # not the preset's dataset: hrr-train --garment must not rebuild it as one
        options["info"]["in_one_cloth"] = config.material.name
    if made_for is not None:  # models trained on it carry the garment from this body onto others
        options["info"]["made_for"] = body_to_dict(made_for)
    options["info"]["motions"] = list(args.motions) if args.motions else None  # None: the preset's own clips
    if args.address and args.executor != "ray":
        raise InputError("--address", "joins a Ray cluster: use it with --executor ray")
    build = BuildSettings(
        jobs=args.jobs,
        retry_rejected=args.retry_rejected,
        preview=None if args.no_preview else write_dataset_preview,
        progress=not args.quiet,
        executor=args.executor,
        address=args.address,
        bodies=choice.bodies,
        hold_out_bodies=choice.hold_out,
        hold_out_materials=cloths.hold_out,
        batch=args.batch,
        **options,
    )
    report = build_dataset(garment, cloths.specs, config, out=out, options=build)
    print_build_report(report, garment)
    air = f"air drag: drag coefficient {config.air_drag:g}; cloth viscosity {config.cloth_viscosity:g} m^2/s"
    if cloths.materials:
        print(
            f"  cloths: {len(cloths.materials)} ({', '.join(cloths.materials)}), "
            f"each sequence in its own; {air}"
        )
    elif config.material is not None or config.air_drag or config.cloth_viscosity:
        cloth = config.material.describe() if config.material is not None else "the project's cloth"
        print(f"  cloth: {cloth}; {air}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-simulate``; returns the exit status."""
    return run_cli(_main, argv, "hrr-simulate")


if __name__ == "__main__":
    sys.exit(main())
