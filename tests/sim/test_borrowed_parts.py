"""A dataset reuses the finished parts of another dataset in the same folder when their keys match
(a preset that only splits the same clips otherwise simulates nothing again)."""

import numpy as np

from hrr_garment.sim.parts import part_paths, parts_to_simulate, read_part_key
from hrr_garment.sim.plan import SequenceSpec


def _part(folder, name, key):
    folder.mkdir(parents=True, exist_ok=True)
    path = part_paths(folder, name)[0]
    np.savez(path, key=np.array(key), frames=np.arange(3))
    return path


def test_parts_of_a_sibling_dataset_are_reused_under_the_same_key_only(tmp_path):
    _part(tmp_path / "first.parts", "same", "k1")
    _part(tmp_path / "first.parts", "changed", "old-key")
    specs = [
        SequenceSpec("same", "walk", seed=0, seconds=1.0),
        SequenceSpec("changed", "walk", seed=1, seconds=1.0),
        SequenceSpec("new", "walk", seed=2, seconds=1.0),
    ]
    parts = tmp_path / "second.parts"
    parts.mkdir()
    pending, rejects, reused = parts_to_simulate(
        specs, parts, {"same": "k1", "changed": "k2", "new": "k3"}, retry_rejected=False
    )
    assert reused == 1 and [s.name for s in pending] == ["changed", "new"] and not rejects
    borrowed = part_paths(parts, "same")[0]
    assert read_part_key(borrowed) == "k1" and np.load(borrowed)["frames"].tolist() == [0, 1, 2]
    assert not part_paths(parts, "changed")[0].exists()  # another key: simulated again, not borrowed
    assert not list(parts.glob(".*borrowed"))
