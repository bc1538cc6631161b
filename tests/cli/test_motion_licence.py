"""A model trained with non-commercial motion says so: hrr-train's summary, bundle.json, hrr-body
info --model (the evaluation report: tests/eval/test_eval.py; hrr-export-model:
tests/pipeline/test_bodies_model.py)."""

import json
import shutil

import h5py

from hrr_garment.artifacts.typed_manifest import read_manifest
from hrr_garment.body.body_file import write_body
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.motion.licences import SOURCES


def _marked(data, out, sequence: str):
    """A copy of ``data`` whose record says ``sequence`` came from the Bandai-Namco library."""
    shutil.copy(data, out)
    with h5py.File(out, "r+") as f:
        info = json.loads(f.attrs["info"])
        info["motion_sources"][sequence] = "bandai"
        info["sources"]["bandai"] = SOURCES["bandai"].to_dict()
        f.attrs["info"] = json.dumps(info)
    return out


def test_one_non_commercial_training_clip_is_said_everywhere_the_model_goes(trained, tmp_path, capsys):
    from hrr_garment.cli.body import main as body_main
    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    config = args[args.index("--config") + 1]
    clean = read_manifest(root / "model").licences  # the synthetic dataset's motion is procedural
    assert clean.commercial is True and "may ship commercially" in clean.statement
    folder = tmp_path / "model"
    shutil.copytree(root / "model", folder)
    marked = _marked(data, tmp_path / "skirt.h5", "walk_001")  # a training clip
    stage = ["--dataset", str(marked), "--config", config, "--stage", "codespace", "-o", str(folder)]
    assert train_main([*stage, "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "motion licence: NOT for commercial use" in out and "bandai: CC BY-NC 4.0" in out
    licences = read_manifest(folder).licences  # bundle.json: train and validation clips, the database's
    assert licences.commercial is False and licences.sequences == {"procedural": 3, "bandai": 1}
    assert json.loads((folder / "bundle.json").read_text())["motion"]["commercial"] is False

    body = write_body(tmp_path / "mannequin.json", mannequin_record())
    body_main(["info", str(body), "--model", str(folder)])
    assert "motion licence: NOT for commercial use" in capsys.readouterr().out
    body_main(["info", str(body), "--model", str(folder), "--json"])
    assert json.loads(capsys.readouterr().out)["model"]["motion_licence"]["commercial"] is False

    # a held-out clip from a non-commercial source does not bar the model: it never learned from it
    test_only = _marked(data, tmp_path / "test_only.h5", "run_000")
    assert train_main([*stage[:1], str(test_only), *stage[2:], "--quiet"]) == 0
    assert read_manifest(folder).licences.commercial is True
