"""Which cloth each sequence of a build is simulated in.

A preset's ``materials`` section (configs/presets/*.yaml) chooses them; without one every sequence
is simulated in the build's own cloth (``sim: {material: ...}``, else the default), as before::

    materials: {fabrics: [denim, jersey, default],  # named fabrics (garment/fabrics.py); "all": every one
                count: 8,                          # and cloths drawn log-uniform over their span
                per_clip: 1,                       # how many of them each clip is simulated in
                hold_out: true, seed: 0}           # validation and test hold out whole cloths
    materials: {..., hold_out: [polyester, denim, cloth03]}  # these cloths test, never train

A drawn cloth takes each value (density, stretch, shear, bend) log-uniform between the smallest and
the largest of the named fabrics' (a seeded Latin hypercube, so that the draws spread over the
range), the project's damping; they are named ``cloth00``, ``cloth01``, ... . Each clip goes to
``per_clip`` of the cloths in turn, the cloths in a shuffled order, so that they share the clips
evenly; a clip simulated in more than one is named ``CLIP__CLOTH`` (:func:`~.plan.in_material`).
The dataset records each sequence's cloth in its info (``GarmentDataset.material_of``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..garment.fabrics import FABRICS, fabric
from ..garment.material import VALUE_NAMES, Material
from .plan import SequenceSpec, in_material

DRAWN = ("density", "stretch", "shear", "bend")  # the values a drawn cloth varies; damping stays
KEYS = {"fabrics", "count", "per_clip", "hold_out", "seed"}


@dataclass(frozen=True)
class MaterialPlan:
    """A preset's ``materials`` section, checked (see the module docstring)."""

    fabrics: tuple[str, ...] = ()  # named fabrics, each a cloth of its own
    count: int = 0  # cloths drawn over the fabrics' span
    per_clip: int = 1  # how many of the cloths each clip is simulated in
    # validation and test also hold out whole cloths (drawn at random), or these cloths test
    hold_out: bool | tuple[str, ...] = True
    seed: int = 0

    @classmethod
    def from_preset(cls, section: dict, where: str) -> "MaterialPlan | None":
        if not section:
            return None
        if not isinstance(section, dict):
            raise InputError(
                where, f"materials: a mapping ({{fabrics: [...], count: N, ...}}), not {section!r}"
            )
        unknown = sorted(set(section) - KEYS)
        if unknown:
            raise InputError(
                where, f"materials: unknown keys {unknown}; a materials section has {sorted(KEYS)}"
            )
        named = section.get("fabrics", [])
        named = list(FABRICS) if named == "all" else named
        if not isinstance(named, list) or not all(isinstance(n, str) for n in named):
            raise InputError(where, "materials: fabrics is a list of fabric names, or all")
        fabrics = tuple(fabric(n, f"{where}: materials").name for n in named)
        hold_out = section.get("hold_out", True)
        if isinstance(hold_out, list) and all(isinstance(n, str) for n in hold_out):
            hold_out = tuple(hold_out)
        elif not isinstance(hold_out, bool):  # YAML's "false" in quotes is a string, true to bool()
            raise InputError(
                where, f"materials: hold_out must be true, false or a list of cloths, got {hold_out!r}"
            )
        numbers = {k: section.get(k, default) for k, default in (("count", 0), ("per_clip", 1), ("seed", 0))}
        bad = {k: v for k, v in numbers.items() if isinstance(v, bool) or not isinstance(v, int)}
        if bad:
            raise InputError(where, f"materials: {', '.join(bad)} must be whole numbers, got {bad}")
        plan = cls(fabrics, numbers["count"], numbers["per_clip"], hold_out, numbers["seed"])
        total = len(set(plan.fabrics)) + plan.count
        if len(set(plan.fabrics)) != len(plan.fabrics) or not (0 <= plan.count <= 256):
            raise InputError(where, "materials: each fabric once, count 0-256")
        if total < 1 or not 1 <= plan.per_clip <= total:
            raise InputError(where, f"materials: {total} cloths; per_clip must be 1-{max(total, 1)}")
        if isinstance(plan.hold_out, tuple):
            known = set(plan.fabrics) | {f"cloth{k:02d}" for k in range(plan.count)}
            unknown = sorted(set(plan.hold_out) - known)
            if unknown:
                raise InputError(
                    where, f"materials: hold_out names {unknown}, not among the plan's cloths {sorted(known)}"
                )
            if len(set(plan.hold_out)) >= total:
                raise InputError(where, "materials: hold_out names every cloth; leave at least one to train")
        return plan


def drawn_materials(plan: MaterialPlan) -> list[Material]:
    """``plan.count`` cloths, each value log-uniform over the named fabrics' span (all of them
    where the plan names fewer than two), a seeded Latin hypercube: value k's draws fall one in
    each of ``count`` equal slices of its log range."""
    span = [FABRICS[n] for n in plan.fabrics] if len(plan.fabrics) > 1 else list(FABRICS.values())
    rng = np.random.default_rng(plan.seed)
    n = plan.count
    values = {}
    for key in DRAWN:
        low, high = (math.log(f(getattr(m, key) for m in span)) for f in (min, max))
        where = (rng.permutation(n) + rng.random(n)) / max(n, 1)
        values[key] = np.exp(low + where * (high - low))
    return [Material(name=f"cloth{k:02d}", **{key: float(values[key][k]) for key in DRAWN}) for k in range(n)]


@dataclass(frozen=True)
class MaterialChoice:
    """The cloths of a build as the preset chose them."""

    specs: list[SequenceSpec]  # each naming its cloth (None: the build's own)
    materials: dict[str, Material] = field(default_factory=dict)
    # validation and test hold out whole cloths too (True), or these cloths test (a tuple)
    hold_out: bool | tuple[str, ...] = False
    info: dict = field(default_factory=dict)  # what the dataset records of the choice


def choose_materials(specs: list[SequenceSpec], section: dict, where: str) -> MaterialChoice:
    """Each sequence's cloth as the preset's ``materials`` section asks (module docstring); none:
    the specs as they are."""
    plan = MaterialPlan.from_preset(section, where)
    if plan is None:
        return MaterialChoice(specs)
    cloths = [FABRICS[n] for n in plan.fabrics] + drawn_materials(plan)
    materials = {m.name: m for m in cloths}
    order = [cloths[i] for i in np.random.default_rng(plan.seed + 1).permutation(len(cloths))]
    out, turn = [], 0
    for spec in specs:
        for j in range(plan.per_clip):
            cloth = order[(turn + j) % len(order)]
            name = in_material(spec.name, cloth.name) if plan.per_clip > 1 else spec.name
            out.append(replace(spec, name=name, material=cloth))
        turn += plan.per_clip
    info = {
        "fabrics": list(plan.fabrics),
        "count": plan.count,
        "per_clip": plan.per_clip,
        "cloths": {m.name: {k: getattr(m, k) for k in VALUE_NAMES} for m in cloths},
    }
    held = plan.hold_out if isinstance(plan.hold_out, tuple) else plan.hold_out and len(cloths) > 2
    return MaterialChoice(
        out, materials, held, {**info, "held_out": list(held) if isinstance(held, tuple) else held}
    )
