"""hrr-make's motion: the library preset's clips with the character's own animations beside them, the
library's split drawn over all of it, each sequence's motion described for the coverage selection,
and the selection a budget takes.

The split is the preset's (whole clips held out for validation and test), drawn over the whole
library before any of it is simulated, so a budget that simulates a fifth of the library still holds
out the library's own held-out clips; the character's own animations always train (they are the
motion the user cares most about, and the report measures held-out library clips). Within each part
the sequences are ordered for coverage (:mod:`hrr_garment.sim.coverage`) or at random, and the
budget takes a prefix of each.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..motion.features import motion_features
from ..sim.coverage import coverage_order, random_order, window_descriptors
from ..sim.plan import SequenceSpec, build_options, load_file_motion, plan_sequences
from ..sim.preset import Preset, mirror_mode
from .make_budget import BudgetPlan, take_prefix

PARTS = ("train", "val", "test")
SELECTIONS = ("coverage", "random")
MIN_HELD_OUT = 2  # sequences each held-out part keeps however small the budget
DESCRIPTORS_NAME = "descriptors.npz"


@dataclass
class MotionLibrary:
    """The clips a run may simulate: ``specs`` (sources; a build adds their mirrors), each one's
    frames at 30 frames a second, the part it is held in, and the build options of its preset."""

    preset: Preset
    specs: list[SequenceSpec]
    frames: dict[str, int]
    part: dict[str, str]
    options: dict  # the preset's BuildSettings keywords (sim.plan.build_options)
    own: list[str]  # the sequences of the character's own animations (always trained on)
    copies: int  # simulated sequences per source: 2 where the preset simulates mirrors, else 1
    # frames each simulated sequence runs before its first kept one (settling, easing into the clip):
    # 30 on real-quick, an eighth of an average clip's cost, more of a short clip's
    lead: int = 0

    def simulated_frames(self, names: list[str]) -> int:
        """The frames ``names`` give the data (their mirrors included)."""
        return self.copies * sum(self.frames[n] for n in names)

    def simulator_frames(self, names: list[str]) -> int:
        """The frames the simulator runs for ``names``: their data frames and each copy's lead-in."""
        return self.simulated_frames(names) + self.copies * self.lead * len(names)

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.specs]


def motion_library(preset: Preset, own: list[Path]) -> MotionLibrary:
    """``preset``'s clips and the ``own`` motion files (the character's animations), split."""
    from ..motion.motion import FPS
    from ..sim.build import BuildSettings
    from ..sim.build_split import split_sources
    from ..sim.config import SimSettings
    from ..sim.lead_in import lead_in_frames

    if preset.materials:  # the budget plans one cloth's simulation rate
        raise InputError(
            preset.name,
            "hrr-make's library is simulated in one cloth: choose a preset without a materials section",
        )
    own = [Path(p).resolve() for p in own]  # the plan records files by their resolved paths
    preset = replace(preset, motions=[*preset.motions, *(str(p) for p in own)])
    specs = plan_sequences(preset)
    options = build_options(preset, specs)
    own_paths = {str(p) for p in own}
    own_names = [s.name for s in specs if str(Path(s.path).resolve()) in own_paths]
    # drawn without the character's clips: the library's held-out clips are the same whatever the
    # character brings (and the same as the preset's own build of the library)
    shared = [s for s in specs if s.name not in own_names]
    split = split_sources([s.name for s in shared], shared, BuildSettings(**options))
    part = {name: p for p, members in split.items() for name in members}
    part.update({name: "train" for name in own_names})
    copies = 2 if mirror_mode(preset.mirror) == "simulate" else 1
    frames = {s.name: s.frames for s in specs}
    sim = SimSettings.from_dict(preset.sim)
    lead = sum(lead_in_frames(sim.settle_s, sim.blend_s, FPS))
    return MotionLibrary(preset, specs, frames, part, options, own_names, copies, lead)


def library_descriptors(library: MotionLibrary, cache: Path, progress: bool = True) -> dict[str, np.ndarray]:
    """Every sequence's window descriptors (:func:`~hrr_garment.sim.coverage.window_descriptors`),
    kept in ``cache`` for the same sequences (a re-run, a changed garment) and made otherwise."""
    from tqdm.auto import tqdm

    keys = [s.key({}) for s in library.specs]
    if cache.exists():
        with np.load(cache) as held:
            if list(held["keys"]) == keys:
                return {n: held[f"d{i}"] for i, n in enumerate(library.names)}
    features, loaded = [], {}
    for spec in tqdm(library.specs, desc="motion features", unit="clip", disable=not progress):
        if spec.kind == "file":  # each file read once, its pieces sliced
            whole = (spec.path, spec.speed)
            if whole not in loaded:  # pieces of a file follow each other: keep one file at a time
                loaded = {whole: load_file_motion(spec.path, spec.speed, spec.source_fps)}
            motion = loaded[whole].slice(spec.start, spec.stop)
        else:
            motion = spec.motion()
        features.append(motion_features(motion))
    described = window_descriptors(features)
    cache.parent.mkdir(parents=True, exist_ok=True)
    tmp = cache.with_name(cache.stem + ".tmp.npz")
    np.savez(tmp, keys=np.array(keys), **{f"d{i}": d for i, d in enumerate(described)})
    tmp.replace(cache)
    return dict(zip(library.names, described, strict=True))


def ordered_parts(
    library: MotionLibrary,
    descriptors: dict[str, np.ndarray],
    selection: str,
    *,
    seed: int = 0,
    probe: int = 0,
) -> dict[str, list[str]]:
    """Each part's sequences in the order a budget takes them. The training part starts with the
    character's own clips, then ``probe`` training clips drawn at random (the simulator's rate is
    measured on them: on the first clips of a coverage order, the library's most unusual motion,
    it measured less than half the library's rate); after them, the coverage order goes on by
    farthest-point sampling from those already taken, the random order at random (seeded)."""
    if selection not in SELECTIONS:
        raise ValueError(f"unknown selection {selection!r}; choose {' or '.join(SELECTIONS)}")
    out = {}
    for k, part in enumerate(PARTS):
        names = [n for n in library.names if library.part[n] == part and n not in library.own]
        shuffled = [names[i] for i in random_order(len(names), seed=seed + k)]
        first = (library.own + shuffled[:probe]) if part == "train" else []
        if selection == "random" or not names:
            out[part] = first + [n for n in shuffled if n not in first]
            continue
        every = first + [n for n in names if n not in first]
        order = coverage_order([descriptors[n] for n in every], first=list(range(len(first))) or None)
        out[part] = [every[i] for i in order]
    return out


def select(
    library: MotionLibrary,
    order: dict[str, list[str]],
    sim_frames: int,
    *,
    test_frames: int,
    validation: float,
) -> dict[str, list[str]]:
    """The sequences ``sim_frames`` simulated frames buy (mirrors included): the held-out test clips
    the report needs (``test_frames`` of source motion), then training and validation clips in the
    ratio ``validation`` (validation frames per training frame), each a prefix of its order; the
    character's own clips train whatever the budget."""
    frames = library.frames
    test = take_prefix(order["test"], frames, test_frames, at_least=MIN_HELD_OUT)
    left = sim_frames / library.copies - sum(frames[n] for n in test)
    train_frames = max(left, 0) / (1 + validation)
    val = take_prefix(order["val"], frames, int(validation * train_frames), at_least=MIN_HELD_OUT)
    own = [n for n in order["train"] if n in library.own]
    rest = [n for n in order["train"] if n not in library.own]
    wanted = int(train_frames) - sum(frames[n] for n in own)
    train = own + (take_prefix(rest, frames, wanted) if wanted > 0 else [])
    return {"train": train, "val": val, "test": test}


def sized_selection(
    library: MotionLibrary,
    order: dict[str, list[str]],
    plan_at: Callable[[float], BudgetPlan],
    *,
    simulator_rate: float,
    test_frames: int,
    validation: float,
) -> tuple[BudgetPlan, dict[str, list[str]]]:
    """The plan (``plan_at``: the plan for a rate in data frames a second) and the sequences it buys
    (:func:`select`), with the rate that selection simulates at: the simulator's ``simulator_rate``
    counts every frame it runs, lead-ins included, so a selection of short clips gives fewer data
    frames a second than one of long clips. The rate and the selection are settled together, a few
    rounds from the library's own ratio (a plan that counted data frames alone ran its simulation
    6 % over its estimate)."""
    rate = simulator_rate * library.simulated_frames(library.names) / library.simulator_frames(library.names)
    for _ in range(4):
        plan = plan_at(rate)
        chosen = select(library, order, plan.sim_frames, test_frames=test_frames, validation=validation)
        names = [n for part in PARTS for n in chosen[part]]
        settled = simulator_rate * library.simulated_frames(names) / max(library.simulator_frames(names), 1)
        if abs(settled - rate) <= 1e-3 * rate:
            break
        rate = settled
    return plan, chosen
