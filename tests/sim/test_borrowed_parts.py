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


def test_a_part_on_a_body_loads_with_its_body_name_whether_written_before_or_after_the_rename(tmp_path):
    """A part's info named its body ``body`` until the body's name became ``body_name``: both load
    into ``SequenceRecord.body_name`` (parts are reused across builds under the same key)."""
    import json

    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.motion.synth import synthesize
    from hrr_garment.sim.parts import PartResult, load_part, write_part
    from tests.garment.test_templates_on_bodies import _larger_body

    motion = motion_on_body(synthesize("walk", 0.5, seed=0), _larger_body(1.1, 1.2))
    vertices = np.zeros((motion.num_frames, 4, 3), np.float32)
    write_part(PartResult("w", "k", motion.num_frames, vertices, motion, {"body_name": "tall"}), tmp_path)
    part = part_paths(tmp_path, "w")[0]
    record = load_part(part, "w")
    assert record.body_name == "tall" and record.info["body_name"] == "tall"
    assert np.allclose(
        record.motion.joint_positions, motion.joint_positions, atol=1e-5
    )  # the body's skeleton
    with np.load(part) as z:
        old = {**z, "info": np.array(json.dumps({"body": "tall"}))}  # as a part was written before
    np.savez(part, **old)
    record = load_part(part, "w")
    assert record.body_name == "tall" and record.info == {"body_name": "tall"}
