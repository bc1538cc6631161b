"""hrr-simulate's garment options: a built-in template by name, or the user's own OBJ (its attached
group, its convention fitted onto the body, the body it was modelled on), and the garment they
resolve to."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..body.body_file import BodyRecord
from ..body.capsules import DEFAULT_BODY
from ..errors import InputError
from ..garment.mesh import GarmentMesh
from ..garment.obj import Placement, load_garment_obj, require_cloth
from ..garment.templates import GARMENT_NAMES, make_garment


def add_garment_options(p: argparse.ArgumentParser) -> None:
    """The options that pick a garment."""
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
        help="OBJ group whose vertices follow the body (with --template); 'auto': the top band lying on the "
        "torso",
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
        require_cloth(mesh, args.template)
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
