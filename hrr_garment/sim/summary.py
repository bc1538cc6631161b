"""A dataset build's summary: counts, quality statistics (strain, penetration, hem swing, limbs
through the body) and simulation speed, per body where there are several (hrr-simulate prints it;
the dataset file and NAME.summary.json record it)."""

from __future__ import annotations

import numpy as np

from ..body.mannequin import MANNEQUIN, MANNEQUIN_STATURE_M
from ..data.dataset import SequenceRecord
from ..garment.dressing import DressedBody
from ..garment.mesh import GarmentMesh
from .quality import edge_strain


def summarise(
    records: list[SequenceRecord],
    garment: GarmentMesh,
    *,
    rejects: dict[str, str],
    sim_wall: float,
    jobs: int | None,
    simulated: int,
    bodies: dict[str, DressedBody] | None = None,
    cloth_of: dict[str, str] | None = None,
) -> dict:
    """The dataset summary: counts, quality statistics (each sequence's strain against the garment
    on its own body) and simulation speed; with bodies, the strain and frames of each; with
    ``cloth_of`` (each planned sequence's cloth, sim/material_plan.py), those of each cloth and its
    rejects."""
    stats = [r.info.get("stats", {}) for r in records]
    edges = garment.edges()
    rest = {MANNEQUIN: garment.vertices, **{n: b.garment.vertices for n, b in (bodies or {}).items()}}
    strains = [edge_strain(r.garment, rest[r.body_name], edges).ravel() for r in records]
    pooled = np.concatenate(strains)
    sim_frames = sum(s.get("simulated_frames", 0) for s in stats)
    sim_seconds = sum(s.get("sim_seconds", 0.0) for s in stats)
    by_kind: dict[str, list[float]] = {}
    for r, s in zip(records, stats):
        if "hem_swing_m" in s:
            by_kind.setdefault(r.info.get("kind", "?"), []).append(s["hem_swing_m"])
    return {
        "garment": garment.name,
        "vertices": garment.num_vertices,
        "sequences": len(records),
        "frames": int(sum(len(r.garment) for r in records)),
        "rejects": rejects,
        "finite": bool(all(np.isfinite(r.garment).all() for r in records)),
        "strain_p99": float(np.percentile(pooled, 99)),
        "strain_max": float(pooled.max()),
        "penetration_frame_max": float(max(s.get("penetration_max", 0.0) for s in stats)),
        # outside frames where the motion's limbs pass through the body (body/self_contact.py)
        "penetration_frame_max_clean": float(
            max(s.get("penetration_max_clean", s.get("penetration_max", 0.0)) for s in stats)
        ),
        "self_intersection_frames": int(sum(s.get("self_intersection_frames", 0) for s in stats)),
        "penetration_mean": float(np.mean([s.get("penetration_mean", 0.0) for s in stats])),
        "deepest_mm": float(max(s.get("deepest_mm", 0.0) for s in stats)),
        **_inside_visible(stats),
        "hem_swing_m_by_kind": {k: float(np.mean(v)) for k, v in sorted(by_kind.items())},
        "sim_frames_per_core_s": float(sim_frames / sim_seconds) if sim_seconds else None,
        "sim_wall_s": float(sim_wall),
        "jobs": jobs,
        "simulated_now": simulated,
        **({"by_body": _by_body(records, strains, bodies)} if bodies else {}),
        **({"by_material": _by_material(records, strains, cloth_of, rejects)} if cloth_of else {}),
    }


def _by_material(
    records: list[SequenceRecord], strains: list[np.ndarray], cloth_of: dict[str, str], rejects: dict
) -> dict:
    """Per cloth: its sequences kept and rejected, frames, strain p99 and mean hem swing."""
    out = {}
    for cloth in sorted(set(cloth_of.values())):
        mine = [k for k, r in enumerate(records) if cloth_of.get(r.name) == cloth]
        swing = [records[k].info.get("stats", {}).get("hem_swing_m") for k in mine]
        swing = [v for v in swing if v is not None]
        out[cloth] = {
            "sequences": len(mine),
            "rejected": sum(cloth_of.get(n) == cloth for n in rejects),
            "frames": int(sum(len(records[k].garment) for k in mine)),
            "strain_p99": float(np.percentile(np.concatenate([strains[k] for k in mine]), 99))
            if mine
            else None,
            "hem_swing_m": float(np.mean(swing)) if swing else None,
        }
    return out


def _by_body(
    records: list[SequenceRecord], strains: list[np.ndarray], bodies: dict[str, DressedBody]
) -> dict:
    """Per body: its stature, sequences, frames and strain p99."""
    out = {}
    for name in sorted({r.body_name for r in records}):
        mine = [k for k, r in enumerate(records) if r.body_name == name]
        pooled = np.concatenate([strains[k] for k in mine])
        stature = bodies[name].record.stature if name in bodies else MANNEQUIN_STATURE_M
        out[name] = {
            "stature_m": stature,
            "sequences": len(mine),
            "frames": int(sum(len(records[k].garment) for k in mine)),
            "strain_p99": float(np.percentile(pooled, 99)),
            **_inside_visible([records[k].info.get("stats", {}) for k in mine]),
        }
    return out


def _inside_visible(stats: list[dict]) -> dict:
    """The cloth inside the body the viewer sees (:func:`~.quality.sequence_stats`): the mean over
    sequences of their mean over frames, and the worst frame; empty for parts simulated before the
    figure existed."""
    known = [s for s in stats if "inside_visible_mean" in s]
    if not known:
        return {}
    return {
        "inside_visible_mean": float(np.mean([s["inside_visible_mean"] for s in known])),
        "inside_visible_frame_max": float(max(s["inside_visible_max"] for s in known)),
    }
