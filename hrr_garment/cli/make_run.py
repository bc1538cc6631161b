"""hrr-make's stages, in order, each skipped where make.json records it finished from the same inputs
(:mod:`hrr_garment.pipeline.make_record`): the character's body and animations, the motion library
and its descriptors, the simulator's probe and the plan, the simulation, the training, and the
outputs (the ONNX graph, the character's clips, the preview, the report).

The outputs are made by the same code as the commands a user would chain by hand (hrr-export-model,
hrr-animate, hrr-export, hrr-preview, hrr-eval), called in-process with the arguments make.json
records under each stage's ``command``, so any stage can be re-run alone from the record."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

from ..body.body_file import read_body, write_body
from ..body.skinned_body import visible_body
from ..errors import InputError
from ..io_utils import atomic_write_text
from ..pipeline.make_budget import (
    OUTPUT_STAGES,
    BudgetPlan,
    BudgetShares,
    MeasuredStart,
    plan_budget,
    take_prefix,
    train_config,
    training_estimate_s,
    training_minutes,
)
from ..pipeline.make_library import (
    DESCRIPTORS_NAME,
    MIN_HELD_OUT,
    MotionLibrary,
    library_descriptors,
    motion_library,
    ordered_parts,
    sized_selection,
)
from ..pipeline.make_record import MakeRecord, MakeRequest, content_key, file_key
from ..sim.preset import load_preset
from .make_data import (
    ChosenBuild,
    build_chosen,
    check_garment,
    frames_to_simulate,
    own_animations,
    place_garment,
)
from .make_outputs import SHOWCASE_CLIPS
from .make_progress import MakeProgress

GARMENT_STAGES = ("probe", "simulate", "train", *OUTPUT_STAGES)  # what a garment change redoes
REPORT_FRAMES = 450  # held-out frames (15 s of motion, before mirroring) the report scores
PROBE_SEQUENCES = 2  # random training sequences per worker the probe simulates (kept: taken first)


def with_cloth(preset, request: MakeRequest):
    """``preset`` with its simulation in the request's cloth, air drag and cloth viscosity where given
    (hrr-make --material, --air-drag, --cloth-viscosity): the model then knows that cloth."""
    given = {k: getattr(request, k) for k in ("material", "air_drag", "cloth_viscosity")}
    changes = {k: v for k, v in given.items() if v is not None}
    return replace(preset, sim={**preset.sim, **changes}) if changes else preset


class MakeRun:
    """One run of hrr-make over ``request.out`` (see the module docstring)."""

    def __init__(self, request: MakeRequest, shares: BudgetShares | None = None):
        self.request, self.shares = request, shares or BudgetShares()
        self.out = request.out
        self.record = MakeRecord.open(self.out)
        self.record.request = request.to_dict()
        self.preset = with_cloth(load_preset(request.library), request)
        self.progress = MakeProgress(self.record, shown=request.progress)
        self.keys: dict[str, str] = {}

    @property
    def body_path(self) -> Path:
        return self.out / "body.json"

    @property
    def dataset(self) -> Path:
        return self.out / "dataset.h5"

    @property
    def model(self) -> Path:
        return self.out / "model"

    def run(self) -> None:
        check_garment(self.request)  # a garment that cannot be read fails before any work
        self.body_stage()
        library = self.motion_stage()
        garment, made_for = self.garment()
        order = ordered_parts(
            library, self.descriptors, self.request.selection, seed=self.request.seed, probe=self.probe_count
        )
        self.probe_stage(library, garment, made_for, order)
        chosen = self.plan(library, order)
        self.simulate_stage(library, garment, made_for, chosen)
        self.train_stage()
        from .make_outputs import write_outputs

        write_outputs(self)
        self.progress.finished()

    # -- the body and the motion: what a changed garment keeps -----------------------------------
    def body_stage(self) -> None:
        character = self.request.character
        if not character.exists():
            raise InputError(character, "no such file")
        key = self.keys["body"] = content_key(["body", file_key(character), character.suffix.lower()])
        if self.record.current("body", key) and self.body_path.exists():
            return
        with self.progress.stage("body") as t:
            if character.suffix.lower() == ".json":
                write_body(self.body_path, read_body(character))
                shutil.rmtree(self.out / "motions" / "own", ignore_errors=True)  # a character's before
                names = []
            else:
                from ..body.character import character_body

                fitted, _ = character_body(character)
                write_body(self.body_path, fitted)
                names = own_animations(character, self.out / "motions" / "own")
        self.record.finish("body", key, t.seconds, {"animations": names})

    @property
    def own_motions(self) -> list[Path]:
        folder = self.out / "motions" / "own"
        return sorted(folder.glob("*.npz")) if folder.exists() else []

    def motion_stage(self) -> MotionLibrary:
        key = self.keys["motions"] = content_key(["motions", self.keys["body"], self.preset.name])
        with self.progress.stage("motions", quiet=self.record.current("motions", key)) as t:
            library = motion_library(self.preset, self.own_motions)
            self.descriptors = library_descriptors(
                library, self.out / "motions" / DESCRIPTORS_NAME, progress=self.request.progress
            )
        if not self.record.current("motions", key):
            notes = {"sequences": len(library.specs), "frames": sum(library.frames.values())}
            self.record.finish("motions", key, t.seconds, notes)
        return library

    # -- the garment, and what depends on it -----------------------------------------------------
    def garment(self):
        """The garment placed for the character (an OBJ made for it, or a template carried onto it);
        a garment unlike the recorded one drops every stage made from it."""
        from ..sim.parts import template_hash

        mesh, made_for = place_garment(self.request, read_body(self.body_path), self.preset.vertices)
        modelled_on = file_key(self.request.made_for) if self.request.made_for else None
        key = content_key(["garment", template_hash(mesh), self.keys["body"], modelled_on])
        self.keys["garment"] = key
        if self.record.plan.get("garment_key") not in (None, key):
            self._forget_garment()
        return mesh, made_for

    def _forget_garment(self) -> None:
        print("hrr-make: the garment changed: its dataset, model and outputs are made again")
        for path in (self.dataset, self.dataset.with_suffix(".parts"), self.model, self.out / "outputs"):
            if path.is_dir():
                shutil.rmtree(path)
            elif path.exists():
                path.unlink()
        self.record.plan = {}
        self.record.forget(list(GARMENT_STAGES))

    def _build(self, library, garment, made_for, names: list[str], *, probe: bool):
        return build_chosen(
            library,
            names,
            ChosenBuild(
                garment=garment,
                made_for=made_for,
                body_path=self.body_path,
                dataset=self.dataset,
                sim=self.sim_settings,
                request=self.request,
            ),
            probe=probe,
        )

    @property
    def sim_settings(self):
        from ..sim.simulator import SimSettings

        overrides = {"device": self.request.device} if self.request.device else {}
        return SimSettings.from_dict({**self.preset.sim, **overrides})

    @property
    def probe_count(self) -> int:
        import os

        return PROBE_SEQUENCES * (self.request.jobs or os.cpu_count() or 1)

    def probe_stage(self, library, garment, made_for, order) -> None:
        from ..sim.build import warm_up

        probe = order["train"][len(library.own) : len(library.own) + self.probe_count]
        sim = self.sim_settings.to_dict()
        key = content_key(["probe", self.keys["garment"], self.keys["motions"], probe, sim])
        self.keys["probe"] = key
        if self.record.current("probe", key):
            return
        pending = frames_to_simulate(library, probe, self.dataset)
        with self.progress.stage("probe") as t:
            warm_up(garment, self.sim_settings)
            compiled = t.seconds
            self._build(library, garment, made_for, probe, probe=True)
        if pending == 0:
            raise InputError(
                self.dataset, "the probe found its clips simulated already; remove make.json to start over"
            )
        rate = pending / max(t.seconds - compiled, 1e-6)  # every frame the simulator ran, lead-ins too
        self.record.plan["garment_key"] = self.keys["garment"]
        notes = {"frames": library.simulated_frames(probe), "simulator_frames_per_s": round(rate, 2)}
        self.record.finish("probe", key, t.seconds, notes)

    def plan(self, library, order) -> dict[str, list[str]]:
        """The budget's plan and the sequences it takes, made once after the probe and kept."""
        plan = self.record.plan
        request = self.request
        # what the plan is made from: the probe, and the budget, selection, outputs and shares asked
        key = content_key(
            [self.keys["probe"], request.budget_s, request.selection, request.outputs, self.shares.to_dict()]
        )
        if plan.get("key") == key and "selection" in plan:
            self.progress.show_plan()
            return plan["selection"]
        spent = {s: self.record.stages[s]["seconds"] for s in ("body", "motions", "probe")}
        test_frames = library.simulated_frames(
            take_prefix(order["test"], library.frames, REPORT_FRAMES, at_least=MIN_HELD_OUT)
        )
        probe = self.record.stages["probe"]
        outputs = request.outputs
        if "report" in outputs and not order["test"]:
            print("hrr-make: the library holds out no test clips: no report")
            outputs = tuple(s for s in outputs if s != "report")

        # the graph written pushes the cloth out of the character's own mesh where it has one
        own_mesh = visible_body(read_body(self.body_path)) is not None

        def plan_at(rate: float) -> BudgetPlan:
            return plan_budget(
                request.budget_s,
                MeasuredStart(spent, rate, simulated_frames=probe["frames"]),
                test_frames=test_frames,
                clips=(len(self.own_motions) or SHOWCASE_CLIPS) if "clips" in outputs else 0,
                outputs=outputs,
                shares=self.shares,
                mesh=own_mesh,
            )

        budget, chosen = sized_selection(
            library,
            order,
            plan_at,
            simulator_rate=probe["simulator_frames_per_s"],
            test_frames=REPORT_FRAMES,
            validation=self.shares.validation,
        )
        plan.update(
            key=key,
            outputs=list(outputs),
            budget=budget.to_dict(),
            estimates=budget.estimates,
            shares=self.shares.to_dict(),
            selection=chosen,
            frames={p: library.simulated_frames(names) for p, names in chosen.items()},
            library_frames=library.simulated_frames(library.names),
        )
        self.record.write()
        self.progress.show_plan()
        return chosen

    def simulate_stage(self, library, garment, made_for, chosen) -> None:
        names = [n for part in ("train", "val", "test") for n in chosen[part]]
        key = self.keys["simulate"] = content_key(["simulate", self.keys["probe"], names, self.preset.sim])
        if self.record.current("simulate", key) and self.dataset.exists():
            return
        with self.progress.stage("simulate") as t:
            report = self._build(library, garment, made_for, names, probe=False)
        notes = {"sequences": len(report.sequences), "rejected": sorted(report.rejects)}
        self.record.finish("simulate", key, t.seconds, notes)

    def train_stage(self) -> None:
        import yaml

        from ..pipeline.train import train_model
        from ..pipeline.train_settings import TrainSettings

        plan = self.record.plan
        if plan.get("training", {}).get("simulate_key") != self.keys["simulate"]:  # decided once, kept
            minutes = training_minutes(plan["budget"], self.progress.elapsed(), self.shares)
            estimate = training_estimate_s(minutes, plan["budget"], self.shares)
            plan["training"] = {"simulate_key": self.keys["simulate"], **minutes, "estimate_s": estimate}
            self.record.write()
            if self.request.progress:
                print(
                    f"hrr-make: training for what the budget has left: the autoencoder "
                    f"{minutes['autoencoder_minutes']:.1f} min, the code space "
                    f"{minutes['codespace_minutes']:.1f} min "
                    f"(planned {plan['budget']['autoencoder_minutes']:.1f} and "
                    f"{plan['budget']['codespace_minutes']:.1f})"
                )
        config = train_config(plan["training"], self.request.device)
        config_path = self.out / "train.yaml"
        text = "# hrr-make's training budget (the preset's settings, trained for these minutes)\n"
        atomic_write_text(config_path, text + yaml.safe_dump(config, sort_keys=True))
        key = self.keys["train"] = content_key(["train", self.keys["simulate"], config, self.preset.train])
        if self.record.current("train", key) and (self.model / "bundle.json").exists():
            return
        settings = TrainSettings.load(self.preset, user_config=config_path)
        with self.progress.stage("train") as t:
            result = train_model(
                self.dataset,
                self.model,
                settings,
                stages=("autoencoder", "codespace"),
                progress=self.request.progress,
                callback=self.progress.train_callback(),
            )
        epochs = {stage: report.epochs for stage, report in result.reports.items()}
        command = (
            f"hrr-train --preset {self.preset.name} --dataset {self.dataset} --config {config_path} "
            f"--stage autoencoder (then --stage codespace) -o {self.model}"
        )
        self.record.finish("train", key, t.seconds, {"epochs": epochs, "command": command})
