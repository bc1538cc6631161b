"""hrr-make's plan (hrr_garment.pipeline.make_budget): the stages' estimates add up to the budget, the
simulation gets its share at the measured rate, a budget too small is refused, budgets parse."""

import pytest

from hrr_garment.pipeline.make_budget import (
    BudgetShares,
    BudgetTooSmall,
    MeasuredStart,
    parse_budget,
    plan_budget,
    take_prefix,
    training_estimate_s,
    training_minutes,
)

START = MeasuredStart({"body": 5.0, "motions": 20.0, "probe": 120.0}, sim_frames_per_s=40.0)


def test_the_estimates_fill_the_budget():
    shares = BudgetShares()
    plan = plan_budget(3600, START, test_frames=1800, clips=2, shares=shares)
    assert plan.total_s == pytest.approx(3600, abs=1.0)  # up to a frame's rounding
    assert list(plan.estimates)[:3] == ["body", "motions", "probe"]  # the spent stages as measured
    assert plan.estimates["probe"] == 120.0
    # the simulation's share of what is left buys frames at the measured rate, with their encoding
    left = 3600 - 145 - plan.estimates["onnx"] - plan.estimates["clips"] - plan.estimates["report"]
    left -= shares.train_fixed_s
    assert plan.sim_frames * (1 / 40 + shares.per_frame_s()) == pytest.approx(shares.simulate * left, abs=1)
    assert plan.autoencoder_minutes / (plan.autoencoder_minutes + plan.codespace_minutes) == pytest.approx(
        shares.autoencoder, abs=0.01
    )


def test_a_character_with_its_own_mesh_pays_for_its_longer_export_and_report():
    """The graph of a character with a mesh holds the mesh's collider and exports for longer, and its
    report measures the cloth inside that mesh on every frame of the model and of the truth: its
    plan holds that time and still fills the budget, with less left for the data."""
    shares = BudgetShares()
    capsules = plan_budget(3600, START, test_frames=960, clips=1, shares=shares)
    mesh = plan_budget(3600, START, test_frames=960, clips=1, shares=shares, mesh=True)
    assert capsules.estimates["onnx"] == shares.onnx_s and mesh.estimates["onnx"] == shares.onnx_mesh_s
    # the model's frames measured, and each of the truth members' frames
    measured = shares.report_mesh_s_per_frame + shares.ensemble * shares.report_mesh_s_per_member_frame
    assert mesh.estimates["report"] - capsules.estimates["report"] == pytest.approx(
        960 * (measured - shares.report_s_per_frame)
    )
    assert mesh.total_s == pytest.approx(3600, abs=1.0)
    assert mesh.sim_frames < capsules.sim_frames


def test_a_faster_simulator_buys_more_frames_and_the_same_training():
    slow = plan_budget(3600, START, test_frames=0, clips=1, shares=BudgetShares())
    fast = plan_budget(3600, MeasuredStart(START.spent, 80.0), test_frames=0, clips=1, shares=BudgetShares())
    per_frame = BudgetShares().per_frame_s()  # what every frame costs after training, whatever the rate
    assert fast.sim_frames / slow.sim_frames == pytest.approx(
        (1 / 40 + per_frame) / (1 / 80 + per_frame), rel=1e-3
    )
    assert fast.autoencoder_minutes == slow.autoencoder_minutes


def test_the_probes_frames_are_data_already_paid_for():
    """The probe's frames are in the data and their time is spent: the plan simulates only the rest
    and still fills the budget."""
    fresh = plan_budget(3600, START, test_frames=0, clips=1, shares=BudgetShares())
    probed = MeasuredStart(START.spent, START.sim_frames_per_s, simulated_frames=1000)
    kept = plan_budget(3600, probed, test_frames=0, clips=1, shares=BudgetShares())
    assert kept.sim_frames > fresh.sim_frames  # the probe's 1,000 frames beside what the share buys
    assert kept.estimates["simulate"] < fresh.estimates["simulate"]
    assert kept.total_s == pytest.approx(3600, abs=1.0)


def test_training_takes_what_the_simulation_left():
    """After the simulation, training gets what the budget has left: more when the simulation was
    quicker than planned, less when slower, never under the least, in the autoencoder's share."""
    shares = BudgetShares()
    plan = plan_budget(3600, START, test_frames=1800, clips=2, shares=shares).to_dict()
    simulated_at = sum(plan["estimates"][s] for s in ("body", "motions", "probe", "simulate"))
    on_time = training_minutes(plan, simulated_at, shares)
    assert on_time["autoencoder_minutes"] == pytest.approx(plan["autoencoder_minutes"], abs=0.02)
    assert on_time["codespace_minutes"] == pytest.approx(plan["codespace_minutes"], abs=0.02)
    # the stage's estimate with them is the plan's: the time left shown from then on adds up
    assert training_estimate_s(on_time, plan, shares) == pytest.approx(plan["estimates"]["train"], abs=2.0)
    early = training_minutes(plan, simulated_at - 300, shares)
    assert sum(early.values()) == pytest.approx(sum(on_time.values()) + 5, abs=0.02)
    late = training_minutes(plan, 3600, shares)
    assert sum(late.values()) == pytest.approx(shares.min_train_s / 60, abs=0.02)


def test_the_report_is_paid_for():
    plain = plan_budget(3600, START, test_frames=0, clips=1, shares=BudgetShares())
    reported = plan_budget(3600, START, test_frames=4000, clips=1, shares=BudgetShares())
    assert reported.estimates["report"] == pytest.approx(4000 * (4 / 40 + 0.01))
    assert reported.sim_frames < plain.sim_frames


def test_a_budget_under_the_fixed_costs_is_refused():
    with pytest.raises(BudgetTooSmall, match="give a larger --budget"):
        plan_budget(600, START, test_frames=1800, clips=2, shares=BudgetShares())


@pytest.mark.parametrize(
    ("text", "seconds"), [("60m", 3600), ("2h", 7200), ("1h30m", 5400), ("90", 5400), ("0.5h", 1800)]
)
def test_budgets_parse(text, seconds):
    assert parse_budget(text) == seconds


@pytest.mark.parametrize("text", ["", "soon", "0m", "-5m", "1d"])
def test_bad_budgets_are_refused(text):
    with pytest.raises(ValueError):
        parse_budget(text)


def test_a_prefix_reaches_its_frames():
    frames = {"a": 100, "b": 50, "c": 80}
    assert take_prefix(["a", "b", "c"], frames, 120) == ["a", "b"]
    assert take_prefix(["a", "b", "c"], frames, 100) == ["a"]
    assert take_prefix(["a", "b", "c"], frames, 0, at_least=2) == ["a", "b"]
    assert take_prefix(["a", "b", "c"], frames, 10_000) == ["a", "b", "c"]
