"""The default output's bars: each one's value, target and mark from a protocol's mode entries."""

import pytest

from hrr_garment.eval.bars import HELD_OUT_BARS, LIBRARY_BARS, default_output, markdown_lead, summary_line


def _entry(pve_floor, members, energy, sharpness, swing, jitter, pen, strain_max):
    return {
        "metrics": {"strain_max": strain_max},
        "ensemble": {
            "pve_floor_ratio": pve_floor,
            "pve_members_mm": members,
            "energy_score_mm": energy,
            "bending_energy_ratio": sharpness,
            "hem_swing_ratio": swing,
            "jitter_ratio": jitter,
            "inside_visible_before_pct": pen,
            "inside_visible_pct": 0.1,
        },
    }


def test_the_default_output_is_held_to_each_bar_and_to_the_regression_beside_it():
    modes = {
        "auto": _entry(1.42, 35.0, 25.0, 0.90, 0.80, 1.05, 3.5, 1.7),
        "regression": _entry(1.35, 34.0, 24.0, 0.10, 0.60, 0.97, 2.5, 1.6),
    }
    held = default_output(modes, HELD_OUT_BARS)["bars"]
    assert held["PVE / floor"] == {"value": 1.42, "target": 1.5, "bar": "<= 1.5", "met": True}
    assert (
        held["PVE vs regression"]["target"] == pytest.approx(1.05 * 34.0) and held["PVE vs regression"]["met"]
    )
    assert (
        not held["inside seen before push-out %"]["met"]
        and held["inside seen after push-out %"]["met"]
        and held["strain max"]["met"]
        and held["jitter ratio"]["met"]
    )
    assert held["sharpness"]["met"] and not held["hem swing"]["met"]  # 0.80 < 0.85: at least, not at most
    library = default_output(modes, LIBRARY_BARS)
    assert library["bars"]["energy score vs regression"] == {
        "value": 25.0,
        "target": 24.0,
        "bar": "<= 1 x the regression's",
        "met": False,
    }
    assert library["values"]["energy_score_mm"] == 25.0
    lead = "\n".join(markdown_lead(library, "detail"))
    assert (
        "| auto | 1.42 | 25.00 | 0.90 | 0.80 | 1.05 |" in lead
        and "| hem swing | 0.80 | >= 0.85 | **no** |" in lead
    )
    assert "energy score vs regression 25 (<= 1 x the regression's: NOT met)" in summary_line(library)


def test_what_cannot_be_said_is_said_so():
    auto = _entry(1.2, 30.0, 20.0, 0.9, 0.9, 1.0, 1.0, 1.5)
    alone = default_output({"auto": auto}, HELD_OUT_BARS)["bars"]  # no regression evaluated beside it
    assert alone["PVE vs regression"]["target"] is None and alone["PVE vs regression"]["met"] is None
    assert alone["PVE / floor"]["met"]
    assert default_output({"regression": auto}, HELD_OUT_BARS) is None  # auto not evaluated
    assert (
        default_output({"auto": {"metrics": {}, "ensemble": {}}}, HELD_OUT_BARS) is None
    )  # no truth ensembles
    assert summary_line(None) is None and markdown_lead(None, "hybrid") == []
