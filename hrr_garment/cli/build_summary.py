"""The summary a dataset build prints (hrr-simulate, and hrr-train where it simulates): sequences,
frames, strain, penetration, simulation speed, splices, bodies, rejects."""

from __future__ import annotations

from ..garment.mesh import GarmentMesh
from ..io_utils import strict_json


def print_build_report(report, garment: GarmentMesh) -> None:
    """Print a dataset build's summary."""
    s = report.summary
    print(
        f"wrote {report.path}: {s['sequences']} sequences, {s['frames']} frames, {garment.num_vertices} "
        f"vertices ({report.reused} reused, {report.simulated} simulated now, {len(report.rejects)} rejected)"
    )
    print(
        f"  strain p99 {s['strain_p99']:.3f} (max {s['strain_max']:.2f}); penetration: worst frame "
        f"{100 * s['penetration_frame_max']:.2f} % of vertices > 5 mm inside, mean "
        f"{100 * s['penetration_mean']:.3f} %"
    )
    if "inside_visible_mean" in s:
        print(
            f"  cloth inside the body the viewer sees (its mesh; the mannequin's capsules): mean "
            f"{100 * s['inside_visible_mean']:.2f} %, worst frame {100 * s['inside_visible_frame_max']:.2f} %"
        )
    print(
        f"  {s['self_intersection_frames']} frame(s) where the motion's limbs pass through the body; worst "
        f"frame outside them {100 * s['penetration_frame_max_clean']:.2f} %"
    )
    if s["sim_frames_per_core_s"]:
        print(
            f"  {s['sim_frames_per_core_s']:.2f} simulated frames/s per core (lead-in included); wall "
            f"{s['sim_wall_s']:.0f} s"
        )
    sp = s.get("splices", {})
    if sp.get("asked"):
        print(
            f"  splices: {sp['made']} of {sp['asked']} (legs of one training clip, upper body of another; "
            f"{sp['refused_self_intersection']} of {sp['drawn']} drawn refused for limbs through the body)"
        )
    windows = (  # (kind, what each is, the length a training clip needs)
        ("backward", "played backward: {made} of {asked} windows of training clips", "that long"),
        (
            "stops",
            "stop and stand: {made} of {asked} windows of training clips, each then held still",
            "stop_motion_s long",
        ),
    )
    for kind, line, needs in windows:
        made, asked = sp.get(f"{kind}_made"), sp.get(f"{kind}_asked")
        if asked:
            short = (
                ""
                if made == asked
                else f" (fewer than asked: no training clip from a motion file is {needs}, or some failed "
                "to simulate)"
            )
            print("  " + line.format(made=made, asked=asked) + short)
    for name, row in s.get("by_body", {}).items():
        print(
            f"  body {name or 'mannequin'} ({row['stature_m']:.2f} m): {row['sequences']} sequences, "
            f"{row['frames']} frames, strain p99 {row['strain_p99']:.3f}"
            + (
                f", inside its visible mesh {100 * row['inside_visible_mean']:.2f} % "
                f"(worst frame {100 * row['inside_visible_frame_max']:.2f} %)"
                if "inside_visible_mean" in row
                else ""
            )
        )
    for name, row in s.get("by_material", {}).items():
        kept = f"{row['sequences']} sequences ({row['rejected']} rejected), {row['frames']} frames"
        quality = (
            f", strain p99 {row['strain_p99']:.3f}, hem swing {row['hem_swing_m']:.3f} m"
            if row["sequences"] and row["hem_swing_m"] is not None
            else ""
        )
        print(f"  cloth {name}: {kept}{quality}")
    licence = s.get("motion_licence")
    if licence:
        counts = ", ".join(f"{k} {v['sequences']}" for k, v in licence["sources"].items())
        print(f"  motion sources (sequences): {counts}; {licence['statement']}")
    print(
        "  hem swing (m) by kind: "
        + strict_json({k: round(v, 3) for k, v in s["hem_swing_m_by_kind"].items()})
    )
    for name, reason in report.rejects.items():
        print(f"  rejected {name}: {reason}")
    if report.preview:
        print(f"  preview: {report.preview}")
