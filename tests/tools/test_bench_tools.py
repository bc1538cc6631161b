"""The benchmark tools (tools/bench_*.py): their reports keep the keys they promise."""

import pytest

from tests.scripts import load_script

pytestmark = pytest.mark.tool


@pytest.mark.slow
def test_bench_inference_reports_every_key(capsys, monkeypatch):
    """The benchmark's JSON keeps the keys the issue names (speeds are measured there, not here)."""
    import json
    import sys
    from pathlib import Path

    path = Path(__file__).parents[2] / "tools" / "bench_inference.py"
    monkeypatch.syspath_prepend(str(path.parent))  # its sibling tools/machine.py, as a script finds it
    bench = load_script(path)
    argv = sys.argv
    sys.argv = [
        str(path),
        "--vertices",
        "300",
        "--database",
        "300",
        "--seconds",
        "1.5",
        "--pace",
        "60",
        "--json",
        "--crowd",
        "3",
        "--crowd-frames",
        "25",
        "--crowd-bodies",
        "--crowd-repeat",
        "1",
    ]
    try:
        bench.main()
    finally:
        sys.argv = argv
    report = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in (
        "vertices",
        "fps_hybrid",
        "fps_regression",
        "fps_retrieval",
        "fps_detail",
        "stream_p50_ms",
        "stream_p99_ms",
        "stream_paced_p50_ms",
        "stream_paced_p99_ms",
        "peak_rss_mb",
    ):
        assert report[key] > 0, key
    assert report["stream_p50_ms"] <= report["stream_p99_ms"]
    assert set(report["stream_stage_p50_ms"]) == {"features", "encoder", "decoder", "world", "push_out"}
    bodies = report["crowd_bodies"]["3"]  # three characters on three bodies, against one body for all
    assert bodies["p99_ratio_median"] > 0 and len(bodies["bodies"]) == len(bodies["one_body"]) == 1
    assert bodies["bodies_from"] == "scaled" and bodies["bodies"][0]["push_out_p50_ms"] > 0
    # the budget on any machine: the reference timed in the same run, each step also as its multiple
    crowd = report["crowd"]["3"]
    assert report["reference_ms"] > 0 and report["reference_spread_ms"][0] <= report["reference_ms"]
    assert crowd["p99_x"] == pytest.approx(crowd["p99_ms"] / report["reference_ms"], abs=1e-3)
    assert "cores" in report["cpu"]


def test_the_push_out_analysis_reports_each_setting_with_and_without_the_subspace_push(trained):
    """tools/studies/push_out_analysis.py on the tiny trained model: every row keeps its keys, and the push
    in the fast decoder's subspace leaves no more of the cloth inside the body than the decoder did."""

    tool = load_script("tools/studies/push_out_analysis.py")
    root, data, _ = trained
    report = tool.analyse(
        str(root / "model"),
        str(data),
        "test",
        tool.push_out_rows([0], 0.25, [0.1]),
        sequences=1,
        timing=(8, 1),
        asked=tool.Asked(mode="regression", subspace_push=True),
    )
    assert report["mode"] == "regression" and report["body"] == "capsules"
    plain, pushed = (
        report["rows"]["follow 0, slack 0.1"],
        report["rows"]["follow 0, slack 0.1, subspace push"],
    )
    for row in (plain, pushed):
        assert set(row) >= {
            "limited_frames_pct",
            "torn_before_limit_pct",
            "strain_max",
            "inside_before_pct",
            "inside_after_pct",
            "pve_mm",
            "us_per_character",
        }
        assert row["pve_mm"] > 0 and row["us_per_character"] > 0
    assert pushed["inside_before_pct"] <= plain["inside_before_pct"]
    assert report["rows"]["unpushed"]["pve_mm"] > 0
    # the first setting on the simulation itself: pushed out, never timed, inside no deeper after
    truth = report["rows"]["simulation, pushed"]
    assert truth["us_per_character"] is None and truth["inside_after_pct"] <= truth["inside_before_pct"]
    with pytest.raises(SystemExit, match="no mesh of its own"):  # the tiny model's body is the mannequin
        tool.analyse(str(root / "model"), str(data), "test", tool.push_out_rows([0], 0.25, [0.1]), 1, (8, 1),
                     tool.Asked(visible=True))  # fmt: skip


def test_bodies_inside_counts_the_cloth_inside_each_body_before_the_push_out(trained, tmp_path, monkeypatch):
    """tools/studies/bodies_inside.py on the tiny trained model: a body file holding the model's own body
    gives what animating on the default body and measuring directly gives; scaled mannequins away
    from the one training body are listed with the measures out of its range."""
    from pathlib import Path

    from hrr_garment.body.body_file import write_body
    from hrr_garment.eval.inside_body import check_motion
    from hrr_garment.inference.animator import Animator
    from hrr_garment.sim.quality import body_signed_distance, penetration_fraction

    tools = Path(__file__).parents[2] / "tools"
    monkeypatch.syspath_prepend(str(tools))  # the tool imports bench_inference's bodies from tools/
    tool = load_script(tools / "studies" / "bodies_inside.py")
    root, _, _ = trained
    animator = Animator.load(root / "model")
    own = write_body(tmp_path / "own.json", animator.bundle.default_body)
    report = tool.analyse(str(root / "model"), ["scaled", str(own)], [], count=3)
    rows = report["rows"]
    assert [r["body_name"].split(" (")[0] for r in rows] == ["scaled 0", "scaled 1", "scaled 2", "own"]
    motion = check_motion()  # the walk the tool runs when given no clip
    distance = body_signed_distance(
        animator.animate(motion, push_out=False).vertices, motion, animator.body().body
    )
    assert rows[3]["inside_pct"] == pytest.approx(100 * penetration_fraction(distance).mean(), abs=1e-9)
    assert rows[3]["inside_any_pct"] == pytest.approx(100 * (distance < 0).mean(), abs=1e-9)
    assert rows[3]["outside_range"] == [] and rows[0]["outside_range"] and rows[2]["outside_range"]
    for r in rows:
        assert 0 <= r["inside_pct"] <= r["inside_worst_pct"] <= 100 and r["inside_pct"] <= r["inside_any_pct"]


@pytest.mark.slow
def test_bench_ab_times_two_checkouts_pass_by_pass_and_refuses_what_is_no_checkout(tmp_path):
    """The checkout against itself, two pairs of one workload: a row with both medians and a ratio
    within its own interval (no speed is asserted: a pass is 0.1 s on a shared machine); a folder
    that is no checkout is refused by name."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).parents[2]
    tool = [sys.executable, str(root / "tools" / "bench_ab.py")]
    done = subprocess.run(
        tool + [str(root), str(root), "--pairs", "2", "--workloads", "hybrid"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    row = re.search(r"\| hybrid \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+)-([\d.]+) \|", done.stdout)
    assert row, done.stdout
    a, b, ratio, lo, hi = map(float, row.groups())
    # the ratio itself is a timing: on two shared cores beside the other test worker it has come out
    # at 2.1 for the same code, so the test holds the row's consistency, not a speed
    assert a > 0 and b > 0 and lo <= ratio <= hi
    refused = subprocess.run(tool + [str(tmp_path), str(root)], capture_output=True, text=True)
    assert refused.returncode != 0 and f"{tmp_path}: not a checkout" in refused.stderr
