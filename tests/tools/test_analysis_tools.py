"""The analysis tools (tools/*_analysis.py) on the tiny trained model."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.tool


def test_gate_analysis_oracle_bounds_both_modes(trained):
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location("gate_analysis", Path(__file__).parents[2] / "tools" / "gate_analysis.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    root, data, _ = trained
    r = tool.analyse(str(root / "model"), str(data), "val")
    # each window takes its better candidate: never worse than either mode alone
    assert r["oracle_hybrid_mm"] <= min(r["regression_mm"], r["retrieval_mm"]) + 1e-9
    assert 0.0 <= r["retrieval_better_fraction"] <= 1.0 and r["windows"] > 0
    corr = [r[f"corr_advantage_low_{g}_doubt"] for g in ("entropy", "similarity", "distance")]
    assert all(-1.0 <= c <= 1.0 or c != c for c in corr)  # a correlation per gate (NaN where a signal is constant)
