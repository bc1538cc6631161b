"""hrr-train's code space stage: the curriculum switch, the paper's validation protocol, the bundle
it writes, its schedule, resuming and re-running, and datasets it refuses."""

import json

import numpy as np
import pytest

from hrr_garment.train.codespace_training import PlateauDetector
from tests.conftest import TINY_TRAINING, synthetic_dataset


def test_curriculum_switches_once_when_the_loss_plateaus():
    loss = [1.0 / (1 + e) for e in range(10)] + [0.0909] * 20  # falls, then flat from epoch 10
    detector = PlateauDetector(patience=5, delta=0.01)
    fired = [e for e, v in enumerate(loss) if detector.update(v)]
    assert fired == [15]  # last improvement at epoch 10 (0.1 -> 0.0909), then five flat epochs; only once


def test_the_paper_protocol_validates_on_a_tenth_of_the_training_clips_windows(trained, paper_model):
    """hrr-train --validation windows: the training and validation clips' windows split 9:1, the
    database holds the nine tenths, tau is calibrated on the tenth, and the bundle says so."""
    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.data.dataset import GarmentDataset

    root, data, args = trained
    report = json.loads((paper_model / "codebook" / "report.json").read_text())
    clips = json.loads((root / "model" / "codebook" / "report.json").read_text())
    ds = GarmentDataset(data)
    every = sum(max(ds.frames[n] - 9, 0) for n in ds.splits["train"] + ds.splits["val"])
    assert (
        report["windows"]["val"] == round(0.1 * every)
        and report["windows"]["train"] + report["windows"]["val"] == every
    )
    assert report["key"] != clips["key"]
    bundle = load_bundle(paper_model)
    assert (
        bundle.manifest.validation == "windows" and load_bundle(root / "model").manifest.validation == "clips"
    )
    assert len(bundle.database) == report["windows"]["train"]
    assert set(bundle.database.names) == set(ds.splits["train"] + ds.splits["val"])
    with pytest.raises(SystemExit):
        train_main([*args[:-1], "--validation", "folds"])


def test_hrr_train_writes_a_bundle_that_reproduces_its_validation_numbers(trained):
    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.train.calibrate import evaluate_bundle

    root, data, _ = trained
    report = json.loads((root / "model" / "codebook" / "report.json").read_text())
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == [1, 2, 3, 4] and {
        "val_agreement",
        "val_perplexity",
        "val_dead_classes",
    } <= set(log[0])
    bundle = load_bundle(root / "model")
    again = evaluate_bundle(bundle, data)
    for mode in ("hybrid", "regression", "retrieval", "autoencoder", "retrieval_usage"):
        assert again[mode] == report["validation_mm"][mode], mode
    assert report["validation_mm"]["hybrid"] <= min(
        report["validation_mm"]["regression"], report["validation_mm"]["retrieval"]
    )
    assert len(bundle.database) == report["windows"]["train"]
    from hrr_garment.data.dataset import GarmentDataset

    groups = GarmentDataset(data).template.groups  # kept in the bundle: evaluation measures the hem's swing
    assert set(groups) <= set(bundle.template.groups) and np.array_equal(
        bundle.template.groups["hem"], groups["hem"]
    )


def test_the_code_space_anneals_its_learning_rate_over_the_run_and_keeps_its_best_epoch(trained):
    """Cosine from learning_rate to lr_final x it over the run's epochs (tiny config: 4 epochs of
    1e-3, lr_final 0.01), and the bundle holds the epoch with the best validation regression."""
    import json

    root = trained[0]
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    rates = [r["learning_rate"] for r in log]
    assert len(rates) == 4 and all(a > b for a, b in zip(rates, rates[1:]))
    assert (
        rates[0] < 1e-3 and rates[-1] < 1e-3 * 0.05
    )  # logged at each epoch's last batch, just short of the end
    report = json.loads((root / "model" / "codebook" / "report.json").read_text())["training"]
    best = min(range(4), key=lambda i: log[i]["val_regress"])
    assert report["best_epoch"] == best + 1 and report["final"]["regress"] == pytest.approx(
        log[best]["val_regress"], rel=1e-5
    )


def test_the_old_codebook_names_still_work_with_a_deprecation_message(trained, capsys):
    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    old = (root / "cfg.yaml").read_text().replace("\ncodespace:", "\ncodebook:")
    (root / "cfg_old.yaml").write_text(old)
    args_old = [a if a != str(root / "cfg.yaml") else str(root / "cfg_old.yaml") for a in args]
    capsys.readouterr()
    assert train_main([*args_old, "--stage", "codebook"]) == 0
    out, err = capsys.readouterr()
    assert "code space:" in out and "(reused)" in out  # the same stage, settings and outputs
    assert (
        "--stage codebook is now --stage codespace" in err and "'codebook' is now called 'codespace'" in err
    )


def test_rerun_resumes_the_code_space_and_skips_finished_stages(trained, capsys):
    from hrr_garment.cli.train import main as train_main

    root, data, args = trained
    capsys.readouterr()
    assert train_main(args) == 0
    assert "(reused)" in capsys.readouterr().out
    longer = (root / "cfg.yaml").read_text().replace("epochs: 4", "epochs: 5")
    (root / "cfg5.yaml").write_text(longer)
    args5 = [a if a != str(root / "cfg.yaml") else str(root / "cfg5.yaml") for a in args]
    assert train_main(args5) == 0
    log = [json.loads(line) for line in (root / "model" / "codebook" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in log] == [1, 2, 3, 4, 5]  # continued from epoch 4's checkpoint, one more epoch


def test_a_new_encoding_retrains_the_code_space(trained, tmp_path):
    """Changing only the refinement re-encodes the same autoencoder weights; the code space (and
    the bundle's database) trained on the old latents must not be reused."""
    import shutil

    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.train.calibrate import evaluate_bundle

    root, data, args = trained
    shutil.copytree(root / "model", tmp_path / "model")
    config = (
        (root / "cfg.yaml").read_text().replace("target_mm: null}", "target_mm: null, refine_steps: 3}", 1)
    )
    (tmp_path / "cfg.yaml").write_text(config)
    before = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    assert (
        train_main(
            [
                "--dataset",
                str(data),
                "--config",
                str(tmp_path / "cfg.yaml"),
                "-o",
                str(tmp_path / "model"),
                "--quiet",
            ]
        )
        == 0
    )
    autoencoder = json.loads((tmp_path / "model" / "autoencoder" / "report.json").read_text())
    after = json.loads((tmp_path / "model" / "codebook" / "report.json").read_text())
    assert (
        autoencoder["extra"]["refine_steps"] == 3 and autoencoder["epochs"] == 3
    )  # re-encoded, not retrained
    assert after["key"] != before["key"] and not after.get("reused")
    # the floor is scored with the stage's encoding (3 steps, not the default 10: the same weights
    # refined for 3 steps land elsewhere), here and from the bundle in a fresh load
    assert after["validation_mm"]["autoencoder"] != before["validation_mm"]["autoencoder"]
    again = evaluate_bundle(load_bundle(tmp_path / "model"), data)
    assert again["autoencoder"] == after["validation_mm"]["autoencoder"]


def test_too_few_sequences_to_split_is_refused(tmp_path, capsys):
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.data.dataset import GarmentDataset, write_dataset
    from hrr_garment.garment.templates import make_garment

    full = GarmentDataset(synthetic_dataset(tmp_path / "all.h5", make_garment("skirt", 300)))
    records = [full.sequence("walk_000")]
    data = write_dataset(
        tmp_path / "one.h5", full.template, records, {"train": ["walk_000"], "val": [], "test": []}
    )
    (tmp_path / "cfg.yaml").write_text(TINY_TRAINING)
    out = tmp_path / "model"
    assert (
        train_main(
            ["--dataset", str(data), "--config", str(tmp_path / "cfg.yaml"), "-o", str(out), "--quiet"]
        )
        == 2
    )
    assert "one.h5" in capsys.readouterr().err
    assert not (out / "bundle.json").exists()


def test_a_dataset_no_stage_can_finish_is_refused_before_training(tmp_path, capsys):
    """Found by tools/fuzz.py: without a validation split the autoencoder trained for minutes and
    left its stage behind before the code space refused the dataset."""
    import h5py

    from hrr_garment.cli.train import main as train_main
    from hrr_garment.garment.templates import make_garment

    data = synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 300))
    with h5py.File(data, "r+") as f:
        del f["splits/val"]
    (tmp_path / "cfg.yaml").write_text(TINY_TRAINING)
    out = tmp_path / "model"
    assert (
        train_main(
            ["--dataset", str(data), "--config", str(tmp_path / "cfg.yaml"), "-o", str(out), "--quiet"]
        )
        == 2
    )
    assert "needs at least one training and one validation sequence" in capsys.readouterr().err
    assert not out.exists()
