"""How a build splits its finished sequences into train, validation and test: by name (clips, kinds
held out only where they also train) or by whole groups, with more held-out fields, whole bodies
and whole cloths beside, a simulated mirror going where its source goes (:class:`~.build.BuildSettings`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..data.splits import combine_splits, mirror_source, split_groups, split_names
from .plan import SequenceSpec, clip_name
from .preset import mirror_mode

if TYPE_CHECKING:  # build imports this module
    from .build import BuildSettings


def split_finished(done: list[str], specs: list[SequenceSpec], o: BuildSettings) -> dict[str, list[str]]:
    """The finished sequences split as ``o`` asks: by name, or by whole groups, with the more fields
    of ``also_hold_out`` and the bodies held out beside (:class:`BuildSettings`). A simulated mirror
    goes where its source goes (the split is drawn over the sources, so it is the split the
    sources alone would get)."""
    finished = set(done)
    simulated_mirrors = mirror_mode(o.mirror) == "simulate"
    by_source: dict[str, list[str]] = {}
    for n in done:
        by_source.setdefault(mirror_source(n) if simulated_mirrors else n, []).append(n)
    split = split_sources(sorted(by_source), specs, o)
    return {
        k: sorted(n for source in v for n in by_source.get(source, []) if n in finished)
        for k, v in split.items()
    }


def split_sources(done: list[str], specs: list[SequenceSpec], o: BuildSettings) -> dict[str, list[str]]:
    """:func:`split_finished` over the sources (``done``: the finished sequences, mirrors left out);
    where ``o.assigned`` gives the split, that split (drawn over a whole library of which only some
    sequences are simulated: hrr-make's budget)."""
    if o.assigned is not None:
        unassigned = sorted(set(done) - set(o.assigned))
        if unassigned:
            raise ValueError(f"the build's assigned split names no part for {unassigned[:3]}")
        return {part: sorted(n for n in done if o.assigned[n] == part) for part in ("train", "val", "test")}
    val, test = (o.splits or {}).get("val", 0.1), (o.splits or {}).get("test", 0.1)
    if o.groups:
        split = split_groups({n: o.groups.get(n, n) for n in done}, val, test, seed=o.seed)
    else:  # drawn over clips: a clip's copies on several bodies go where the clip goes
        clip_of = {s.name: clip_name(s) for s in specs}
        kinds = {clip_of.get(n, n): kind for n, kind in o.kinds.items()} if o.kinds else None
        by_clip = split_names(sorted({clip_of.get(n, n) for n in done}), val, test, seed=o.seed, kinds=kinds)
        part_of = {clip: part for part, clips in by_clip.items() for clip in clips}
        split = {part: sorted(n for n in done if part_of[clip_of.get(n, n)] == part) for part in by_clip}
    for held in (o.also_hold_out or {}).values():  # only the sequences the field groups take part
        grouped = {n: held["groups"][n] for n in done if n in held["groups"]}
        more = (
            split_groups(grouped, held["val"], held["test"], seed=o.seed)
            if grouped
            else {"val": [], "test": []}
        )
        split = combine_splits(
            split, {**more, "train": sorted(set(done) - set(more["val"]) - set(more["test"]))}
        )
    if o.hold_out_bodies:
        # the mannequin is never held out as a body: it is the default body, and a preset that keeps
        # every clip on it too (bodies: {mannequin: true}) holds out the same sampled bodies as without
        by_body = {s.name: s.body_name for s in specs if s.name in done and s.body_name}
        split = combine_splits(split, split_groups(by_body, val, test, seed=o.seed))
    if o.hold_out_materials:  # whole cloths (sim/material_plan.py): drawn, or the named ones test
        by_cloth = {s.name: s.material.name for s in specs if s.name in done and s.material is not None}
        named = o.hold_out_materials if isinstance(o.hold_out_materials, tuple) else None
        cloths = (
            split_groups(by_cloth, val, test, seed=o.seed + 1)
            if named is None
            else {"val": [], "test": sorted(n for n, c in by_cloth.items() if c in named)}
        )
        split = combine_splits(split, cloths)
    return split
