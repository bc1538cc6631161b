"""Scoring predictions against simulated ground truth: every metric of one predicted sequence, the
truth ensemble's own values and a prediction's ensemble scores, and :class:`SequenceScorer`, which
scores one garment's predictions sequence by sequence. The cloth inside the body the viewer sees is
:mod:`.visible_inside`'s, before and after the push-out; the capsule figures beside it are what the
push-out works against."""

from __future__ import annotations

import math

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel
from ..data.dataset import SequenceRecord
from ..garment.fit import hem_vertices
from ..inference.collision import PushOutReport
from ..sim.quality import body_signed_distance, penetration_fraction
from . import metrics as M
from .ensemble import TruthEnsemble
from .ensemble_metrics import ensemble_metrics, truth_metrics
from .mode_results import SequenceResult
from .visible_inside import SHARES, VisibleBody, inside_before_and_after, inside_visible, visible_body_of

# the share of frames (%) on which the push-out's strain limit moved an edge: where the push alone tore
# the cloth; NaN where no push-out ran
LIMITED = "push_limited_pct"


def as_simulated(bundle, record: SequenceRecord) -> dict:
    """The run settings that animate ``record`` as it was simulated: on its body and, for a model
    that records its cloths, in its cloth; either one outside the model's range is animated anyway
    (warned): a measurement, not a user's run. A model from before cloths were recorded animates
    its own."""
    cloth = record.material if bundle.material_range is not None else None
    return {
        "body": record.dressed,
        "allow_outside": True,
        "material": cloth,
        "allow_outside_material": cloth is not None,
    }


def body_of(record: SequenceRecord) -> BodyModel:
    """The body a sequence was simulated on (its capsules): penetration is measured against it."""
    return record.dressed.body if record.dressed is not None else DEFAULT_BODY


def visible_of(record: SequenceRecord) -> VisibleBody:
    """What a viewer sees of the body a sequence was simulated on
    (:func:`~.visible_inside.visible_body_of`)."""
    return visible_body_of(record.dressed.record if record.dressed is not None else None)


def rest_of(record: SequenceRecord, template_rest: np.ndarray) -> np.ndarray:
    """The garment at rest on the sequence's body: strain and the cloth energies are measured from it."""
    return record.dressed.garment.vertices.astype(np.float64) if record.dressed is not None else template_rest


def sequence_metrics(
    pred: np.ndarray,
    truth: np.ndarray,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    retrieved: np.ndarray,
    *,
    visible: VisibleBody | None = None,
    before: np.ndarray | None = None,
) -> dict[str, float]:
    """Every metric of one predicted sequence (world space, metres). The cloth inside the body the
    viewer sees (``visible``; None: :func:`visible_of` the record's) is measured on the prediction and
    on it ``before`` the push-out (None: no push-out ran, the same)."""
    pred, truth = pred.astype(np.float64), truth.astype(np.float64)
    visible = visible_of(record) if visible is None else visible
    before = pred if before is None else before
    out = {
        **inside_before_and_after(before, pred, record.motion, visible=visible),
        "pve_mm": M.pve_mm(pred, truth),
        "rmse_mm": M.rmse_mm(pred, truth),
        **M.sted(pred, truth, topo),
        "chamfer_cm": M.chamfer_cm(pred, truth),
        **M.penetration_pct(body_signed_distance(pred, record.motion, body_of(record))),
        "curvature_error_cm": M.curvature_error_cm(pred, truth, topo),
        **M.edge_strain_percentiles(pred, rest, topo),
        **M.energy_ratios(pred, truth, rest, topo=topo),
        **M.jitter_mm(pred, truth),
        "retrieval_usage": float(np.mean(retrieved)),
    }
    return out


def ensemble_truth(
    ensemble: TruthEnsemble,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    hem: np.ndarray | None,
    visible: VisibleBody,
) -> dict[str, float]:
    """The members' own values, the penetration (inside the body the viewer sees, ``visible``, and
    inside the capsules) and strain beside the floor and the other ``truth_*``."""
    truth_pen = [
        penetration_fraction(body_signed_distance(m, record.motion, body_of(record)))
        for m in ensemble.members
    ]
    seen = np.stack([inside_visible(m, record.motion, visible) for m in ensemble.members])
    strain = M.edge_strain_percentiles(ensemble.members.reshape(-1, *ensemble.members.shape[2:]), rest, topo)
    return {
        **truth_metrics(ensemble.members, record.motion, rest, topo=topo, hem=hem),
        "truth_inside_visible_pct": 100.0 * float(seen.mean()),
        "truth_inside_visible_worst_pct": 100.0 * float(seen.max()),
        "truth_penetration_pct": 100.0 * float(np.mean([p.mean() for p in truth_pen])),
        "truth_penetration_worst_pct": 100.0 * float(max(p.max() for p in truth_pen)),
        "truth_strain_p99": strain["strain_p99"],
        "truth_strain_max": strain["strain_max"],
    }


def sequence_ensemble_metrics(
    anim_vertices: np.ndarray,
    before_push_out: tuple[float, float] | None,
    ensemble: TruthEnsemble,
    record: SequenceRecord,
    rest: np.ndarray,
    topo: M.MeshTopology,
    hem: np.ndarray | None,
    truth: dict[str, float],
) -> dict[str, float]:
    """Ensemble scores of one prediction ((T, V, 3), or (S, T, V, 3): its draws), with the
    penetration (of the first draw) before the collision push-out
    (``before_push_out``: mean and worst-frame fraction; None when there was no push-out) and the
    members' own values (``truth``, from :func:`ensemble_truth`) beside it."""
    out = ensemble_metrics(
        anim_vertices, ensemble.members, record.motion, rest=rest, topo=topo, hem=hem, truth=truth
    )
    if before_push_out is None:
        first = anim_vertices if anim_vertices.ndim == 3 else anim_vertices[0]
        pen = penetration_fraction(body_signed_distance(first, record.motion, body_of(record)))
        before_push_out = float(pen.mean()), float(pen.max())
    out.update(
        penetration_before_pct=100.0 * before_push_out[0],
        penetration_before_worst_pct=100.0 * before_push_out[1],
    )
    return out


class SequenceScorer:
    """Scores predictions of one garment against records and their truth ensembles, the truths'
    own ensemble values computed once per record."""

    def __init__(self, template, ensembles: dict[str, TruthEnsemble] | None):
        self.topo = M.MeshTopology.of(template.faces, template.num_vertices)
        self.rest = template.vertices.astype(np.float64)
        self.hem = hem_vertices(template)
        self.ensembles = ensembles or {}
        self.truths: dict[str, dict[str, float]] = {}
        self.visible: dict[str, VisibleBody] = {}

    def sequence(
        self,
        vertices: np.ndarray,
        record: SequenceRecord,
        retrieved: np.ndarray,
        entropy: np.ndarray,
        pushed: PushOutReport | None,
        *,
        unpushed: np.ndarray | None = None,
        draws: np.ndarray | None = None,
    ) -> SequenceResult:
        """One prediction's :class:`SequenceResult`: ``vertices`` (T, V, 3) world, ``unpushed`` the same
        before the push-out (None: no push-out ran), ``pushed`` the push-out's own report (None: no
        push-out ran): the cloth inside the capsules before it and the share of frames on which its
        strain limit moved an edge (NaN without one). ``draws``: (S, T, V, 3) further draws of a
        generative mode (other seeds), scored with ``vertices`` as one prediction's samples against
        the truth ensemble (the energy score's spread term, the draws' spread); the other metrics
        are ``vertices``' alone."""
        ensemble, rest = {}, rest_of(record, self.rest)
        if record.name not in self.visible:
            self.visible[record.name] = visible_of(record)
        visible = self.visible[record.name]
        if record.name in self.ensembles:
            if record.name not in self.truths:
                self.truths[record.name] = ensemble_truth(
                    self.ensembles[record.name], record, rest, self.topo, self.hem, visible
                )
            ensemble = sequence_ensemble_metrics(
                vertices if draws is None else np.concatenate([vertices[None], draws]),
                None if pushed is None else (pushed.inside_before, pushed.worst_before),
                self.ensembles[record.name],
                record,
                rest,
                self.topo,
                self.hem,
                self.truths[record.name],
            )
        metrics = sequence_metrics(
            vertices, record.garment, record, rest, self.topo, retrieved, visible=visible, before=unpushed
        )
        metrics[LIMITED] = math.nan if pushed is None else 100.0 * pushed.limited
        if ensemble:  # the ensemble table's plausibility: inside the visible body, the push-out's tears
            ensemble.update({k: metrics[k] for k in (*SHARES, LIMITED)})
        return SequenceResult(
            record.name,
            len(record.garment),
            metrics,
            per_frame_pve_mm=M.per_frame_pve_mm(
                vertices.astype(np.float64), record.garment.astype(np.float64)
            ),
            entropy=entropy,
            retrieved=retrieved,
            ensemble=ensemble,
            visible_body=visible.kind,
        )
