"""hrr-make end to end on tiny inputs: a body, the tiny preset's five clips, a budget of minutes. It
writes the model, the ONNX graph, the clips, the preview, the report and make.json; a re-run redoes
nothing; a run stopped mid-simulation or mid-training goes on from its recorded plan (finished
sequences not simulated again, the code space from its checkpoint); a changed garment keeps the
body and the motion library and makes the rest again; bad input is refused naming the problem."""

import importlib
import json
from dataclasses import replace
from pathlib import Path

import pytest

from hrr_garment.body.body_file import write_body
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.cli import make as make_cli
from hrr_garment.cli.make_data import own_animations
from hrr_garment.cli.make_run import MakeRun
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.motion.synth import synthesize
from hrr_garment.pipeline.make_budget import BudgetShares
from hrr_garment.pipeline.make_record import MakeRecord, MakeRequest

pytestmark = [pytest.mark.slow, pytest.mark.sim]

# the costs of tiny stages, so that a budget of a few minutes plans a run of a few minutes (the tiny
# model's graph exports in about a minute). The budget leaves the plan room for a probe slowed by
# the other test worker: at 100 s, a probe of 6 frames/s (21 s, half this machine's idle rate) left
# too little to simulate and train (BudgetTooSmall), and at 150 s one of 4.1 frames/s (32 s, a
# clean clone on the AVX2-only EPYC, 2026-12-07); 180 s holds down to about 3 frames/s
TINY = BudgetShares(
    train_fixed_s=10.0, onnx_s=50.0, clip_s=5.0, report_s_per_frame=0.01, min_train_s=10.0, ensemble=2
)
BUDGET_S = 180.0


def _request(tmp_path, garment="skirt", skip=(), budget_s=BUDGET_S) -> MakeRequest:
    body = tmp_path / "body.json"
    if not body.exists():
        write_body(body, mannequin_record())
    return MakeRequest(
        character=body,
        garment=garment,
        out=tmp_path / "out",
        budget_s=budget_s,
        library="tiny",
        jobs=1,
        progress=False,
        skip=skip,
    )


def _stopped(run: MakeRun, target: str, stop_after) -> None:
    """Run ``run`` with ``target`` (a function's import path) wrapped to call the original and then
    raise KeyboardInterrupt, as Ctrl-C would, where ``stop_after(*args)`` says so."""
    module, name = target.rsplit(".", 1)
    original = getattr(importlib.import_module(module), name)

    def then_stop(*args, **kwargs):
        original(*args, **kwargs)
        if stop_after(*args):
            raise KeyboardInterrupt

    with pytest.MonkeyPatch.context() as patch, pytest.raises(KeyboardInterrupt):
        patch.setattr(target, then_stop)
        run.run()


def _parts(out: Path) -> dict[str, int]:
    """Each simulated part's modification time: a part simulated again would change it."""
    return {p.name: p.stat().st_mtime_ns for p in (out / "dataset.parts").glob("*.npz")}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """One whole run, stopped twice as Ctrl-C stops it: when the simulation has finished its first
    sequence, then when the code space has written its first checkpoint; run again each time. What
    it had recorded at each stop."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.sim.build import warm_up
    from hrr_garment.sim.preset import load_preset
    from hrr_garment.sim.simulator import SimSettings

    # the simulator's kernels compiled before the run: a cold compile (minutes) would not fit the budget
    warm_up(make_garment("skirt", 300), SimSettings.from_dict(load_preset("tiny").sim))
    tmp_path = tmp_path_factory.mktemp("make")
    request = _request(tmp_path)
    out = request.out
    # the probe's sequences finish before its stage is recorded; the first one after it is the simulation's
    _stopped(MakeRun(request, TINY), "hrr_garment.sim.executors._finish", lambda *a: _probed(out))
    simulating = {"record": json.loads((out / "make.json").read_text()), "parts": _parts(out)}
    codespace_checkpoint = lambda path, *a: "codebook" in Path(path).parts  # noqa: E731
    _stopped(MakeRun(request, TINY), "hrr_garment.train.checkpoint.save_checkpoint", codespace_checkpoint)
    training = {
        "record": json.loads((out / "make.json").read_text()),
        "dataset": (out / "dataset.h5").read_bytes(),
        "autoencoder": (out / "model" / "autoencoder" / "model.pt").stat().st_mtime_ns,
        "codespace_epochs": _epochs(out / "model" / "codebook" / "log.jsonl"),
    }
    MakeRun(request, TINY).run()
    return request, {"simulating": simulating, "training": training}


def _probed(out: Path) -> bool:
    return "probe" in json.loads((out / "make.json").read_text())["stages"]


def _epochs(log: Path) -> list[int]:
    return [json.loads(line)["epoch"] for line in log.read_text().splitlines()] if log.exists() else []


def test_a_run_writes_every_output_and_its_record(made):
    request, _ = made
    out = request.out
    outputs = out / "outputs"
    for path in ("body.json", "dataset.h5", "model/bundle.json", "train.yaml", "make.json"):
        assert (out / path).exists(), path
    assert (outputs / "body.onnx").exists() and (outputs / "body.tensors.npz").exists()
    assert (outputs / "preview.png").exists() and (outputs / "report" / "report.json").exists()
    clips = sorted(outputs.glob("body_*.glb"))
    assert clips, "no clip exported"
    summary = json.loads((outputs / "summary.json").read_text())
    assert summary["pve_over_floor"] > 0 and summary["step_ms"] > 0
    assert summary["onnx_step_ms"] > 0  # the graph written, timed in onnxruntime as an engine runs it
    assert summary["motion_licence"].startswith("may ship commercially")  # procedural motion only
    record = MakeRecord.open(out)
    assert list(record.stages) == ["body", "motions", "probe", "simulate", "train", "onnx", "clips", "report"]
    assert all(entry["seconds"] >= 0 for entry in record.stages.values())
    plan = record.plan
    assert set(plan["selection"]) == {"train", "val", "test"} and plan["selection"]["test"]
    assert plan["budget"]["total_s"] == pytest.approx(BUDGET_S, abs=2.0)
    assert "hrr-eval --model" in record.stages["report"]["command"]


def test_a_run_stopped_mid_simulation_goes_on_from_its_plan(made):
    request, stops = made
    stopped = stops["simulating"]
    assert set(stopped["record"]["stages"]) == {"body", "motions", "probe"}
    record = MakeRecord.open(request.out)
    assert record.plan["selection"] == stopped["record"]["plan"]["selection"]  # not planned again
    assert record.stages["probe"] == stopped["record"]["stages"]["probe"]  # not probed again
    # the probe's sequences and the one finished before the stop are kept, not simulated again
    finished = _parts(request.out)
    assert stopped["parts"] and all(finished[name] == stamp for name, stamp in stopped["parts"].items())
    assert len(finished) > len(stopped["parts"])
    planned = {n for names in record.plan["selection"].values() for n in names}
    simulated = GarmentDataset(request.out / "dataset.h5").names
    assert set(simulated) <= planned | {f"{n}_mirror" for n in planned}


def test_a_run_stopped_mid_training_goes_on_from_its_checkpoint(made):
    request, stops = made
    stopped = stops["training"]
    out = request.out
    assert "simulate" in stopped["record"]["stages"] and "train" not in stopped["record"]["stages"]
    assert stopped["codespace_epochs"] == [1]  # stopped at the code space's first checkpoint
    assert (out / "dataset.h5").read_bytes() == stopped["dataset"]  # the same dataset
    # the autoencoder kept; the code space continued from its checkpoint: every epoch trained once
    assert (out / "model" / "autoencoder" / "model.pt").stat().st_mtime_ns == stopped["autoencoder"]
    epochs = _epochs(out / "model" / "codebook" / "log.jsonl")
    # (a loaded machine may have spent the code space's minutes on its first epoch: then none follows)
    assert epochs == list(range(1, len(epochs) + 1))
    assert MakeRecord.open(out).plan["training"] == stopped["record"]["plan"]["training"]  # minutes kept


def test_a_finished_run_redoes_nothing(made, monkeypatch):
    request, _ = made
    before = MakeRecord.open(request.out).stages

    def refused(*args, **kwargs):
        raise AssertionError("a finished stage ran again")

    for name in ("hrr_garment.sim.build.build_dataset", "hrr_garment.pipeline.train.train_model"):
        monkeypatch.setattr(name, refused)
    MakeRun(request, TINY).run()
    assert MakeRecord.open(request.out).stages == before


def test_a_new_garment_keeps_the_body_and_the_motion(made, tmp_path):
    """Only the garment changed: the body and the motion library's features are kept, everything
    that depends on the garment (its probe, data, model and outputs) goes; the run is stopped once
    the new garment's simulation has begun."""
    import shutil

    request, _ = made
    shutil.copytree(request.out, tmp_path / "out")
    (tmp_path / "body.json").write_bytes(request.character.read_bytes())
    before = MakeRecord.open(tmp_path / "out").stages
    # a budget the dress's plan fits on a slow hour (its probe measured 5.9 frames/s and 21 s on the
    # EPYC); the run stops after its probe either way
    again = _request(tmp_path, garment="dress", budget_s=2 * BUDGET_S)
    _stopped(MakeRun(again, TINY), "hrr_garment.sim.executors._finish", lambda *a: _probed(again.out))
    after = MakeRecord.open(again.out).stages
    assert after["body"] == before["body"] and after["motions"] == before["motions"]
    assert after["probe"]["key"] != before["probe"]["key"]
    assert not {"simulate", "train", "onnx", "clips", "report"} & set(after)
    assert not (again.out / "model").exists() and not (again.out / "outputs").exists()


def test_bad_requests_are_refused(tmp_path, capsys):
    body = tmp_path / "body.json"
    write_body(body, mannequin_record())
    out = str(tmp_path / "out")
    assert make_cli.main([str(body), "--garment", "cape", "-o", out]) == 2
    assert "neither an OBJ nor a built-in garment" in capsys.readouterr().err
    assert make_cli.main([str(body), "--garment", "skirt", "-o", out, "--budget", "soon"]) == 2
    assert "not a budget" in capsys.readouterr().err
    assert make_cli.main([str(tmp_path / "missing.glb"), "--garment", "skirt", "-o", out]) == 2
    assert "missing.glb: no such file" in capsys.readouterr().err
    assert make_cli.main([str(body), "--garment", "skirt", "-o", out, "--material", "denimm"]) == 2
    assert "denimm" in capsys.readouterr().err
    assert make_cli.main([str(body), "--garment", "skirt", "-o", out, "--air-drag", "-1"]) == 2
    assert "a drag coefficient" in capsys.readouterr().err
    assert not Path(out).exists()  # nothing made


def test_a_cloth_asked_for_is_the_librarys_cloth():
    """hrr-make --material --air-drag --cloth-viscosity: the library is simulated in that cloth, in
    that air (the simulation's key with it), and the model then knows that cloth."""
    from hrr_garment.cli.make_run import with_cloth
    from hrr_garment.garment.fabrics import FABRICS
    from hrr_garment.pipeline.make_record import MakeRequest
    from hrr_garment.sim.config import SimSettings
    from hrr_garment.sim.preset import load_preset

    preset = load_preset("real-quick-commercial")
    asked = MakeRequest(Path("hero.glb"), "dress.obj", Path("out"))
    assert with_cloth(preset, asked) is preset
    asked = replace(asked, material="denim", air_drag=1.2, cloth_viscosity=0.02)
    denim = SimSettings.from_dict(with_cloth(preset, asked).sim)
    assert denim.material == FABRICS["denim"] and denim.air_drag == 1.2 and denim.cloth_viscosity == 0.02
    assert denim.substeps == SimSettings.from_dict(preset.sim).substeps  # the rest as the preset's


def test_a_characters_own_animations_become_clips(tmp_path):
    from tests.motion.test_gltf import write_character

    glb = tmp_path / "hero.glb"
    write_character(glb, {"Walk": synthesize("walk", 3.0, seed=1), "Wave": synthesize("idle", 1.0, seed=2)})
    run = MakeRun(_request(tmp_path), TINY)
    assert own_animations(glb, run.out / "motions" / "own") == ["Walk"]  # the other, 1 s, is a pose
    assert [p.name for p in run.own_motions] == ["own_Walk.npz"]  # never a library sequence's name


def test_the_body_a_garment_was_modelled_on(tmp_path):
    """--made-for: a body.json is read as it is; a file of another kind is refused naming it (a body
    mesh OBJ is fitted with the parametric body, the bodies extra: not run here)."""
    from hrr_garment.cli.make_data import garment_body
    from hrr_garment.errors import InputError

    body = tmp_path / "made_for.json"
    write_body(body, mannequin_record())
    assert garment_body(body).stature == pytest.approx(mannequin_record().stature)
    with pytest.raises(InputError, match="a body.json or a body mesh as OBJ"):
        garment_body(tmp_path / "made_for.fbx")
