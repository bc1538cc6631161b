"""tools/studies/settle_study.py: the hem's settling after a stop, against known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrr_garment.motion.synth import synthesize
from tests.scripts import load_script

pytestmark = pytest.mark.tool

FPS = 30.0


def _tool():
    return load_script("tools/studies/settle_study.py")


def _decaying_hem(seconds: float, start_m: float, tau_s: float) -> np.ndarray:
    """(T, 8, 3): eight hem points displaced sideways by start_m * exp(-t / tau_s) from where they rest."""
    t = np.arange(round(seconds * FPS)) / FPS
    rest = np.stack(
        [np.cos(np.linspace(0, 2 * np.pi, 8)), np.zeros(8), np.sin(np.linspace(0, 2 * np.pi, 8))], 1
    )
    offset = start_m * np.exp(-t / tau_s)
    return rest[None] + offset[:, None, None] * np.array([1.0, 0.0, 0.0])


def test_settle_time_of_an_exponential_decay():
    tool = _tool()
    hem = _decaying_hem(8.0, 0.05, 0.5)
    away = tool.away_from_rest(hem, FPS, smooth_s=1 / FPS)  # unsmoothed
    # 50 mm decaying with a 0.5 s time constant passes 10 mm at 0.5 ln 5 = 0.80 s
    assert tool.settle_time(away, FPS, 0.010) == pytest.approx(0.5 * math.log(5.0), abs=1.5 / FPS)
    # a hem that never comes within 1 mm before the last second has not settled
    assert tool.settle_time(tool.away_from_rest(_decaying_hem(3.0, 0.05, 5.0), FPS, 0.5), FPS, 0.001) is None
    # one that never leaves is settled from the start
    assert tool.settle_time(np.zeros(90), FPS, 0.010) == 0.0


def test_the_curve_gap_tells_a_ringing_hem_from_a_creeping_one():
    """Two hems that settle (within 10 mm) at the same time: one closes on its place smoothly, the
    other swings back out; the gap between their curves says so, and is zero for a curve itself."""
    tool = _tool()
    t = np.arange(0, 8.0, 0.25)
    creep = 40.0 * np.exp(-t / 3.0)
    ringing = 40.0 * np.exp(-t / 3.0) * np.abs(np.cos(np.pi * t / 2.0))
    settle = [tool.settle_time(c / 1000.0, 4.0, 0.010) for c in (creep, ringing)]
    assert settle[0] == pytest.approx(settle[1], abs=0.5)
    assert tool.curve_gap(creep, creep) == 0.0
    assert (
        tool.curve_gap(creep, ringing) == pytest.approx(np.mean(creep - ringing))
        and tool.curve_gap(creep, ringing) > 5.0
    )


def test_smoothing_removes_a_jitter_about_the_resting_place():
    tool = _tool()
    hem = _decaying_hem(4.0, 0.0, 1.0)
    jitter = 0.004 * np.where(np.arange(len(hem)) % 2 == 0, 1.0, -1.0)  # 4 mm each frame, alternating
    hem[:, :, 1] += jitter[:, None]
    assert tool.away_from_rest(hem, FPS, 1 / FPS).mean() == pytest.approx(0.004, rel=0.05)
    assert tool.away_from_rest(hem, FPS, 0.5).max() < 0.004  # 0.5 s of positions averaged


def test_stopping_holds_the_last_frame():
    tool = _tool()
    motion = synthesize("walk", 2.0, seed=0)
    stopped = tool.stopping(motion, 1.0, 0.5)
    assert stopped.num_frames == 30 + 15
    np.testing.assert_array_equal(stopped.local_rotations[:30], motion.local_rotations[:30])
    np.testing.assert_array_equal(
        stopped.local_rotations[30:], np.repeat(motion.local_rotations[29:30], 15, 0)
    )
    np.testing.assert_array_equal(stopped.root_translation[-1], motion.root_translation[29])


def test_still_time_of_an_exponential_decay_and_of_a_creep():
    """The hem's speed (50 mm decaying with a 0.5 s time constant: 0.1 exp(-t / 0.5) m/s) falls
    under 2 cm/s at 0.5 ln 5 = 0.80 s; a creep at 1 cm/s is still from the start, though it comes
    within 10 mm of where it ends only a second before then."""
    tool = _tool()
    hem = _decaying_hem(8.0, 0.05, 0.5)
    assert tool.still_time(hem, FPS, 1 / FPS, 0.02) == pytest.approx(0.5 * math.log(5.0), abs=1.5 / FPS)
    creep = _decaying_hem(8.0, 0.0, 1.0)
    creep[:, :, 0] += 0.01 * np.arange(len(creep))[:, None] / FPS
    assert tool.still_time(creep, FPS, 0.5, 0.02) == 0.0
    # while its distance from where it ends (its mean over the last second, at 7.5 s) stays over
    # 10 mm until 6.5 s
    away = tool.away_from_rest(creep, FPS, 0.5)
    assert tool.settle_time(away, FPS, 0.010) == pytest.approx(6.5, abs=1.5 / FPS)
    assert tool.still_time(creep, FPS, 0.5, 0.005) is None


def test_the_members_mean_keeps_the_shared_settling_and_drops_the_chaotic():
    """Two members share a decay of 50 mm (0.5 s) and differ by a slow one of 40 mm (3 s) in
    opposite directions: each settles late, their mean as the shared decay alone (0.80 s)."""
    tool = _tool()
    motion = synthesize("walk", 9.0, seed=0)
    shared = _decaying_hem(8.0, 0.05, 0.5)
    t = np.arange(len(shared)) / FPS
    chaos = 0.04 * np.exp(-t / 3.0)[:, None, None] * np.array([0.0, 0.0, 1.0])
    # (30 + T, 16, 3): a second before the stop where the cloth stands as it is at the stop
    members = [np.repeat(shared + sign * chaos, 2, axis=1) for sign in (1.0, -1.0)]
    members = [np.concatenate([np.repeat(m[:1], 30, 0), m]) for m in members]
    hem = np.arange(16)

    class Args:
        near, smooth, still = 10.0, 1 / FPS, 0.02

    alone = [tool.hem_after_stop(m, motion, 30, hem, Args) for m in members]
    mean = tool.mean_member_after_stop(members, motion, 30, hem, Args)
    assert mean["settle_s"] == pytest.approx(0.5 * math.log(5.0), abs=1.5 / FPS)
    assert all(a["settle_s"] > 3.0 for a in alone)


def test_by_cloth_averages_each_cloth_over_the_clips():
    tool = _tool()

    def row(clip, cloth, truth, shared, model, swings, gap):
        members = [None, 5.0] if truth is None else [truth - 1.0, truth + 1.0]
        return {
            "clip": clip,
            "cloth": cloth,
            "truth": {"settle_s": truth, "hem_swing_cm": swings[0], "settle_s_members": members},
            "truth_mean": {"settle_s": shared},
            "model": {"settle_s": model, "hem_swing_cm": swings[1], "stand_pve_mm": gap + 20.0},
            "curve_gap_mm": gap,
        }

    rows = [
        row("a", "silk", 8.0, 6.0, 4.0, (10.0, 9.0), 2.0),
        row("b", "silk", 10.0, 8.0, 8.0, (20.0, 15.0), 4.0),
        row("a", "denim", None, 5.0, 3.0, (12.0, 12.0), 1.0),  # a truth that never settles
        row("b", "denim", 6.0, 5.0, 5.0, (8.0, 8.0), 3.0),
    ]
    summary = tool.by_cloth(rows)
    assert list(summary) == ["silk", "denim"]
    silk = summary["silk"]
    assert silk["clips"] == 2 and silk["settle_s"] == {"truth": 9.0, "members_mean": 7.0, "model": 6.0}
    assert silk["settle_ratio"] == pytest.approx(6.0 / 9.0)
    assert silk["settle_ratio_to_mean"] == pytest.approx(6.0 / 7.0)
    assert silk["hem_swing_ratio"] == pytest.approx(12.0 / 15.0)  # the ratio of the means
    assert silk["curve_gap_mm"] == pytest.approx(3.0)
    assert silk["stand_pve_mm"] == pytest.approx(23.0)
    # the members settle at 7 and 9 s, then 9 and 11: 8 and 10 s over the clips, each over the other
    assert silk["member_settle_ratios"] == pytest.approx([0.8, 1.25])
    assert summary["denim"]["member_settle_ratios"] is None  # a member that never settles
    denim = summary["denim"]
    assert denim["settle_s"]["truth"] is None and denim["settle_ratio"] is None
    assert denim["settle_ratio_to_mean"] == pytest.approx(1.0 / 1.25)


def test_a_members_settle_ratio_is_over_the_other_members_mean_over_the_clips():
    tool = _tool()
    rows = [{"truth": {"settle_s_members": m}} for m in ([6.0, 9.0, 12.0], [4.0, 9.0, 8.0])]
    # over the clips: 5, 9 and 10 s; each against the other two's mean over both clips
    assert tool.member_settle_ratios(rows) == pytest.approx([5.0 / 9.5, 9.0 / 7.5, 10.0 / 7.0])
    same = [{"truth": {"settle_s_members": [7.0, 7.0, 7.0, 7.0]}}]
    assert tool.member_settle_ratios(same) == pytest.approx([1.0] * 4)  # an ensemble without chaos
    assert tool.member_settle_ratios([{"truth": {"settle_s_members": [7.0]}}]) is None  # no other member
