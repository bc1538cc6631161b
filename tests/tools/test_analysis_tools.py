"""The analysis tools (tools/studies/*_analysis.py) on the tiny trained model."""

from __future__ import annotations

import pytest

from tests.scripts import load_script

pytestmark = pytest.mark.tool


def test_gate_analysis_oracle_bounds_both_modes(trained):

    tool = load_script("tools/studies/gate_analysis.py")
    root, data, _ = trained
    r = tool.analyse(str(root / "model"), str(data), "val")
    # each window takes its better candidate: never worse than either mode alone
    assert r["oracle_hybrid_mm"] <= min(r["regression_mm"], r["retrieval_mm"]) + 1e-9
    assert 0.0 <= r["retrieval_better_fraction"] <= 1.0 and r["windows"] > 0
    corr = [r[f"corr_advantage_low_{g}_doubt"] for g in ("entropy", "similarity", "distance")]
    assert all(
        -1.0 <= c <= 1.0 or c != c for c in corr
    )  # a correlation per gate (NaN where a signal is constant)


def test_residual_nodes_analysis_spans_regression_to_residual(trained, tmp_path):
    """A ramp below every node's hang is the residual mode as it is, one above every node's the
    regression (through the residual mode's path): the variants sit between known ends."""
    import dataclasses
    import shutil

    from hrr_garment.artifacts.typed_manifest import read_manifest, update_manifest

    tool = load_script("tools/studies/residual_nodes_analysis.py")
    root, data, _ = trained
    model = (
        tmp_path / "model"
    )  # with a residual weight, so that the residual mode differs from the regression
    shutil.copytree(root / "model", model)
    residual = read_manifest(model).residual
    update_manifest(model, residual=dataclasses.replace(residual, weight=0.7))
    rows = {
        r["label"]: r
        for r in tool.analyse(str(model), str(data), [(-2000.0, -1000.0), (1000.0, 2000.0)], sequences=2)
    }
    assert rows["residual"]["pve_mm"] != rows["regression"]["pve_mm"]
    simulation = rows["simulation"]  # the clips' own simulations: no error, all their swing
    assert simulation["pve_mm"] == 0.0 and simulation["hem_swing_ratio"] == pytest.approx(1.0)
    for row in rows.values():  # the capsules share out the vertices inside, each counted once
        assert sum(row["inside_by_capsule_pct"].values()) == pytest.approx(row["inside_pct"], abs=1e-9)
    every, none = rows["residual, nodes -2000--1000 mm"], rows["residual, nodes 1000-2000 mm"]
    assert every["mean_weight"] == 1.0 and none["mean_weight"] == 0.0
    for key in ("inside_pct", "hem_swing_ratio", "pve_mm"):
        assert every[key] == rows["residual"][key]
        assert abs(none[key] - rows["regression"][key]) < 1e-3 * max(1.0, abs(rows["regression"][key]))
