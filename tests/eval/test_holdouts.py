"""The test split taken apart by hold-out: pooled as the whole split is, worst clip, every clip."""

import pytest

from hrr_garment.eval.ensemble_metrics import ensemble_ratios
from hrr_garment.eval.holdouts import holdout_section, markdown_holdouts
from hrr_garment.eval.mode_results import combine


def _entry(rows):
    return {
        "sequences": {
            n: {"frames": f, "ensemble": {"pve_members_mm": p, "floor_mm": fl, "pve_floor_ratio": p / fl}}
            for n, f, p, fl in rows
        }
    }


def test_each_holdout_is_pooled_as_the_split_is_and_names_its_worst_clip():
    rows = [
        ("a_style", 100, 30.0, 20.0),
        ("b_style", 50, 50.0, 20.0),
        ("c_content", 80, 44.0, 22.0),
        ("d_content", 20, 60.0, 20.0),
    ]
    holdouts = {"a_style": "style", "b_style": "style", "c_content": "content", "d_content": "content"}
    section = holdout_section({"auto": _entry(rows), "regression": _entry(rows[:2])}, holdouts)
    content = section["by_holdout"]["content"]["auto"]
    pooled = ensemble_ratios(
        combine(
            [{"pve_members_mm": 44.0, "floor_mm": 22.0}, {"pve_members_mm": 60.0, "floor_mm": 20.0}], [80, 20]
        )
    )
    assert content["pve_floor_ratio"] == pytest.approx(pooled["pve_floor_ratio"])
    assert content["pve_floor_ratio"] == pytest.approx((0.8 * 44 + 0.2 * 60) / (0.8 * 22 + 0.2 * 20))
    assert content["worst"] == {"sequence": "d_content", "pve_floor_ratio": 3.0}
    assert content["sequences"] == 2 and content["frames"] == 100
    assert "content" not in {
        k for k, v in section["by_holdout"].items() if "regression" in v
    }  # no content clip ran
    assert section["sequences"]["b_style"] == {"holdout": "style", "auto": 2.5, "regression": 2.5}
    assert list(section["by_holdout"]) == ["style", "content"]  # the split's own hold-out first
    table = "\n".join(markdown_holdouts(section))
    style = section["by_holdout"]["style"]["auto"]["pve_floor_ratio"]
    assert (
        f"| held-out contents | auto | 2 | 100 | {content['pve_floor_ratio']:.2f} | "
        f"{content['pve_floor_ratio'] / style:.3f} |" in table
    )


def test_one_holdout_or_no_ensembles_leave_no_section():
    rows = [("a", 10, 30.0, 20.0), ("b", 10, 40.0, 20.0)]
    assert holdout_section({"auto": _entry(rows)}, {"a": "style", "b": "style"}) is None
    bare = {"auto": {"sequences": {"a": {"frames": 10}, "b": {"frames": 10}}}}
    assert holdout_section(bare, {"a": "style", "b": "content"}) is None


def test_the_test_split_by_cloth_pools_each_cloth_against_its_own_floor():
    from hrr_garment.eval.holdouts import markdown_cloths

    rows = [("a", 100, 30.0, 20.0), ("b", 50, 50.0, 25.0), ("c", 80, 44.0, 22.0)]
    section = holdout_section({"auto": _entry(rows)}, {"a": "jersey", "b": "jersey", "c": "denim"})
    jersey = section["by_holdout"]["jersey"]["auto"]
    assert jersey["pve_floor_ratio"] == pytest.approx((100 * 30 + 50 * 50) / (100 * 20 + 50 * 25))
    table = "\n".join(markdown_cloths(section))
    assert f"| jersey | auto | 2 | 150 | {jersey['pve_floor_ratio']:.2f} | n/a | n/a | b (2.00) |" in table
    assert "| denim | auto | 1 | 80 | 2.00 |" in table
    assert markdown_cloths(None) == []
