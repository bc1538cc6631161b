"""hrr-make's data: the character's own animations as clips, the garment placed on the character, and
the chosen clips simulated on it (the probe's few, then the plan's all, into one dataset whose
finished sequences the second build reuses)."""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from ..body.body_file import BodyRecord
from ..errors import InputError
from ..pipeline.make_library import MotionLibrary
from ..sim.plan import safe_name

MIN_ANIMATION_FRAMES = 60  # an animation under 2 s is a pose, not motion to learn from
OWN_PREFIX = "own_"  # a character's clip is never named like a library sequence


def own_animations(character: Path, folder: Path) -> list[str]:
    """The character's own glTF animations (at least two seconds each), written into ``folder`` as
    motion files the library takes (the folder made again); their names."""
    from ..motion.gltf_animation import gltf_animations
    from ..motion.io import load_motion
    from ..motion.native_file import save_motion

    shutil.rmtree(folder, ignore_errors=True)
    names, files = [], set()
    for animation in gltf_animations(character):
        motion = load_motion(character, animation=animation.index)
        if motion.num_frames < MIN_ANIMATION_FRAMES:
            continue
        stem, k = OWN_PREFIX + safe_name(animation.name), 1
        while stem in files:  # two names alike once made safe: the second numbered
            k += 1
            stem = f"{OWN_PREFIX}{safe_name(animation.name)}_{k}"
        files.add(stem)
        folder.mkdir(parents=True, exist_ok=True)
        save_motion(motion, folder / f"{stem}.npz")
        names.append(animation.name)
    return names


def check_garment(request) -> None:
    """Refuse a garment that names neither an OBJ nor a built-in template, before any work."""
    from ..garment.templates import GARMENT_NAMES

    obj = Path(request.garment)
    if obj.suffix.lower() == ".obj":
        if not obj.exists():
            raise InputError(obj, "no such file")
    elif request.garment not in GARMENT_NAMES:
        raise InputError(
            request.garment, f"is neither an OBJ nor a built-in garment ({', '.join(GARMENT_NAMES)})"
        )
    if request.made_for is not None and not Path(request.made_for).exists():
        raise InputError(request.made_for, "no such file")


def place_garment(request, body: BodyRecord, vertices: int):
    """The garment ``request`` names: an OBJ modelled on the character ``body``, or on the body
    ``request.made_for`` names (:func:`garment_body`), its attached band found or named
    (``request.fit``: another unit or up axis); or a built-in template made for the mannequin. The
    build carries it onto the character. Returns the mesh and the body it was modelled on (None: the
    mannequin)."""
    from ..garment.obj import Placement, load_garment_obj, require_cloth
    from ..garment.templates import GARMENT_NAMES, make_garment

    obj = Path(request.garment)
    if obj.suffix.lower() == ".obj":
        if not obj.exists():
            raise InputError(obj, "no such file")
        made_for = garment_body(request.made_for) if request.made_for else body
        notes: list[str] = []
        placement = Placement(fit=request.fit, body=made_for.body)
        mesh = load_garment_obj(obj, None, attached_group=request.attached, placement=placement, notes=notes)
        require_cloth(mesh, obj)
        for note in notes:
            print(note)
        return mesh, made_for
    if request.made_for:
        raise InputError("--made-for", "says which body your garment OBJ was modelled on: give --garment OBJ")
    if request.garment in GARMENT_NAMES:
        return make_garment(request.garment, vertices), None
    raise InputError(
        request.garment, f"is neither an OBJ nor a built-in garment ({', '.join(GARMENT_NAMES)})"
    )


def garment_body(path: Path) -> BodyRecord:
    """The body a garment was modelled on: a body.json, or a body's mesh as an OBJ without a rig (the
    parametric body nearest to it, fitted as ``hrr-body fit --parametric`` fits a mesh: the mesh in
    the project's frame, Y up, metres, soles on the ground, standing as anny rests)."""
    from ..body.body_file import read_body, record_of

    path = Path(path)
    if path.suffix.lower() == ".json":
        return read_body(path)
    if path.suffix.lower() != ".obj":
        raise InputError(path, "a garment's body is a body.json or a body mesh as OBJ")
    from ..body.parametric import fit_shape, parametric_body
    from ..garment.obj import read_obj

    vertices, faces, _ = read_obj(path)
    try:
        fitted = fit_shape(vertices, faces)
    except ValueError as exc:
        raise InputError(path, str(exc)) from None
    print(
        f"{path.name}: the nearest parametric body lies {fitted.mean_mm:.1f} mm from the mesh on average "
        f"(95th percentile {fitted.p95_mm:.1f} mm); the garment is carried from it"
    )
    return record_of(parametric_body(fitted.shape))


@dataclass(frozen=True)
class ChosenBuild:
    """What a build of chosen clips simulates on and writes: the garment, the body it was modelled on
    (None: the template's mannequin), carried onto the character's ``body_path``, the dataset, the
    simulator's settings and the request's workers and progress."""

    garment: object  # GarmentMesh
    made_for: BodyRecord | None
    body_path: Path
    dataset: Path
    sim: object  # SimSettings
    request: object  # MakeRequest


def build_chosen(library: MotionLibrary, names: list[str], build: ChosenBuild, *, probe: bool):
    """Simulate ``names`` of ``library`` on the character into ``build.dataset`` (finished sequences
    reused), split as the library assigns them (no splices: the budget did not choose them); the
    probe's build makes no preview."""
    from ..export.preview import write_dataset_preview
    from ..sim.body_plan import choose_bodies
    from ..sim.build import BuildSettings, build_dataset

    wanted = set(names)
    choice = choose_bodies(
        [s for s in library.specs if s.name in wanted],
        build.garment,
        preset_bodies={},
        where="hrr-make",
        body_file=build.body_path,
        made_for=build.made_for,
        progress=False,
    )
    # a budget pays for the clips it chose, not a preset's splices of them
    options = {**library.options, "splices": None}
    options["info"] = {
        **options["info"],
        "garment_vertices": build.garment.num_vertices,
        "bodies": choice.info,
    }
    return build_dataset(
        build.garment,
        choice.specs,
        build.sim,
        out=build.dataset,
        options=BuildSettings(
            **options,
            jobs=build.request.jobs,
            batch=build.request.batch,
            progress=build.request.progress,
            preview=None if probe else write_dataset_preview,
            bodies=choice.bodies,
            assigned={n: library.part[n] for n in names},
        ),
    )


def frames_to_simulate(library: MotionLibrary, names: list[str], dataset: Path) -> int:
    """The frames the simulator runs, lead-ins included, for the sequences of ``names`` (and their
    mirrors) that ``dataset``'s build has neither finished nor rejected yet: what a build of them
    will simulate (a probe stopped and run again measures only those)."""
    from ..data.splits import MIRROR_SUFFIX
    from ..sim.parts import part_paths

    parts = dataset.with_suffix(".parts")
    copies = [""] + ([MIRROR_SUFFIX] if library.copies == 2 else [])
    return sum(
        library.frames[n] + library.lead
        for n in names
        for suffix in copies
        if not any(p.exists() for p in part_paths(parts, n + suffix))
    )
