"""hrr-eval end to end on the tiny trained model (synthetic skirt dataset)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hrr_garment.eval.report import REPORT_VERSION


def test_hrr_eval_causal_scores_what_a_stream_shows(trained, tmp_path):
    """``--causal`` runs every mode as a stream does: the report's numbers are the causal animation's."""
    from hrr_garment.cli.eval import main
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.metrics import pve_mm
    from hrr_garment.inference.animator import Animator

    root, data, _ = trained
    out = tmp_path / "causal"
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--split",
                "test",
                "--modes",
                "regression,residual",
                "--no-sweep",
                "--library",
                "0",
                "--no-plots",
                "--causal",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert report["settings"]["causal"] and "causal (as streamed" in (out / "report.md").read_text()
    # the model's report says whether it may ship (its motion procedural: yes)
    assert report["model"]["motion_licence"]["commercial"] is True
    assert "Motion licence: may ship commercially" in (out / "report.md").read_text()
    record = GarmentDataset(data).sequence("run_000")
    animator = Animator.load(root / "model")
    for mode in ("regression", "residual"):
        causal, offline = (
            animator.animate(record.motion, mode=mode, causal=c).vertices for c in (True, False)
        )
        assert report["modes"][mode]["metrics"]["pve_mm"] == pytest.approx(
            pve_mm(causal, record.garment), rel=1e-6
        )
        assert not np.allclose(causal, offline, atol=1e-4)  # and they are not the offline numbers


def test_hrr_eval_report_end_to_end(trained, tmp_path, capsys):
    from hrr_garment.cli.eval import main

    root, data, _ = trained
    out = tmp_path / "report"
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--split",
                "test",
                "--tau-sweep",
                "0,0.5,1,100",
                "--detail-strength",
                "1.2",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert report["format_version"] == REPORT_VERSION == 16 and report["dataset"]["sequences"] == ["run_000"]
    assert (
        report["dataset"]["holdouts"] == {"run_000": "clip"} and report["holdouts"] is None
    )  # one hold-out: no table
    base = json.loads((root / "model" / "bundle.json").read_text())["auto"]["detail_base"]
    assert (report["settings"]["detail_strength"], report["settings"]["detail_base"]) == (
        1.2,
        base,
    )  # as asked; the base as calibrated
    assert f"detail mode: folds x1.2 on the {base}" in (out / "report.md").read_text()
    assert report["ensemble"] == {"members": 0}  # a synthetic dataset: no simulator settings to perturb
    modes = report["modes"]
    # the default output first (auto), then every mode the model has (residual: calibrated in training)
    assert list(modes) == ["auto", "hybrid", "regression", "retrieval", "residual", "detail", "naive-nn"]
    assert report["default"] is None  # no truth ensembles, so no bars to hold it to
    for name, entry in modes.items():
        m = entry["metrics"]
        assert all(v is not None and math.isfinite(v) for v in m.values()), (name, m)
        assert m["pve_mm"] > 0 and m["rmse_mm"] >= m["pve_mm"] and 0 <= m["penetration_pct"] <= 100
        # the push-out ran (the default): the share of frames its strain limit repaired, a percentage
        assert 0 <= m["push_limited_pct"] <= 100
        assert set(entry["sequences"]) == {"run_000"}
        # the mannequin has no mesh: its capsules are the body the viewer sees, and the figure theirs
        assert entry["visible_bodies"] == {"capsules": 1} == report["visible_bodies"]
        assert entry["sequences"]["run_000"]["visible_body"] == "capsules"
        assert m["inside_visible_pct"] == pytest.approx(m["penetration_5mm_pct"], rel=1e-12, abs=1e-12)
        assert m["inside_visible_pct"] <= m["inside_visible_worst_pct"]
        assert 0 <= m["inside_visible_before_pct"] <= m["inside_visible_before_worst_pct"] <= 100
    assert (
        modes["regression"]["metrics"]["retrieval_usage"] == 0
        and modes["retrieval"]["metrics"]["retrieval_usage"] == 1
    )
    # the sweep's ends are the single modes: tau 0 never retrieves, tau 100 always does
    sweep = {p["tau"]: p for p in report["tau_sweep"]}
    assert sweep[0.0]["retrieval_usage"] == 0 and sweep[100.0]["retrieval_usage"] == 1
    assert sweep[0.0]["pve_mm"] == pytest.approx(modes["regression"]["metrics"]["pve_mm"], rel=1e-9)
    assert sweep[100.0]["pve_mm"] == pytest.approx(modes["retrieval"]["metrics"]["pve_mm"], rel=1e-9)
    for tau, mode in ((0.0, "regression"), (100.0, "retrieval")):  # plausibility beside accuracy, per tau
        assert sweep[tau]["sharpness"] == pytest.approx(
            modes[mode]["metrics"]["bending_energy_ratio"], rel=1e-9
        )
    goals = report["goals"]
    assert goals["hybrid_vs_regression"]["ratio"] == pytest.approx(
        modes["hybrid"]["metrics"]["pve_mm"] / modes["regression"]["metrics"]["pve_mm"]
    )
    assert goals["interior_tau_optimum"]["best_tau"] in sweep
    assert goals["residual_vs_regression"]["ratio"] == pytest.approx(
        modes["residual"]["metrics"]["pve_mm"] / modes["regression"]["metrics"]["pve_mm"]
    )
    hist = report["entropy"]["histogram"]
    assert (
        sum(hist["counts"]) == report["dataset"]["frames"] and len(hist["edges"]) == len(hist["counts"]) + 1
    )
    md = (out / "report.md").read_text()
    assert "| hybrid |" in md and "## Tau sweep" in md
    assert md.index("| inside seen before push-out % | inside seen % |") < md.index("| in capsules % |")
    assert "which are the visible body of a body with no mesh of its own (the mannequin)" in md
    for plot in ("error_over_time.png", "entropy_histogram.png", "tau_curve.png"):
        assert (out / plot).stat().st_size > 1000
    printed = capsys.readouterr().out
    assert "hybrid_vs_regression" in printed and "no ensemble ground truth" in printed
    assert printed.index("inside seen") < printed.index("in capsules")
    # a real-motion clip whose simulation was rejected is named in report.md, not silently dropped
    from hrr_garment.eval.report import markdown

    real = {
        "files": ["a.bvh", "b.bvh"],
        "dataset": "real.h5",
        "sequences": ["a"],
        "frames": 10,
        "rejected": {"b": "edge strain 2.7 > 2.5"},
        "modes": report["modes"],
    }
    assert "Not evaluated: `b`, its simulation was rejected (edge strain 2.7 > 2.5)" in markdown(
        {**report, "real_motion": real}, []
    )


def test_ensemble_scores_lead_the_report(trained):
    import numpy as np

    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.ensemble import TruthEnsemble
    from hrr_garment.eval.evaluate import EvaluationSettings, evaluate_modes
    from hrr_garment.eval.report import build_report, markdown
    from hrr_garment.inference.animator import Animator

    root, data, _ = trained
    animator, record = Animator.load(root / "model"), GarmentDataset(data).sequence("run_000")
    shift = np.array([0.003, 0.0, 0.0], np.float32)  # two truths 3 mm either side of the recorded one
    members = np.stack([record.garment + shift, record.garment - shift])
    ensembles = {record.name: TruthEnsemble(record.name, members, ["+x", "-x"], {})}
    results = evaluate_modes(
        animator,
        [record],
        EvaluationSettings(("regression", "retrieval"), progress=False),
        ensembles=ensembles,
    )
    for result in results.values():
        e = result.ensemble
        assert e["floor_mm"] == pytest.approx(6.0, rel=1e-4) and e["sequences"] == 1
        assert e["pve_floor_ratio"] == pytest.approx(e["pve_members_mm"] / e["floor_mm"])
        # the members' mean is the recorded truth: PVE to it is the single-truth PVE
        assert e["pve_ensemble_mean_mm"] == pytest.approx(result.metrics["pve_mm"], rel=1e-4)
        assert e["pve_members_mm"] >= e["pve_ensemble_mean_mm"] and e["energy_score_mm"] >= 0
        assert 0 <= e["penetration_before_worst_pct"] <= 100 and e["acceleration_ratio"] > 0
        # before the push-out, inside the mannequin's visible body (its capsules) as the push-out saw it
        assert e["inside_visible_before_pct"] == pytest.approx(e["penetration_before_pct"], abs=1e-9)
        assert e["inside_visible_before_worst_pct"] == pytest.approx(
            e["penetration_before_worst_pct"], abs=1e-9
        )
        assert e["truth_inside_visible_pct"] == pytest.approx(e["truth_penetration_pct"], abs=1e-9)
    report = build_report(
        model={"folder": "m", "garment": "skirt", "hash": "h", "tau": 0.1},
        dataset={"path": "d.h5", "split": "test", "sequences": [record.name], "frames": len(record.garment)},
        settings={"collision": True, "exclude_own_sequence": False, "gate": "entropy", "tau": 0.1},
        modes=results,
        sweep=None,
        seconds=1.0,
        ensemble={"members": 2, "perturbations": ["+x", "-x"], "sequences": 1},
    )
    md = markdown(report, [])
    assert md.index("ensemble ground truth") < md.index("## Modes") and "| simulation (truths) | 1.00 |" in md


def test_hrr_eval_excluding_own_sequence_changes_training_retrieval(trained, tmp_path):
    from hrr_garment.cli.eval import main

    root, data, _ = trained
    reports = []
    for flag in ([], ["--exclude-own-sequence"]):
        out = tmp_path / f"r{len(flag)}"
        assert (
            main(
                [
                    "--model",
                    str(root / "model"),
                    "--dataset",
                    str(data),
                    "--split",
                    "train",
                    "--modes",
                    "retrieval",
                    "--no-sweep",
                    "--no-plots",
                    "-o",
                    str(out),
                    "--quiet",
                    *flag,
                ]
            )
            == 0
        )
        reports.append(json.loads((out / "report.json").read_text()))
    own, excluded = (r["modes"]["retrieval"]["metrics"]["pve_mm"] for r in reports)
    train = reports[0]["dataset"]["sequences"]
    out = tmp_path / "two"
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--split",
                "train",
                "--modes",
                "retrieval",
                "--sequences",
                "2",
                "--no-sweep",
                "--no-plots",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    assert json.loads((out / "report.json").read_text())["dataset"]["sequences"] == [train[0], train[-1]]
    # with its own windows available retrieval finds the sequence itself: far closer than without
    assert own < excluded


def test_hrr_eval_refuses_bad_input(trained, tmp_path, capsys):
    from hrr_garment.cli.eval import main
    from hrr_garment.garment.templates import make_garment
    from tests.conftest import synthetic_dataset

    root, data, _ = trained
    other = synthetic_dataset(tmp_path / "dress.h5", make_garment("dress", 300))
    assert main(["--model", str(root / "model"), "--dataset", str(other), "-o", str(tmp_path / "x")]) == 2
    assert "dress.h5" in capsys.readouterr().err
    assert main(["--model", str(tmp_path / "nothing"), "-o", str(tmp_path / "x")]) == 2
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--modes",
                "direct",
                "-o",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    assert "baseline" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--model", str(root / "model"), "--modes", "bogus"])
    # a motion pattern the shell left unexpanded fails at once, not after the evaluation
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--motions",
                str(tmp_path / "*.bvh"),
                "-o",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    captured = capsys.readouterr()
    assert "*.bvh" in captured.err and "unquoted" in captured.err and "evaluating" not in captured.out
    assert not (tmp_path / "x").exists()


def test_direct_baseline_trains_is_causal_and_is_evaluated(trained, tmp_path):
    import shutil

    import numpy as np

    from hrr_garment.cli.eval import main as eval_main
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.synth import synthesize

    root, data, args = trained
    model = tmp_path / "model"
    shutil.copytree(root / "model", model)  # the shared fixture's bundle stays without a baseline
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(  # the section under its old name, "baseline", still read
        (root / "cfg.yaml").read_text() + "baseline:\n  model: {hidden: 32, layers: 1}\n"
        "  train: {epochs: 6, crop: 20, batch_size: 4}\n"
    )
    base = ["--dataset", str(data), "--config", str(cfg), "-o", str(model), "--quiet", "--stage"]
    assert train_main([*base, "direct"]) == 0
    log = [json.loads(line) for line in (model / "direct" / "log.jsonl").read_text().splitlines()]
    assert len(log) == 6 and min(r["val_l1"] for r in log) < log[0]["val_l1"]
    meta = json.loads((model / "bundle.json").read_text())
    assert meta["direct"]["epochs"] == 6 and "direct.safetensors" in meta["files"]
    assert train_main([*base, "baseline"]) == 0  # a re-run (the stage's old name) finds it current
    assert len((model / "direct" / "log.jsonl").read_text().splitlines()) == 6

    animator = Animator.load(model)
    assert animator.has_direct
    motion = synthesize("walk", 1.5, seed=11)
    full = animator.animate(motion, mode="direct", push_out=False)
    head = animator.animate(motion.slice(0, 20), mode="direct", push_out=False)
    assert full.vertices.shape == (motion.num_frames, 308, 3) and np.isfinite(full.vertices).all()
    assert np.abs(full.vertices[:19] - head.vertices[:19]).max() < 1e-5  # frame t never sees frames after t
    assert full.retrieved.sum() == 0 and (full.match == -1).all()

    out = tmp_path / "report"
    assert (
        eval_main(["--model", str(model), "--dataset", str(data), "--no-sweep", "-o", str(out), "--quiet"])
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert "direct" in report["modes"] and "hybrid_vs_direct" in report["goals"]
    assert math.isfinite(report["modes"]["direct"]["metrics"]["pve_mm"])


def test_demo_says_which_dataset_its_model_was_trained_on(trained, capsys):
    from hrr_garment.cli.demo import _say_dataset

    root, data, _ = trained
    _say_dataset(root / "model")
    said = capsys.readouterr().out
    assert f"trained on {data}" in said and "sequences" in said and "frames" in said


def test_library_plays_are_seeded_edits_of_the_training_clips(tmp_path):
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.library import MIN_ENTRY_S, library_plays, plays_digest, save_plays
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.io import load_motion
    from tests.conftest import synthetic_dataset

    ds = GarmentDataset(synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 200)))
    names = ds.splits["train"]
    plays = library_plays(ds, names, 4, seconds=2.0, seed=3)
    assert [p.name for p in plays] == ["play_00", "play_01", "play_02", "play_03"]
    assert plays_digest(plays) == plays_digest(library_plays(ds, names, 4, seconds=2.0, seed=3))
    assert plays_digest(plays) != plays_digest(library_plays(ds, names, 4, seconds=2.0, seed=4))
    for p in plays:
        replay = "->" not in p.description
        assert replay == (p.name in ("play_00", "play_02"))
        assert 0 < p.motion.num_frames <= 60 and np.isfinite(p.motion.root_translation).all()
        clips = [part.split(" x")[0] for part in p.description.split(" -> ")]
        assert all(c in names for c in clips), p.description
        entries = [float(part.split(" from ")[1].split(" s")[0]) for part in p.description.split(" -> ")]
        assert all(e >= MIN_ENTRY_S - 1e-9 for e in entries), (
            p.description
        )  # never where the database's clip began
    files = save_plays(plays, tmp_path / "plays")
    again = load_motion(files[1])
    np.testing.assert_allclose(again.root_translation, plays[1].motion.root_translation)
    assert json.loads((tmp_path / "plays" / "plays.json").read_text())["play_01"] == plays[1].description
    with pytest.raises(ValueError, match="count"):
        library_plays(ds, names, 0)


def test_a_play_knows_its_source_frames_and_plays_their_simulation_along(tmp_path, monkeypatch):
    """The database-simulation reference: at speed 1 a replay's reference is the clip's own simulated
    frames, and a transition's second clip, turned and moved to carry on, keeps its cloth where it
    was on the body (every vertex's distance to every joint)."""
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval import library
    from hrr_garment.garment.templates import make_garment
    from tests.conftest import synthetic_dataset

    ds = GarmentDataset(synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 200)))
    monkeypatch.setattr(library, "SPEED_RANGE", (1.0, 1.0))
    plays = library.library_plays(ds, ds.splits["train"], 4, seconds=2.0, seed=3)

    def distances(vertices, joints):
        return np.linalg.norm(vertices[:, :, None] - joints[:, None], axis=-1)

    for play in plays:
        sim = library.source_simulation(ds, play)
        assert sim.shape == (play.motion.num_frames, ds.template.num_vertices, 3) and sim.dtype == np.float32
        assert sum(len(s.frames) for s in play.sources) - play.blend == play.motion.num_frames
        first = play.sources[0]
        clip = ds.sequence(first.clip)
        shown = first.frames.astype(int)
        assert (
            np.array_equal(shown, first.frames) and shown[0] >= 1
        )  # entered part-way, whole frames at speed 1
        head = len(shown) - play.blend
        np.testing.assert_allclose(sim[:head], clip.garment[shown[:head]], atol=1e-5)
        if len(play.sources) == 2:
            second = play.sources[1]
            other = ds.sequence(second.clip)
            tail = second.frames.astype(int)[play.blend :]
            joints = play.motion.joint_positions[head + play.blend :]
            np.testing.assert_allclose(
                distances(sim[head + play.blend :], joints),
                distances(other.garment[tail], other.motion.joint_positions[tail]),
                atol=1e-4,
            )
    assert any(len(p.sources) == 2 for p in plays)
    with pytest.raises(ValueError, match="sources"):
        library.source_simulation(ds, library.LibraryPlay("bare", "", plays[0].motion))


def test_library_protocol_in_hrr_eval(artist_model, tmp_path, monkeypatch):
    """Plays of a simulated dataset's training clips, simulated with their ensembles, evaluated with
    their own sweep and goals (conftest's tiny artist dress)."""
    from hrr_garment.cli.eval import main

    monkeypatch.setenv("HRR_HOME", str(tmp_path / "work"))
    data, model, _ = artist_model
    out = tmp_path / "report"
    assert (
        main(
            [
                "--model",
                str(model),
                "--dataset",
                str(data),
                "--split",
                "test",
                "--ensemble",
                "2",
                "--jobs",
                "1",
                "--library",
                "2",
                "--tau-sweep",
                "0,100",
                "--no-plots",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    assert report["format_version"] == REPORT_VERSION == 16
    # the dataset's own frames against the ensemble: a simulation like the members, about 1 x the floor
    own = report["dataset_simulation"]["ensemble"]
    assert 0.5 < own["pve_floor_ratio"] < 2.0 and set(report["dataset_simulation"]["sequences"]) == set(
        report["dataset"]["sequences"]
    )
    assert "| dataset simulation |" in (out / "report.md").read_text()
    lib = report["library"]
    assert list(lib["plays"]) == ["play_00", "play_01"] and "->" in lib["plays"]["play_01"]
    assert lib["sequences"] == ["play_00", "play_01"] and not lib["rejected"]
    assert lib["ensemble"]["members"] == 2 and lib["ensemble"]["sequences"] == 2
    modes = lib["modes"]
    assert (
        modes["regression"]["metrics"]["retrieval_usage"] == 0
        and modes["retrieval"]["metrics"]["retrieval_usage"] == 1
    )
    assert all(math.isfinite(modes[m]["ensemble"]["pve_floor_ratio"]) for m in modes)
    sweep = {p["tau"]: p for p in lib["tau_sweep"]}
    assert sweep[0.0]["pve_mm"] == pytest.approx(modes["regression"]["metrics"]["pve_mm"], rel=1e-9)
    assert sweep[100.0]["pve_mm"] == pytest.approx(modes["retrieval"]["metrics"]["pve_mm"], rel=1e-9)
    goals = lib["goals"]
    assert goals["hybrid_vs_regression"]["ratio"] == pytest.approx(
        modes["hybrid"]["metrics"]["pve_mm"] / modes["regression"]["metrics"]["pve_mm"]
    )
    scores = {m: modes[m]["ensemble"]["energy_score_mm"] for m in ("hybrid", "regression", "retrieval")}
    assert goals["energy_score_vs_single_modes"]["met"] == (
        scores["hybrid"] < min(scores["regression"], scores["retrieval"])
    )
    reference = lib["source_simulation"]  # the database's own simulation of the played frames
    assert reference["metrics"]["retrieval_usage"] == 1 and math.isfinite(
        reference["ensemble"]["pve_floor_ratio"]
    )
    assert set(reference["sequences"]) == {"play_00", "play_01"}
    md = (out / "report.md").read_text()
    assert "## Library protocol" in md and lib["plays"]["play_01"] in md and "| database simulation |" in md
    # the default output leads the protocol, held to the library's bars
    bars = lib["default"]["bars"]
    assert list(bars) == ["energy score vs regression", "sharpness", "hem swing"]
    assert bars["energy score vs regression"]["target"] == pytest.approx(scores["regression"])
    assert bars["energy score vs regression"]["value"] == pytest.approx(
        modes["auto"]["ensemble"]["energy_score_mm"]
    )
    assert bars["sharpness"]["met"] == (modes["auto"]["ensemble"]["bending_energy_ratio"] >= 0.85)
    assert md.index("**The default output**", md.index("## Library protocol")) < md.index(
        "| database simulation |"
    )
    assert report["default"]["bars"]["PVE / floor"]["value"] == pytest.approx(
        report["modes"]["auto"]["ensemble"]["pve_floor_ratio"]
    )


def test_paper_protocol_beside_the_papers_ratios(trained, paper_model, tmp_path, capsys):
    from hrr_garment.cli.eval import main
    from hrr_garment.eval.goals import PAPER_RATIOS

    root, data, _ = trained
    out = tmp_path / "report"
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--paper",
                str(paper_model),
                "--no-sweep",
                "--no-plots",
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    report = json.loads((out / "report.json").read_text())
    paper = report["paper"]
    assert paper["model"] == str(paper_model) and paper["paper_ratios"] == {
        k: list(v) for k, v in PAPER_RATIOS.items()
    }
    modes = paper["modes"]
    assert set(modes) == set(report["modes"]) and all(
        set(m["sequences"]) == {"run_000"} for m in modes.values()
    )
    assert paper["goals"]["hybrid_vs_regression"]["ratio"] == pytest.approx(
        modes["hybrid"]["metrics"]["pve_mm"] / modes["regression"]["metrics"]["pve_mm"]
    )
    md = (out / "report.md").read_text()
    assert "## Paper protocol" in md and "| hybrid vs regression |" in md and "0.37-0.49" in md
    # a model validated on held-out clips is not the paper's protocol
    capsys.readouterr()
    assert (
        main(
            [
                "--model",
                str(root / "model"),
                "--dataset",
                str(data),
                "--paper",
                str(root / "model"),
                "--no-sweep",
                "--no-plots",
                "-o",
                str(tmp_path / "x"),
                "--quiet",
            ]
        )
        == 2
    )
    assert "--validation windows" in capsys.readouterr().err


def test_sampler_trains_draws_by_seed_streams_the_same_and_is_evaluated(trained, tmp_path):
    import shutil

    import numpy as np

    from hrr_garment.artifacts.manifest import BundleError
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.cli.eval import main as eval_main
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.inference.animator import Animator
    from hrr_garment.motion.native_file import save_motion
    from hrr_garment.motion.synth import synthesize

    root, data, args = trained
    with pytest.raises(BundleError, match="--stage sampler"):  # the shared model has none
        Animator.load(root / "model").animate(synthesize("walk", 0.5, seed=1), mode="sample")
    model = tmp_path / "model"
    shutil.copytree(root / "model", model)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(
        (root / "cfg.yaml").read_text() + "sampler:\n  model: {hidden: 32, layers: 1, steps: 2}\n"
        "  train: {epochs: 3, batch_size: 64, contact_steps: 4}\n"
    )
    base = ["--dataset", str(data), "--config", str(cfg), "-o", str(model), "--quiet", "--stage"]
    assert train_main([*base, "sampler"]) == 0
    meta = json.loads((model / "bundle.json").read_text())
    assert meta["sampler"]["epochs"] == 3 and "sampler.safetensors" in meta["files"]
    assert math.isfinite(meta["sampler"]["validation_mm"])
    contact = meta["sampler"]["contact"]  # draws taught the body (here the mannequin's capsules)
    assert contact["steps"] == 4 and contact["against"] == {"capsules": ["mannequin"]}
    assert 0.0 <= contact["val_inside_after"] <= 1.0 and math.isfinite(contact["mean_depth_mm"])
    from hrr_garment.train.sampler_calibration import NOISE_DECAYS, TEMPERATURES

    entry = meta["sampler"]  # the draw calibrated on the validation clips: as sharp as the simulation
    assert entry["temperature"] in TEMPERATURES and entry["noise_decay"] in NOISE_DECAYS
    nearest = min(entry["sharpness"].values(), key=lambda r: abs(math.log(r)))
    assert entry["sharpness"][f"{entry['temperature']:g}"] == nearest
    auto = meta["auto"]  # the draw is a candidate of auto's, measured into the recorded calibration
    assert set(auto["candidates"]["sample"]) >= {"pve_mm", "sharpness", "hem_swing", "penetration_pct"}
    assert "hybrid" in auto["candidates"] and auto["mode"] in ("hybrid", "residual", "detail", "sample")
    assert train_main([*base, "sampler"]) == 0  # a re-run finds it current
    assert len((model / "sampler" / "log.jsonl").read_text().splitlines()) == 3

    animator = Animator.load(model)
    assert animator.supports("sample")
    motion = synthesize("walk", 1.5, seed=11)
    a, again, other = (animator.animate(motion, mode="sample", seed=s, push_out=False) for s in (3, 3, 4))
    assert a.vertices.shape == (motion.num_frames, 308, 3) and np.isfinite(a.vertices).all()
    assert np.array_equal(a.vertices, again.vertices)  # the same seed, bit for bit
    assert np.abs(a.vertices - other.vertices).mean() > 1e-4  # another seed, another cloth
    assert a.settings["mode"] == "sample" and a.settings["seed"] == 3 and a.settings["causal"] == 1
    head = animator.animate(motion.slice(0, 20), mode="sample", seed=3, push_out=False)
    assert np.abs(a.vertices[:20] - head.vertices).max() < 1e-5  # frame t never sees frames after t
    # a crowd draws each character as its clip: the run's seed, or one of its own
    crowd = animator.crowd(mode="sample", seed=3, push_out=False, device="native")
    crowd.set_seed("b", 4)
    frames = [
        crowd.push_motions({"a": motion.slice(t, t + 1), "b": motion.slice(t, t + 1)})
        for t in range(motion.num_frames)
    ]
    streamed = np.stack(frames, 1)
    assert np.abs(streamed[0] - a.vertices).max() < 1e-4
    assert np.abs(streamed[1] - other.vertices).max() < 1e-4
    with pytest.raises(ValueError, match="sample_steps"):
        animator.animate(motion, mode="regression", sample_steps=2)
    for bad in (-1, 2**32, 1.5):
        with pytest.raises(ValueError, match="seed"):
            animator.animate(motion, mode="sample", seed=bad)
    with pytest.raises(ValueError, match="seed"):
        crowd.set_seed("c", 2**40)

    out_h5 = tmp_path / "drawn.h5"
    model_args = ["--model", str(model), "-o", str(out_h5), "--mode", "sample", "--seed", "3"]
    motion_file = tmp_path / "walk.npz"
    save_motion(motion, motion_file)
    assert animate_main([str(motion_file), *model_args, "--sample-steps", "1"]) == 0
    assert animate_main([str(motion_file), *model_args, "--seed", "-2"]) == 2
    report_dir = tmp_path / "report"
    evaluated = ["--model", str(model), "--dataset", str(data), "--modes", "regression,sample"]
    assert eval_main([*evaluated, "--no-sweep", "-o", str(report_dir), "--quiet"]) == 0
    report = json.loads((report_dir / "report.json").read_text())
    assert math.isfinite(report["modes"]["sample"]["metrics"]["pve_mm"])
