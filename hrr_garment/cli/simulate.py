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

Re-running the same command skips sequences already simulated (kept in DATASET.parts/).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Sequence

from ..body.body_file import BodyRecord, body_to_dict, read_body
from ..body.capsules import DEFAULT_BODY
from ..errors import InputError
from ..garment.mesh import GarmentMesh
from ..garment.obj import Placement, load_garment_obj
from ..garment.templates import GARMENT_NAMES, make_garment
from ..io_utils import refuse_input_as_output, require_suffix
from ..paths import workspace
from ..sim.plan import build_options, plan_sequences
from ..sim.preset import load_preset, preset_names
from ._common import add_fps_option, run_cli


def add_garment_options(p: argparse.ArgumentParser) -> None:
    """The options that pick a garment (shared with hrr-train)."""
    p.add_argument(
        "--garment",
        default=None,
        help=f"built-in template: {', '.join(GARMENT_NAMES)} (or the name of --template)",
    )
    p.add_argument(
        "--template",
        type=Path,
        default=None,
        help="your own garment OBJ in the canonical rest pose (Y up, metres)",
    )
    p.add_argument(
        "--attached",
        default=None,
        metavar="GROUP",
        help="OBJ group whose vertices follow the body (with --template); 'auto': the top band lying on the torso",
    )
    p.add_argument(
        "--attached-file",
        type=Path,
        default=None,
        help="file of 0-based attached vertex indices (with --template)",
    )
    p.add_argument("--vertices", type=int, default=None, help="template resolution (default: the preset's)")
    p.add_argument(
        "--fit",
        action="store_true",
        help="the OBJ is in another convention: detect its unit and up axis and place it on the body",
    )
    p.add_argument(
        "--up",
        default=None,
        choices=("+x", "-x", "+y", "-y", "+z", "-z"),
        help="with --fit: the OBJ's up axis",
    )
    p.add_argument(
        "--unit", default=None, choices=("m", "cm", "mm", "in"), help="with --fit: the OBJ's length unit"
    )
    p.add_argument(
        "--made-for",
        type=Path,
        default=None,
        metavar="BODY_JSON",
        help="the body your --template was modelled on (body.json from hrr-body; the OBJ in that body's "
        "frame): the garment is carried from it onto the body simulated, which is this one unless "
        "--body or the preset names others",
    )
    p.add_argument(
        "--dense-ok",
        action="store_true",
        help="simulate a template far denser than the preset's resolution anyway (slow; see --preset full)",
    )


DENSE_FACTOR = 3  # a template with more than this many times the preset's vertices is refused


def resolve_garment(
    args: argparse.Namespace, default_vertices: int, made_for: BodyRecord | None = None
) -> GarmentMesh:
    """The garment the options name: a template, or the user's OBJ (fitted, its attached vertices
    found, and refused when far denser than the preset's resolution unless --dense-ok)."""
    if args.template is not None:
        notes: list[str] = []
        mesh = load_garment_obj(
            args.template,
            args.garment,
            attached_group=args.attached,
            attached_file=args.attached_file,
            placement=Placement(
                fit=args.fit,
                up=args.up,
                unit=args.unit,
                body=made_for.body if made_for is not None else DEFAULT_BODY,
            ),
            notes=notes,
        )
        for note in notes:
            print(note)
        if mesh.num_vertices > DENSE_FACTOR * default_vertices and not args.dense_ok:
            raise InputError(
                args.template,
                f"has {mesh.num_vertices:,} vertices, far more than this preset's "
                f"{default_vertices:,}: the solver settings are tuned for that resolution "
                "and the simulation time grows with it. Decimate the mesh to about "
                f"{default_vertices:,} vertices, use a denser preset (--preset full: 4,000), "
                "or pass --dense-ok",
            )
        return mesh
    if args.fit or args.up or args.unit or args.made_for:
        raise InputError(
            "--made-for" if args.made_for else "--fit", "places your own garment: use it with --template OBJ"
        )
    if args.garment is None:
        raise InputError("hrr-simulate", "give --garment NAME or --template OBJ")
    return make_garment(args.garment, args.vertices or default_vertices)


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


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..export.preview import write_dataset_preview
    from ..sim.bodies import choose_bodies
    from ..sim.build import BuildOptions, build_dataset
    from ..sim.simulator import SimConfig

    preset = load_preset(args.preset)
    if args.made_for and args.fit:
        raise InputError(
            "--fit",
            "moves a garment onto the mannequin; a garment declared --made-for its body is carried, not moved",
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
    overrides = {
        k: v
        for k, v in (("substeps", args.substeps), ("iterations", args.iterations), ("device", args.device))
        if v is not None
    }
    config = SimConfig.from_dict({**preset.sim, **overrides})
    out = args.output
    if out is None:
        suffix = f"-{args.vertices}v" if args.vertices else ""
        on = f"-on-{Path(args.body).stem}" if args.body else ""
        out = workspace() / "datasets" / f"{garment.name}-{preset.name}{suffix}{on}.h5"
    require_suffix(out, (".h5", ".hdf5"), "a dataset")
    refuse_input_as_output(out, [*(args.motions or []), args.template, args.body, args.made_for])
    options = build_options(preset, choice.specs)
    options["info"]["garment_vertices"] = garment.num_vertices
    if choice.bodies:
        options["info"]["bodies"] = choice.info
    if made_for is not None:  # models trained on it carry the garment from this body onto others
        options["info"]["made_for"] = body_to_dict(made_for)
    options["info"]["motions"] = list(args.motions) if args.motions else None  # None: the preset's own clips
    if args.address and args.executor != "ray":
        raise InputError("--address", "joins a Ray cluster: use it with --executor ray")
    build = BuildOptions(
        jobs=args.jobs,
        retry_rejected=args.retry_rejected,
        preview=None if args.no_preview else write_dataset_preview,
        progress=not args.quiet,
        executor=args.executor,
        address=args.address,
        bodies=choice.bodies,
        hold_out_bodies=choice.hold_out,
        batch=args.batch,
        **options,
    )
    report = build_dataset(garment, choice.specs, config, out=out, options=build)
    print_report(report, garment)
    return 0


def print_report(report, garment: GarmentMesh) -> None:
    """Print a dataset build's summary."""
    s = report.summary
    print(
        f"wrote {report.path}: {s['sequences']} sequences, {s['frames']} frames, {garment.num_vertices} vertices "
        f"({report.reused} reused, {report.simulated} simulated now, {len(report.rejects)} rejected)"
    )
    print(
        f"  strain p99 {s['strain_p99']:.3f} (max {s['strain_max']:.2f}); penetration: worst frame "
        f"{100 * s['penetration_frame_max']:.2f} % of vertices > 5 mm inside, mean {100 * s['penetration_mean']:.3f} %"
    )
    print(
        f"  {s['self_intersection_frames']} frame(s) where the motion's limbs pass through the body; worst frame "
        f"outside them {100 * s['penetration_frame_max_clean']:.2f} %"
    )
    if s["sim_frames_per_core_s"]:
        print(
            f"  {s['sim_frames_per_core_s']:.2f} simulated frames/s per core (lead-in included); wall {s['sim_wall_s']:.0f} s"
        )
    sp = s.get("splices", {})
    if sp.get("asked"):
        print(
            f"  splices: {sp['made']} of {sp['asked']} (legs of one training clip, upper body of another; "
            f"{sp['refused_self_intersection']} of {sp['drawn']} drawn refused for limbs through the body)"
        )
    if sp.get("backward_asked"):
        short = (
            ""
            if sp["backward_made"] == sp["backward_asked"]
            else " (fewer than asked: no training clip from a motion file is that long, or some failed to simulate)"
        )
        print(
            f"  played backward: {sp['backward_made']} of {sp['backward_asked']} windows of training clips{short}"
        )
    for name, row in s.get("by_body", {}).items():
        print(
            f"  body {name or 'mannequin'} ({row['stature_m']:.2f} m): {row['sequences']} sequences, {row['frames']} frames, "
            f"strain p99 {row['strain_p99']:.3f}"
        )
    print(
        "  hem swing (m) by kind: "
        + json.dumps({k: round(v, 3) for k, v in s["hem_swing_m_by_kind"].items()})
    )
    for name, reason in report.rejects.items():
        print(f"  rejected {name}: {reason}")
    if report.preview:
        print(f"  preview: {report.preview}")


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-simulate``; returns the exit status."""
    return run_cli(_main, argv, "hrr-simulate")


if __name__ == "__main__":
    sys.exit(main())
