"""Which body each sequence of a build is simulated on, and the garment on each body.

A preset's ``bodies`` section (configs/presets/*.yaml) chooses them; without one every sequence
stands on the mannequin, as before::

    bodies: {from: performer}                        # each motion file on its performer's nearest body
    bodies: {from: sample, count: 16, per_clip: 1,   # bodies spread over statures, both genders,
             statures_m: [1.50, 1.95], hold_out: true}  # slim to heavy; whole bodies held out
    bodies: {from: sample, ..., mannequin: true}     # every clip on the mannequin as well

``hrr-simulate --body body.json`` puts every sequence on one body instead. The garment on each
body is the template carried onto it (:func:`~hrr_garment.garment.transfer.transfer_garment`:
one topology for every body, each vertex as far off the new body as it was off the old), so one
dataset holds one garment on many bodies. Procedural clips have no performer: under ``from:
performer`` they stay on the mannequin.

``mannequin: true`` keeps every clip on the mannequin too, under its own name (so a build beside
a dataset of the mannequin alone reuses those parts): the default body of every command is then
one the model across bodies has trained on. The mannequin is never held out as a body (its
sequences split by their clip groups alone), so the sampled bodies held out stay the same.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..body.body_file import BodyRecord
from ..body.capsules import BodyModel
from ..body.mannequin import MANNEQUIN, mannequin_record
from ..body.symmetry import symmetrized
from ..errors import InputError
from ..garment.clearance import CLEARANCE_M
from ..garment.dressing import DressedBody, dress
from ..garment.mesh import GarmentMesh
from ..garment.transfer import TransferReport
from .plan import SequenceSpec, on_body, safe_name

SOURCES = ("performer", "sample")
DEFAULT_STATURES_M = (1.50, 1.95)
STATURE_TOLERANCE_M = 0.002  # the sampled bodies' statures are solved to this


@dataclass(frozen=True)
class BodyPlan:
    """A preset's ``bodies`` section, checked (see the module docstring)."""

    source: str  # "performer" or "sample"
    count: int = 16  # sampled bodies
    per_clip: int = 1  # how many of the sampled bodies each clip is simulated on
    statures_m: tuple[float, float] = DEFAULT_STATURES_M
    hold_out: bool = True  # validation and test also hold out whole sampled bodies
    seed: int = 0
    mannequin: bool = False  # every clip on the mannequin as well (sample only)

    @classmethod
    def from_preset(cls, section: dict, where: str) -> "BodyPlan | None":
        if not section:
            return None
        unknown = sorted(
            set(section) - {"from", "count", "per_clip", "statures_m", "hold_out", "seed", "mannequin"}
        )
        if unknown or section.get("from") not in SOURCES:
            raise InputError(
                where, f"bodies: 'from' must be one of {', '.join(SOURCES)}; unknown keys {unknown}"
            )
        flags = {
            k: section[k]
            for k in ("hold_out", "mannequin")
            if k in section and not isinstance(section[k], bool)
        }
        if flags:  # YAML's "false" in quotes is a string, which bool() would take as true
            raise InputError(where, f"bodies: {', '.join(flags)} must be true or false, got {flags}")
        plan = cls(
            section["from"],
            int(section.get("count", 16)),
            int(section.get("per_clip", 1)),
            tuple(float(v) for v in section.get("statures_m", DEFAULT_STATURES_M)),
            bool(section.get("hold_out", section["from"] == "sample")),
            int(section.get("seed", 0)),
            bool(section.get("mannequin", False)),
        )
        low, high = plan.statures_m
        if not (2 <= plan.count <= 256 and 1 <= plan.per_clip <= plan.count and 1.0 <= low < high <= 2.2):
            raise InputError(
                where, "bodies: count 2-256, per_clip 1-count, statures_m two heights in 1.0-2.2 m, low first"
            )
        if plan.mannequin and plan.source != "sample":
            raise InputError(
                where,
                "bodies: mannequin: true goes with from: sample (under from: performer only "
                "procedural clips stand on the mannequin)",
            )
        return plan


def one_body(
    specs: list[SequenceSpec], name: str, body: DressedBody
) -> tuple[list[SequenceSpec], dict[str, DressedBody]]:
    """Every sequence on ``body`` (``hrr-simulate --body``)."""
    name = safe_name(name, empty="body")
    return [replace(s, body_name=name) for s in specs], {name: replace(body, name=name)}


def placement_note(name: str, report: TransferReport) -> str:
    """One line on how the garment landed on a body (and, where the body has a visible mesh, how it
    was kept clear of it)."""
    note = (
        f"the garment on body {name}: {100 * report.inside:.1f} % of its vertices were inside it and "
        f"{100 * report.pushed:.1f} % pushed out; each vertex {report.moved_mean_mm:.1f} mm from where it "
        f"was modelled on average, its distance from the body changed {report.gap_change_mean_mm:.1f} mm"
    )
    kept = report.visible
    if kept is not None:
        note += (
            f"; then kept {1000 * CLEARANCE_M:.0f} mm off the body's visible mesh: {100 * kept.inside:.1f} % "
            f"of its vertices were inside the mesh and {100 * kept.closer:.1f} % nearer, "
            f"{100 * kept.moved:.0f} % moved (at most {kept.moved_max_mm:.0f} mm)"
        )
    return note


def plan_bodies(
    plan: BodyPlan,
    specs: list[SequenceSpec],
    garment: GarmentMesh,
    *,
    made_for: BodyModel,
    progress: bool = True,
) -> tuple[list[SequenceSpec], dict[str, DressedBody]]:
    """The sequences with their bodies named, and the bodies (each with ``garment`` on it)."""
    if plan.source == "performer":
        return _performer_bodies(specs, garment, made_for, progress)
    return _sampled_bodies(plan, specs, garment, made_for)


def _performer_bodies(specs, garment, made_for, progress):
    from tqdm.auto import tqdm

    from ..body.performer import performer_body

    bodies: dict[str, DressedBody] = {}
    by_path: dict[str, str] = {}
    by_body: dict[BodyModel, str] = {}  # performer_body gives rigs of the same limbs one body: dressed once
    out = []
    for spec in tqdm(specs, desc="performers' bodies", unit="clip", disable=not progress):
        if spec.kind != "file":
            out.append(spec)  # a procedural clip has no performer: the mannequin
            continue
        if spec.path not in by_path:
            found = performer_body(spec.path, unit_scale=None)
            if found.body not in by_body:
                record = BodyRecord(
                    found.body.skeleton,
                    found.body,
                    pelvis_height=found.body.pelvis_height,
                    stature=found.stature,
                    shape=found.shape,
                )
                dressed, _ = dress(MANNEQUIN, record, garment, made_for=made_for)
                name = f"performer-{dressed.key()[:8]}"
                bodies.setdefault(name, replace(dressed, name=name))
                by_body[found.body] = name
            by_path[spec.path] = by_body[found.body]
        out.append(replace(spec, body_name=by_path[spec.path]))
    return out, bodies


def sampled_shapes(plan: BodyPlan):
    """``plan.count`` parametric shapes: statures evenly over ``plan.statures_m``, genders
    alternating, weight and muscle spread over slim to heavy (a seeded Latin hypercube)."""
    from ..body.parametric import BodyShape

    rng = np.random.default_rng(plan.seed)
    n = plan.count
    weight = (rng.permutation(n) + rng.random(n)) / n * 0.9 + 0.05
    muscle = (rng.permutation(n) + rng.random(n)) / n * 0.9 + 0.05
    statures = np.linspace(*plan.statures_m, n)[rng.permutation(n)]
    shapes = []
    for k in range(n):
        base = BodyShape(gender=float(k % 2), weight=float(weight[k]), muscle=float(muscle[k]))
        shapes.append(_shape_of_stature(base, float(statures[k])))
    return shapes


def _shape_of_stature(base, stature: float):
    """``base`` with the height value that gives ``stature`` (bisection; clamped to anny's range)."""
    from ..body.parametric import anny_rest_mesh

    def height_of(value: float) -> float:
        vertices = anny_rest_mesh(replace(base, height=value)).vertices
        return float(vertices[:, 1].max() - vertices[:, 1].min())

    low, high = 0.0, 1.0
    for _ in range(30):
        mid = 0.5 * (low + high)
        if height_of(mid) < stature:
            low = mid
        else:
            high = mid
        if high - low < 1e-4:
            break
    return replace(base, height=0.5 * (low + high))


def _sampled_bodies(plan, specs, garment, made_for):
    from ..body.body_file import record_of
    from ..body.parametric import parametric_body

    shapes = sampled_shapes(plan)
    bodies = {}
    for k, shape in enumerate(shapes):
        name = f"body{k:02d}"
        bodies[name], _ = dress(name, record_of(parametric_body(shape)), garment, made_for=made_for)
    names = sorted(bodies)
    rng = np.random.default_rng(plan.seed + 1)
    out = []
    # each clip on per_clip bodies; the bodies go round in a shuffled order so they share the clips evenly
    order = [names[i] for i in rng.permutation(len(names))]
    turn = 0
    for spec in specs:
        chosen = [order[(turn + j) % len(order)] for j in range(plan.per_clip)]
        turn += plan.per_clip
        if plan.mannequin:  # under its own name: a dataset of the mannequin alone holds its part
            out.append(spec)
        for name in chosen:
            several = plan.per_clip > 1 or plan.mannequin
            out.append(replace(spec, name=on_body(spec.name, name) if several else spec.name, body_name=name))
    return out, bodies


@dataclass(frozen=True)
class BodyChoice:
    """The bodies of a build as the command line and the preset chose them."""

    specs: list[SequenceSpec]  # each naming its body ("" for the mannequin)
    bodies: dict[str, DressedBody]
    hold_out: bool  # validation and test hold out whole bodies too
    info: dict  # what the dataset records of the choice
    notes: list[str] = field(default_factory=list)  # how the garment landed on a chosen body


def choose_bodies(
    specs: list[SequenceSpec],
    garment: GarmentMesh,
    *,
    preset_bodies: dict,
    where: str,
    body_file: str | Path | None = None,
    made_for: BodyRecord | None = None,
    progress: bool = True,
) -> BodyChoice:
    """The bodies of a build: ``body_file`` (every sequence on it), else the preset's ``bodies``
    section, else the mannequin; ``garment`` was modelled on ``made_for`` (default the mannequin)
    and is carried onto each. A garment made for another body and no body chosen stands on its own."""
    from ..body.body_file import read_body

    # the garment stays where it was modelled on its own body: that body is made symmetric as every
    # simulated body is (dress), so the transfer onto it moves nothing but what the push must
    source = symmetrized(made_for.body) if made_for is not None else mannequin_record().body
    if body_file is not None:
        dressed, report = dress(MANNEQUIN, read_body(body_file), garment, made_for=source)
        specs, bodies = one_body(specs, Path(body_file).stem, dressed)
        return BodyChoice(
            specs,
            bodies,
            False,
            {"from": "file", "file": Path(body_file).name, "placement": asdict(report)},
            [placement_note(next(iter(bodies)), report)],
        )
    plan = BodyPlan.from_preset(preset_bodies, where)
    if plan is not None:
        specs, bodies = plan_bodies(plan, specs, garment, made_for=source, progress=progress)
        return BodyChoice(
            specs, bodies, plan.hold_out and len(bodies) > 2, {"from": plan.source, "count": len(bodies)}
        )
    if made_for is not None:
        dressed, report = dress(MANNEQUIN, made_for, garment, made_for=source)
        specs, bodies = one_body(specs, "made_for", dressed)
        return BodyChoice(
            specs,
            bodies,
            False,
            {"from": "made_for", "placement": asdict(report)},
            [placement_note("made_for", report)],
        )
    return BodyChoice(specs, {}, False, {})
