"""hrr-make's plan sized to a budget: how many frames to simulate, how long to train, and what each
stage should take, from what the run's first minutes measured on this machine.

    start = MeasuredStart({"body": 2, "motions": 40, "probe": 230}, 8.1, simulated_frames=1700)
    plan = plan_budget(3600, start, test_frames=960, clips=2, shares=BudgetShares())
    plan.sim_frames, plan.autoencoder_minutes, plan.estimates   # what to do, and the seconds expected

The budget pays, in order: what is already spent (the body fit, the motion library's features, the
simulator's first compile and the probe that measured its rate), the outputs after training (the
ONNX graph, the character's clips, the preview, the report with its truth ensembles), the fixed part
of training (the code space's contact phase, calibrations), and then what is left is divided between
simulating frames and training on them (:class:`BudgetShares`). The simulation's rate is measured;
the training stages run for their minutes (a cosine schedule over the minutes, as many epochs as
they hold here), so their estimate is their budget.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

OUTPUT_STAGES = ("onnx", "clips", "report")  # the stages after training, each of which may be skipped


class BudgetTooSmall(ValueError):
    """The budget does not cover the fixed costs and a minimal model."""


@dataclass(frozen=True)
class BudgetShares:
    """How hrr-make divides its budget, and the costs it expects of the stages it does not measure
    (seconds measured on a 2-core Xeon with the quick dress; each stage's actual time is recorded
    beside its estimate in make.json, so the next plan can be checked)."""

    # of the time left for data and training, the simulation's share; the full real-quick-commercial
    # recipe spends about as long simulating (27 min) as training (27 min) on 2 cores
    simulate: float = 0.5
    # of the training minutes, the autoencoder's: real-quick-commercial's full recipe gave it 13 min
    # (7 epochs) and the code space 7 (27 epochs) and 1.5 min of contact phase: about 0.6
    autoencoder: float = 0.6
    # validation frames per training frame (the preset's val 0.1 of the clips)
    validation: float = 0.12
    # truth-ensemble members per held-out sequence in the report (hrr-eval --ensemble)
    ensemble: int = 4
    # per simulated frame: encoding it with the autoencoder and the code space's data and database
    train_s_per_frame: float = 0.004
    # per validation frame: the auto mode's calibration, 22 candidate modes and 5 swing gains played
    # over the validation clips with the push-out (about 800 s for 4,240 frames on a character with
    # its own mesh, 2 cores: the second measured run, which the old fixed 240 s took 13 minutes over)
    calibration_s_per_val_frame: float = 0.19
    # training's fixed cost: the code space's contact phase and the gate's calibration
    train_fixed_s: float = 120.0
    # the ONNX graph for the character's body, its push-out against the capsules (72 s for a
    # 1,028-vertex dress on a 615-vertex body) ...
    onnx_s: float = 90.0
    # ... or against the character's own mesh, the graph then holding the mesh's collider (137 s for
    # that dress on that body, the export and its check, 2-core AMD EPYC, 2026-12-07; 182 s before
    # the strict trace first and the collider's steps as a loop)
    onnx_mesh_s: float = 140.0
    # each of the character's clips: animated, exported with the character, and the preview (4 s each
    # for 4 to 12 s clips)
    clip_s: float = 10.0
    # the report's inference over the held-out frames, besides simulating their truth ensembles ...
    report_s_per_frame: float = 0.01
    # ... or, on a character with a mesh of its own, with the cloth inside that mesh measured exactly
    # on every frame (the skin posed and the C kernel's count): the model's, before and after the
    # push-out (about 29 s for 960 held-out frames of a 1,046-vertex dress on a 615-vertex body), and
    # each truth member's (about 15 s for their 3,840 frames; hrr-eval of the report, its ensembles
    # cached, 47 s in all, 2-core AMD EPYC, 2026-12-07)
    report_mesh_s_per_frame: float = 0.03
    report_mesh_s_per_member_frame: float = 0.004
    # the least training a budget may leave, both stages together: less learns nothing worth shipping
    min_train_s: float = 120.0

    def to_dict(self) -> dict:
        return asdict(self)

    def report_frame_s(self, mesh: bool) -> float:
        """The report's seconds per held-out frame beyond simulating its truth: inference, and on a
        character with a mesh (``mesh``) the cloth inside it measured on the model's frames and on
        each of the ``ensemble`` truth members'."""
        if not mesh:
            return self.report_s_per_frame
        return self.report_mesh_s_per_frame + self.ensemble * self.report_mesh_s_per_member_frame

    def per_frame_s(self) -> float:
        """Training's seconds per simulated frame beyond its minutes: encoding it, and calibrating
        on it where it validates (``validation`` of every ``1 + validation`` frames)."""
        return self.train_s_per_frame + self.calibration_s_per_val_frame * self.validation / (
            1 + self.validation
        )

    def beyond_minutes_s(self, frames: int) -> float:
        """What the training stage costs beyond its two stages' minutes on ``frames`` simulated
        frames: its fixed part, and encoding and calibrating on every frame."""
        return self.train_fixed_s + frames * self.per_frame_s()


@dataclass(frozen=True)
class BudgetPlan:
    """What the budget buys: frames to simulate (mirrors included), minutes of each training stage,
    and every stage's expected seconds (``estimates``, in run order, spent stages as measured)."""

    budget_s: float
    sim_frames: int
    autoencoder_minutes: float
    codespace_minutes: float
    estimates: dict[str, float]
    sim_frames_per_s: float = 0.0  # the simulator's rate the plan assumed, in data frames

    @property
    def total_s(self) -> float:
        return float(sum(self.estimates.values()))

    def to_dict(self) -> dict:
        return {**asdict(self), "total_s": self.total_s}


@dataclass(frozen=True)
class MeasuredStart:
    """What the first minutes measured: seconds already spent per stage (run order), the simulator's
    rate (frames a second, every worker together) and the frames the probe simulated (kept: they are
    part of the data, and their time is spent already)."""

    spent: dict[str, float]
    sim_frames_per_s: float
    simulated_frames: int = 0


def plan_budget(
    budget_s: float,
    start: MeasuredStart,
    *,
    test_frames: int,
    clips: int,
    shares: BudgetShares,
    outputs: tuple[str, ...] = OUTPUT_STAGES,
    mesh: bool = False,
) -> BudgetPlan:
    """The plan for ``budget_s`` seconds in all (see the module docstring). ``test_frames``: the held-out
    frames the report scores (simulated as part of the data, then ``shares.ensemble`` times more for
    their truth); ``clips``: the character's clips the outputs animate; ``outputs``: the output
    stages made (the others are not paid for); ``mesh``: whether the character has a mesh of its own,
    which its ONNX graph pushes the cloth out of and its report measures the cloth inside."""
    rate = start.sim_frames_per_s
    if rate <= 0:
        raise ValueError("the simulator's measured rate must be positive")
    costs = {
        "onnx": shares.onnx_mesh_s if mesh else shares.onnx_s,
        "clips": shares.clip_s * clips,
        "report": test_frames * (shares.ensemble / rate + shares.report_frame_s(mesh)),
    }
    outputs = {stage: costs[stage] for stage in outputs}
    left = budget_s - sum(start.spent.values()) - sum(outputs.values()) - shares.train_fixed_s
    # left = new frames / rate (simulate) + every frame * per_frame (encode, calibrate on its share of
    # validation) + minutes (train): the simulation's share of it goes to the frames beyond the
    # probe's and to what every frame costs after training
    sim_s = shares.simulate * left
    already = start.simulated_frames
    per_frame = shares.per_frame_s()
    new = int((sim_s - already * per_frame) / (1.0 / rate + per_frame))
    frames = already + max(new, 0)
    train_s = left - sim_s
    if new <= 0 or train_s < shares.min_train_s:
        raise BudgetTooSmall(
            f"a budget of {budget_s / 60:.0f} min leaves {max(left, 0) / 60:.1f} min for simulating and "
            f"training once the fixed costs are paid ({sum(start.spent.values()) / 60:.1f} min spent, "
            f"{sum(outputs.values()) / 60:.1f} min of outputs, {shares.train_fixed_s / 60:.1f} min of "
            "calibration): give a larger --budget"
        )
    ae_min = shares.autoencoder * train_s / 60
    cs_min = train_s / 60 - ae_min
    estimates = {
        **start.spent,
        "simulate": new / rate,
        "train": train_s + shares.beyond_minutes_s(frames),
        **outputs,
    }
    return BudgetPlan(float(budget_s), frames, round(ae_min, 2), round(cs_min, 2), estimates, rate)


def training_minutes(plan: dict, elapsed_s: float, shares: BudgetShares) -> dict:
    """The training's minutes once the simulation has ended (``plan``: :meth:`BudgetPlan.to_dict`,
    ``elapsed_s``: the run's time so far): what the budget has left after the outputs' estimates and
    the training's fixed part, in the autoencoder's share, at least ``shares.min_train_s`` in all. A
    simulation quicker than its estimate (the probe's clips are not the plan's) gives its time to
    training, a slower one takes it, so that the run ends near its budget."""
    after = sum(plan["estimates"].get(stage, 0.0) for stage in OUTPUT_STAGES)
    beyond = shares.beyond_minutes_s(plan["sim_frames"])
    train_s = max(plan["budget_s"] - elapsed_s - after - beyond, shares.min_train_s)
    autoencoder = round(shares.autoencoder * train_s / 60, 2)
    return {"autoencoder_minutes": autoencoder, "codespace_minutes": round(train_s / 60 - autoencoder, 2)}


def training_estimate_s(minutes: dict, plan: dict, shares: BudgetShares) -> float:
    """The training stage's seconds with ``minutes`` (:func:`training_minutes`) for ``plan``'s frames:
    the two stages' minutes and what it costs beyond them (:meth:`BudgetShares.beyond_minutes_s`)."""
    minutes_s = 60 * (minutes["autoencoder_minutes"] + minutes["codespace_minutes"])
    return minutes_s + shares.beyond_minutes_s(plan["sim_frames"])


def train_config(plan: dict, device: str | None = None) -> dict:
    """The training settings a plan (:meth:`BudgetPlan.to_dict`) adds to its preset's: each stage for
    its minutes (epochs unbounded: the minutes end it, the cosine schedule spans them); on a CUDA
    ``device`` the autoencoder there, as ``hrr-train --device`` puts it."""
    from ..train.loop import ENDLESS_EPOCHS  # torch: not for hrr-make --help, which reads this module

    autoencoder = {"epochs": ENDLESS_EPOCHS, "max_minutes": plan["autoencoder_minutes"]}
    if (device or "").startswith("cuda"):
        autoencoder["device"] = device.split(":")[0]
    return {
        "autoencoder": {"train": autoencoder},
        "codespace": {"train": {"epochs": ENDLESS_EPOCHS, "max_minutes": plan["codespace_minutes"]}},
    }


def take_prefix(order: list[str], frames: dict[str, int], wanted: int, at_least: int = 1) -> list[str]:
    """The first sequences of ``order`` whose frames reach ``wanted`` (at least ``at_least`` of them,
    all of them where the order holds fewer frames)."""
    taken, total = [], 0
    for name in order:
        if total >= wanted and len(taken) >= at_least:
            break
        taken.append(name)
        total += frames[name]
    return taken


def parse_budget(text: str) -> float:
    """A budget as the command line gives it (``60m``, ``2h``, ``90`` minutes, ``1h30m``) in seconds."""
    import re

    value = text.strip().lower()
    match = re.fullmatch(r"(?:(\d+(?:\.\d+)?)h)?(?:(\d+(?:\.\d+)?)m?)?", value)
    if not value or match is None or not any(match.groups()):
        raise ValueError(f"{text!r} is not a budget: write it as 60m, 2h, 1h30m or minutes")
    hours, minutes = (float(g) if g else 0.0 for g in match.groups())
    seconds = 3600 * hours + 60 * minutes
    if seconds <= 0:
        raise ValueError(f"{text!r}: a budget must be longer than nothing")
    return seconds
