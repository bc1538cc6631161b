"""hrr-body: make a body from the parametric model, or look at a body file.

    hrr-body make -o tall.json --height 0.8 --weight 0.3 --gender 1     # anny's phenotype, each in [0, 1]
    hrr-body make -o average.json                                        # its average adult
    hrr-body fit character.glb -o hero.json [--skin N] [--joint-map map.yaml] [--unit-scale S] [--parametric]
    hrr-body nearest clip.bvh -o performer.json      # the parametric body nearest to the clip's performer
    hrr-body info tall.json [--json] [--model DIR]      # --model: within the body range DIR was trained on?
    hrr-body info hero.json --model DIR --inside        # and how much cloth it puts inside the body

``make`` builds anny's body of that shape (the ``bodies`` extra; the first run builds its blend
shapes, 20-30 s, cached under the workspace), fits the canonical skeleton's bone lengths and
the collision capsules to it and writes body.json (docs/bodies.md), reporting its height and how
closely the capsules follow its surface. ``fit`` does the same for your character: a skinned glTF /
GLB's mesh in its bind pose and its skeleton's joints (Mixamo's names and the other known rigs,
or a joint map), in metres, Y up, facing +Z.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import fields, replace
from pathlib import Path
from typing import Sequence

from ..body.body_file import read_body, write_body
from ..body.measures import BODY_MEASURES, body_vector
from ..body.parametric import BodyShape
from ..errors import InputError
from ..io_utils import strict_json
from ._common import run_cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-body", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = p.add_subparsers(dest="command", required=True)
    make = sub.add_parser("make", help="a body of the parametric model's shape -> body.json")
    for f in fields(BodyShape):
        make.add_argument(
            f"--{f.name}", type=float, default=0.5, help=f"anny's {f.name}, in [0, 1] (default 0.5)"
        )
    make.add_argument("-o", "--output", type=Path, required=True, help="body.json to write")
    fit = sub.add_parser("fit", help="a skinned glTF / GLB character's mesh -> body.json")
    fit.add_argument("character", type=Path, help="a skinned .glb or .gltf")
    fit.add_argument("-o", "--output", type=Path, required=True, help="body.json to write")
    fit.add_argument(
        "--skin", type=int, default=None, help="which skin (default: the one with the most skinned vertices)"
    )
    fit.add_argument(
        "--joint-map",
        type=Path,
        default=None,
        help="YAML 'canonical_joint: your_joint' per line, for a rig whose names are not known",
    )
    fit.add_argument(
        "--unit-scale",
        type=float,
        default=None,
        help="metres per unit of the file (default 1, as glTF says; detected when implausible)",
    )
    fit.add_argument(
        "--parametric",
        action="store_true",
        help="also find the parametric (anny) shape nearest to the mesh, report the surface distance "
        "both ways and record the shape (the bodies extra)",
    )
    nearest = sub.add_parser("nearest", help="the parametric body nearest to a clip's performer -> body.json")
    nearest.add_argument("motion", type=Path, help="a BVH or glTF / GLB clip (its rig's proportions)")
    nearest.add_argument("-o", "--output", type=Path, required=True, help="body.json to write")
    nearest.add_argument(
        "--unit-scale", type=float, default=None, help="metres per file unit (default: detected)"
    )
    info = sub.add_parser("info", help="what a body file holds")
    info.add_argument("body", type=Path)
    info.add_argument("--json", action="store_true")
    info.add_argument(
        "--model",
        type=Path,
        default=None,
        help="a model folder: whether the body lies within the range it was trained on (exit 1 where not)",
    )
    info.add_argument(
        "--inside",
        action="store_true",
        help="with --model: animate a procedural walk on the body and on the model's own, and say how "
        "much of the cloth lies inside each before the push-out (the measures' range is each on its "
        "own; this asks the model)",
    )
    return p


def _summary(record) -> dict:
    rest = record.skeleton.rest_positions()
    return {
        "pelvis_height_m": round(record.pelvis_height, 4),
        "stature_m": round(record.stature, 4),
        "hip_width_m": round(float(rest[1, 0] - rest[2, 0]), 4),
        "shoulder_width_m": round(float(rest[16, 0] - rest[17, 0]), 4),
        "leg_length_m": round(float(rest[1, 1] - rest[7, 1]), 4),
        "capsules": len(record.body.capsules),
        "shape": record.shape,
        "measures_m": {
            k: round(float(v), 4) for k, v in zip(BODY_MEASURES, body_vector(record))
        },  # what models read
        "fit": record.report.to_dict() if record.report else None,
    }


def _fit_character(args) -> int:
    """hrr-body fit: read the character, fit the skeleton and capsules, write body.json."""
    from ..body.character import character_body
    from ..motion.joint_maps import load_joint_map

    joint_map = load_joint_map(args.joint_map) if args.joint_map is not None else None
    record, character = character_body(
        args.character, skin=args.skin, joint_map=joint_map, unit_scale=args.unit_scale
    )
    notes = [f"skin {character.skin}, {len(character.vertices)} vertices, {character.scheme} joint names"]
    if args.parametric:
        from ..body.parametric import fit_shape

        _announce_first_build()
        nearest = fit_shape(character.vertices, character.faces, joints=character.joints)
        record = replace(record, shape=nearest.shape.to_dict())
        notes.append(
            f"nearest parametric shape {_values(record.shape)}: surfaces {nearest.mean_mm:.1f} mm apart on "
            f"average (95th percentile {nearest.p95_mm:.1f} mm)"
        )
    write_body(args.output, record)
    if character.unit_scale != 1.0:
        notes.append(f"{character.unit_scale:g} m per file unit")
    if character.turned:
        notes.append("turned to stand Y up, facing +Z")
    if character.posed_joints:
        notes.append(
            f"read in its bind pose; {len(character.posed_joints)} joint(s) stood posed away from it"
        )
    if character.filled_joints:
        notes.append(f"placed {', '.join(character.filled_joints)}, which the skeleton lacks")
    notes.append(_mesh_note(record, character))
    fit = record.report
    print(
        f"wrote {args.output}: {record.stature:.3f} m tall, pelvis {record.pelvis_height:.3f} m over the "
        f"soles; capsules within {fit.mean_mm:.1f} mm of the surface on average (95th percentile "
        f"{fit.p95_mm:.1f} mm; {fit.outside_1cm:.0%} of vertices more than 1 cm outside) ({'; '.join(notes)})"
    )
    return 0


def _mesh_note(record, character) -> str:
    """What body.json keeps of the character's own mesh, the body the viewer sees."""
    from ..body.mesh_record import MAX_MESH_VERTICES

    if record.mesh is not None:
        return f"its skinned mesh kept as the body the viewer sees ({len(record.mesh.faces)} faces)"
    why = (
        "its file carries no skin weights"
        if character.weights is None
        else f"over {MAX_MESH_VERTICES} vertices or twice that in faces; decimate it to keep it"
    )
    return f"its mesh not kept ({why}): the body is drawn and collided as its capsules"


def _announce_first_build() -> None:
    """Say so before anny builds its blend shapes (20-30 s, once), which shows no progress."""
    from ..body.parametric import anny_cache, anny_cache_ready

    if not anny_cache_ready():
        print(
            f"hrr-body: building the parametric body's blend shapes, once (20-30 s on two cores; "
            f"cached in {anny_cache()})",
            file=sys.stderr,
        )


def _values(shape: dict) -> str:
    return ", ".join(f"{k} {v:.2f}" for k, v in shape.items())


def _nearest(args) -> int:
    """hrr-body nearest: the performer's proportions from the clip's rig, the nearest parametric body."""
    from ..body.parametric import parametric_body
    from ..body.proportions import nearest_body, source_proportions

    measures = source_proportions(args.motion, args.unit_scale)
    _announce_first_build()
    found = nearest_body(measures)
    body = parametric_body(found.shape)
    write_body(args.output, body)
    errors = ", ".join(f"{k} {v:+.0f}" for k, v in found.errors_mm.items())
    print(
        f"wrote {args.output}: {body.fitted.stature:.3f} m tall ({_values(body.shape.to_dict())}); the "
        f"performer's measures missed by {found.rms_mm:.1f} mm RMS ({errors} mm)"
    )
    return 0


def _inside(model: Path, record, name: str) -> dict:
    """The cloth inside the body and inside the model's own before the push-out, on the check's walk."""
    from ..eval.inside_body import CHECK_SECONDS, check_motion, cloth_inside
    from ..inference.animator import Animator

    animator, motion = Animator.load(model), check_motion()
    clip = {"clip": f"procedural walk of {CHECK_SECONDS:g} s"}
    return {
        f"body {name!r}": {**cloth_inside(animator, motion, record, name=name).to_dict(), **clip},
        "the model's own body": {**cloth_inside(animator, motion).to_dict(), **clip},
    }


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "info":
        if args.inside and args.model is None:
            raise InputError("hrr-body info", "--inside asks a model: give it with --model DIR")
        record = read_body(args.body)
        summary = _summary(record)
        outside = None
        if args.model is not None:  # before a held-out body's simulation: will this model animate it?
            from ..artifacts.bundle_loader import load_bundle
            from ..body.measures import body_vector

            bundle = load_bundle(args.model)
            body_range = bundle.body_range
            outside = body_range.outside(body_vector(record))
            summary["model"] = {
                "folder": str(args.model),
                "training_bodies": body_range.bodies,
                "outside": outside,
                "motion_licence": bundle.manifest.licences.to_dict(),
            }
            if args.inside:
                summary["model"]["inside_before_push_out"] = _inside(args.model, record, args.body.stem)
        print(
            strict_json(summary)  # a non-finite value prints as null, never NaN
            if args.json
            else "\n".join(f"{k}: {v}" for k, v in summary.items() if k != "model")
        )
        if outside is not None and not args.json:
            print(
                f"within the range of the {body_range.bodies} bodies {args.model} was trained on"
                if not outside
                else f"outside the range of the {body_range.bodies} bodies {args.model} was trained on: "
                + "; ".join(outside)
            )
            print(f"motion licence: {bundle.manifest.licences.statement}")
            for who, r in summary["model"].get("inside_before_push_out", {}).items():
                seen = (
                    f"{r['inside_visible_pct']:.2f} % of the cloth more than 5 mm inside the body the viewer "
                    f"sees (worst frame {r['inside_visible_worst_pct']:.2f} %)"
                    if r["visible_body"] != "unknown"
                    else "the body the viewer sees unknown (no mesh in its body.json)"
                )
                print(
                    f"inside {who} before the push-out, on a {r['clip']}: {seen}; inside its capsules "
                    f"{r['inside_pct']:.2f} % (worst frame {r['inside_worst_pct']:.2f} %)"
                )
        return 1 if outside else 0
    if args.output.suffix.lower() != ".json":
        raise InputError(args.output, "a body file is written as .json")
    if args.command == "nearest":
        return _nearest(args)
    if args.command == "fit":
        return _fit_character(args)
    try:
        shape = BodyShape(**{f.name: getattr(args, f.name) for f in fields(BodyShape)})
    except ValueError as exc:
        raise InputError("hrr-body", str(exc)) from None
    from ..body.parametric import parametric_body

    _announce_first_build()
    body = parametric_body(shape)
    write_body(args.output, body)
    summary = _summary(read_body(args.output))
    fit = body.fitted.report
    print(
        f"wrote {args.output}: {summary['stature_m']:.3f} m tall, pelvis {summary['pelvis_height_m']:.3f} m "
        f"over the soles; capsules within {fit.mean_mm:.1f} mm of the surface on average (95th percentile "
        f"{fit.p95_mm:.1f} mm)"
    )
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-body``; returns the exit status."""
    return run_cli(_main, argv, "hrr-body")


if __name__ == "__main__":
    sys.exit(main())
