"""The cross-source protocol (hrr-eval --other-source): another source's test clips, the model's own
training clips left out, beside the reference model, pooled and per clip."""

import json

import numpy as np
import pytest

from hrr_garment.data.dataset import GarmentDataset, write_dataset
from hrr_garment.motion.licences import SOURCES


def _other_source(data, out):
    """The synthetic dataset again as if its motion came from CMU, testing a clip the tiny model
    trained on (walk_000) beside one it never saw (run_000)."""
    ds = GarmentDataset(data)
    records = [ds.sequence(n) for n in ds.names]
    for record in records:  # captured, as a motion file's sequences are (procedural clips take no part)
        record.info["kind"] = "file"
    splits = {"train": ["walk_001", "spin_000"], "val": ["walk_002"], "test": ["walk_000", "run_000"]}
    info = {"motion_sources": dict.fromkeys(ds.names, "cmu"), "sources": {"cmu": SOURCES["cmu"].to_dict()}}
    return write_dataset(out, ds.template, records, splits=splits, info=info)


def test_other_source_clips_beside_the_reference_with_the_trained_ones_left_out(trained, tmp_path):
    from hrr_garment.cli.eval import main

    root, data, _ = trained
    other = _other_source(data, tmp_path / "cmu.h5")
    out = tmp_path / "report"
    args = ["--model", str(root / "model"), "--dataset", str(data), "--split", "test", "--modes", "auto"]
    args += ["--no-sweep", "--library", "0", "--ensemble", "0", "--no-plots", "-o", str(out), "--quiet"]
    assert main([*args, "--other-source", f"{other}={root / 'model'}"]) == 0
    report = json.loads((out / "report.json").read_text())
    entry = report["cross_source"]["cmu"]
    assert entry["left_out_trained"] == ["walk_000"] and entry["sequences"] == ["run_000"]
    assert entry["clip_sources"] == ["cmu"] and entry["model_sources"] == ["procedural"]
    assert entry["model"]["pve_mm"] > 0 and entry["reference"]["folder"] == str(root / "model")
    # the reference is the same model here: the same clip, the same error
    assert entry["reference"]["pve_mm"] == entry["model"]["pve_mm"]
    assert "## Other motion sources" in (out / "report.md").read_text()


def test_a_dataset_of_only_trained_or_procedural_clips_is_refused(trained, tmp_path, capsys):
    from hrr_garment.cli.eval import main

    root, data, _ = trained
    out = tmp_path / "report"
    args = ["--model", str(root / "model"), "--split", "test", "--modes", "auto", "--no-sweep"]
    args += ["--library", "0", "--ensemble", "0", "--no-plots", "-o", str(out), "--quiet"]
    own = GarmentDataset(data)
    records = [own.sequence(n) for n in own.names]
    only_trained = write_dataset(
        tmp_path / "same.h5", own.template, records, splits={"train": ["run_000"], "test": ["walk_000"]}
    )
    assert main([*args, "--other-source", str(only_trained)]) != 0
    assert "has no test clip of captured motion that the model did not train on" in capsys.readouterr().err
    assert not (out / "report.json").exists()


def test_the_own_split_ratio_pools_the_captured_clips_by_frames():
    from hrr_garment.data.dataset import SequenceRecord
    from hrr_garment.eval.cross_source import captured_ratio
    from hrr_garment.eval.mode_results import ModeResult, SequenceResult
    from hrr_garment.motion.synth import synthesize

    def result(name, frames, pve, floor):
        return SequenceResult(
            name,
            frames,
            {},
            np.zeros(frames),
            np.zeros(frames),
            np.zeros(frames, bool),
            ensemble={"pve_members_mm": pve, "floor_mm": floor},
        )

    motion = synthesize("walk", 1.0)
    records = [
        SequenceRecord(n, np.zeros((1, 1, 3)), motion, info={"kind": k})
        for n, k in (("a", "file"), ("b", "file"), ("walk_000", "walk"))
    ]
    auto = ModeResult(
        "auto",
        0.0,
        [result("a", 30, 20.0, 10.0), result("b", 90, 60.0, 20.0), result("walk_000", 50, 1.0, 10.0)],
    )
    # (30 * 20 + 90 * 60) / (30 * 10 + 90 * 20): the procedural clip left out
    assert captured_ratio(auto, records) == pytest.approx(6000 / 2100)
    assert captured_ratio(ModeResult("auto", 0.0, [result("walk_000", 50, 1.0, 10.0)]), records) is None
