"""How a dataset's sequences are split into train / validation / test: seeded by sequence, by whole
groups (a style, a content, one clip with its augmentations), or by two such splits together, and
the names of mirrored sequences (which always go where their source goes)."""

from __future__ import annotations

from collections import Counter

import numpy as np

MIRROR_SUFFIX = "_mirror"  # a mirrored sequence's name: its source's and this (sim.build adds them)


def mirror_source(name: str) -> str:
    """The sequence a mirrored sequence's ``name`` mirrors (``name`` itself if it is no mirror)."""
    return name[: -len(MIRROR_SUFFIX)] if name.endswith(MIRROR_SUFFIX) else name


MIN_TEST = 5  # sequences: a test split of one clip measures that clip, not the model


def test_size(total: int, fraction: float, minimum: int = MIN_TEST) -> int:
    """Sequences the test split should hold: ``fraction`` of ``total`` but at least ``minimum``, and
    never more than a third of them (a tiny dataset keeps most for training), at least one from three."""
    if total < 3 or fraction <= 0:
        return 0
    return max(1, int(round(fraction * total)), min(minimum, total // 3))


def split_names(
    names: list[str], val: float, test: float, seed: int, kinds: dict[str, str] | None = None
) -> dict[str, list[str]]:
    """Seeded split by sequence; with three or more sequences val and test get at least one each,
    and test at least :data:`MIN_TEST` where the data allows (:func:`test_size`).

    ``kinds`` (sequence name -> motion kind, procedural clips) makes the held-out splits in
    distribution: a clip is held out only while its kind keeps a clip in training, so every test
    and validation clip is of a kind the model trained on (a kind with one clip trains). Where
    that leaves too few to hold out, the rest are drawn as without kinds."""
    order = sorted(names)
    rng = np.random.default_rng(seed)
    rng.shuffle(order)
    n = len(order)
    n_val = max(1, int(round(val * n))) if n >= 3 and val > 0 else 0
    n_test = test_size(n, test)
    if kinds:
        training = Counter(kinds.get(name, name) for name in order)
        held = []
        for name in order:
            if len(held) < n_val + n_test and training[kinds.get(name, name)] > 1:
                held.append(name)
                training[kinds.get(name, name)] -= 1
        order = held + [name for name in order if name not in held]
    return {
        "val": sorted(order[:n_val]),
        "test": sorted(order[n_val : n_val + n_test]),
        "train": sorted(order[n_val + n_test :]),
    }


def split_groups(groups: dict[str, str], val: float, test: float, seed: int) -> dict[str, list[str]]:
    """Seeded split that keeps each group (a content, a style, one clip with its augmentations) whole.

    ``groups`` maps sequence name -> group. Groups are shuffled and given to test, then validation,
    until each holds its fraction of the sequences (at least one group each when there are three
    or more groups); the rest train.
    """
    members: dict[str, list[str]] = {}
    for name, group in sorted(groups.items()):
        members.setdefault(group, []).append(name)
    order = sorted(members)
    np.random.default_rng(seed).shuffle(order)
    total = len(groups)
    out: dict[str, list[str]] = {"val": [], "test": [], "train": []}
    wanted = {"test": max(test * total, test_size(total, test)), "val": val * total}
    for split, fraction in (("test", test), ("val", val)):
        while (
            order and fraction > 0 and len(order) >= 2 and (not out[split] or len(out[split]) < wanted[split])
        ):
            out[split] += members[order.pop(0)]
    for group in order:
        out["train"] += members[group]
    return {k: sorted(v) for k, v in out.items()}


def combine_splits(first: dict[str, list[str]], second: dict[str, list[str]]) -> dict[str, list[str]]:
    """Two splits of the same sequences held out together (for example whole styles and whole
    bodies): a sequence tests where either split tests it, else validates where either validates
    it, else trains. Training then sees no held-out style and no held-out body."""
    test = set(first.get("test", [])) | set(second.get("test", []))
    val = (set(first.get("val", [])) | set(second.get("val", []))) - test
    names = {n for split in (first, second) for names in split.values() for n in names}
    return {"val": sorted(val), "test": sorted(test), "train": sorted(names - test - val)}
