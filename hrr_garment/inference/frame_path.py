"""The frame path: the nine stages that take a body's motion to the garment's world vertices, in
one numbered list (:data:`STAGES`) that every driver runs in order:

1. ``features``: each frame's motion features (:mod:`hrr_garment.motion.features`), its motion
   memory (:mod:`hrr_garment.motion.memory`) and, for a model across bodies, the body's measures,
   for a model across cloths, the cloth's values (:mod:`hrr_garment.garment.material_range`);
2. ``windows``: the last W frames' features (offline: every W-frame window that holds a frame of
   the clip, its ends repeated: :func:`~hrr_garment.motion.windows.covering_windows`);
3. ``choice``: the window step (motion encoder, gate, code-space decoder) and what the mode picks
   (:func:`~.gate.choose_windows`): each window's latents and its database match;
4. ``blending``: per-frame latents from the windows' (offline: :func:`~.blending.blend_windows`;
   causal: the inertializer, :class:`~.blending.Inertializer`); in the sample mode, the generative
   decoder's draw departing from them (:meth:`FramePath.draw`);
5. ``swing``: the free cloth's swing restored (:mod:`.swing`; as predicted at gain 1), then the
   cloth's settling after a stop (:mod:`.settle`; none at 0 s);
6. ``decoding``: the mesh decoder, latents to body-frame vertices (:mod:`.decoding`);
7. ``folds``: the detail mode's simulated folds (:mod:`.detail`, :mod:`.fold_track`);
8. ``world``: the garment stood on the body (its rest offset) and taken to the world
   (:func:`~hrr_garment.motion.frame.world_vertices`);
9. ``push_out``: the collision push-out and its strain limit (:mod:`.collision`), the residual
   and detail modes' additions to the regression first taken back where they carry the cloth into the body
   (:mod:`.take_back`).

The drivers: :mod:`.clip_path` (a whole clip, offline or causal: :meth:`Animator.animate`),
:class:`~.stream.CrowdStream` (a frame of many characters; one character:
:mod:`.character_stream`) and :class:`~.torch_step.StreamStep` (the regression as one torch graph:
the ONNX export and :class:`~.torch_crowd.DeviceCrowd`, the same stages' arithmetic in torch). A
:class:`FramePath` is one model under one resolved run (:class:`~.resolved_run.ResolvedRun`): it
holds what the stages share (the decoder the run asks for, the push-out's settings, the mesh's
smoothing and edge limits) and runs the stages whose arithmetic every driver shares (3, 6 to 9);
stages 1, 2, 4 and 5 keep a driver's state (a clip's frames at once, a crowd's characters one frame
on) and are the drivers' own, under the same names. Every stage's output goes to ``observe`` where
one is given (tests/inference/test_frame_path.py compares the drivers stage by stage): a check per
stage and frame for the whole crowd, nothing per character.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from ..body.measures import with_columns
from ..motion.frame import world_vertices
from ..motion.motion import Motion
from . import collision
from .collision import PushOutReport, push_out
from .detail import add_folds
from .gate import WindowChoice, choose_windows
from .resolved_run import ResolvedRun
from .run_material import material_columns
from .settle import SettleLag
from .swing import SwingGain

#: the stages of a frame, in order (the module docstring says what each does)
STAGES = ("features", "windows", "choice", "blending", "swing", "decoding", "folds", "world", "push_out")

Observer = Callable[[str, np.ndarray], None]  # a stage's name and its output


def with_conditions(
    bundle, features: np.ndarray, measures: np.ndarray, cloth: np.ndarray | None
) -> np.ndarray:
    """Stage 1's last part: (n, F) features with the body's ``measures`` ((b,) for all, or (n, b))
    appended for a model trained across bodies, and then the ``cloth``'s values ((m,) or (n, m),
    :func:`~.run_material.material_columns`) for a model trained across cloths."""
    config = bundle.codespace.config
    if config.body_features:
        features = with_columns(features, measures)
    if config.material_features:
        features = with_columns(features, cloth)
    return features


class FramePath:
    """One model (an :class:`~.animator.Animator`'s) under one resolved ``run``: the stages every
    driver shares; see the module docstring. ``observe``: called with each stage's name and output."""

    def __init__(self, animator, run: ResolvedRun, observe: Observer | None = None):
        self.animator, self.bundle, self.run = animator, animator.bundle, run
        self.window, self.blend = animator.window, animator.blend
        self.cloth = material_columns(self.bundle, run.material)  # stage 1's cloth values (None: reads none)
        self.smoothing, self.edge_limits = animator.smoothing, animator.edge_limits  # the template's
        # stage 9's strain limit measures the garment as it rests on the run's body (a carried
        # garment's edges are not the template's); a crowd's push gives its own bodies' limits
        self.push_limits = run.body.push_limits(animator.edge_limits, self.bundle.template.vertices)
        self.decoder = animator.decoder_for(run)  # stage 6's
        self.push_settings = animator.push_settings(run)  # stage 9's (None: the product's)
        # stage 3's causal window step (native where it can be, else None: PyTorch's)
        self.step = animator.causal_step(run.mode.regresses) if run.causal else None
        self.observe = observe
        self._swing: dict[float, SwingGain | None] = {}
        self._settle: dict[float, SettleLag | None] = {}

    def seen(self, stage: str, value):
        """``value``, the output of ``stage``, shown to the observer (where there is one)."""
        if self.observe is not None:
            self.observe(stage, value)
        return value

    # 3. choice
    def choose(
        self,
        windows: np.ndarray,
        *,
        last_frame: bool = False,
        gates: np.ndarray | None = None,
        step=None,
    ) -> WindowChoice:
        """Feature windows (N, W, F) -> the mode's :class:`~.gate.WindowChoice` (with ``last_frame``,
        the latents of each window's last frame only: what causal paths use; ``gates``: the windows'
        frames' GRU input gates, :func:`~.gate.frame_gates`; ``step``: a window step other than the
        run's, a crowd's traced one). The run's ``exclude_sequence`` is retrieved from by no window."""
        excluded = self.run.exclude_sequence
        choice = choose_windows(
            self.bundle,
            windows,
            self.run,
            exclude=None if excluded is None else np.full(len(windows), excluded),
            last_frame=last_frame,
            step=(self.step if step is None else step) if last_frame else None,
            gates=gates,
        )
        self.seen("choice", choice.latents[:, -1])
        return choice

    # 4. blending, the sample mode's draw
    def draw(self, features: np.ndarray, regression: np.ndarray, tracks: list | None = None) -> np.ndarray:
        """Frames drawn by the generative decoder (:mod:`hrr_garment.models.sampler`): raw
        ``features`` (n, F) and the regression's latents (n, nodes, C) of each frame from the window
        ending at it -> the drawn latents (n, nodes, C). Without ``tracks``, the n frames are a clip
        drawn from the run's seed, frame after frame; with them, one frame of n characters, each
        moving its :class:`~hrr_garment.models.sampler.SampleTrack` on (a crowd). Frame t reads
        frames <= t only and its seed's noise a frame at a time, so both draw the same frames."""
        bundle, sampler = self.bundle, self.bundle.sampler
        n, shape = len(regression), regression.shape[1:]
        feats = torch.from_numpy(bundle.motion_stats.normalize(features).astype(np.float32))
        mean = torch.from_numpy(bundle.latent_stats.normalize(regression.reshape(n, -1)).astype(np.float32))
        if tracks is None:
            drawn = sampler.roll_out(feats, mean, seed=self.run.seed, steps=self.run.sample_steps)
        else:
            drawn = sampler.draw_frame(tracks, feats, mean, steps=self.run.sample_steps)
        return bundle.latent_stats.denormalize(drawn.numpy()).reshape(n, *shape).astype(np.float32)

    # 5. swing
    def swing_gain(self, fps: float) -> SwingGain | None:
        """The swing's gain at ``fps`` (made once per rate), None where the run leaves the swing as
        predicted."""
        if fps not in self._swing:
            swing = self.run.swing
            self._swing[fps] = None if swing == 1.0 else SwingGain.of(swing, self.bundle.node_hang_m, fps)
        return self._swing[fps]

    def settle_lag(self, fps: float) -> SettleLag | None:
        """The settling lag at ``fps`` (made once per rate), None where the run has none."""
        if fps not in self._settle:
            settle = self.run.settle
            self._settle[fps] = SettleLag(settle, fps) if settle > 0 else None
        return self._settle[fps]

    # 7. folds
    def add_folds(self, local: np.ndarray, folds: np.ndarray, follow) -> np.ndarray:
        """Body-frame vertices (n, V, 3) with the detail mode's ``folds`` (n, V, 3) added at the run's
        strength, ``follow``: the fold term's smoothing in time (:func:`~.detail.add_folds`)."""
        store = self.bundle.folds
        return add_folds(
            local,
            folds,
            self.smoothing,
            passes=store.passes,
            strength=self.run.detail.strength,
            limits=self.edge_limits,
            follow=follow,
            weights=self.bundle.fold_weights,
        )

    def follow_over_time(self, folds: np.ndarray) -> np.ndarray:
        """A clip's fold term followed in time (:func:`~.fold_track.follow_over_time`)."""
        from .fold_track import follow_over_time

        return follow_over_time(folds, mean=self.smoothing)

    # 8. world
    def world(self, stood: np.ndarray, motion: Motion, seen: bool = True) -> np.ndarray:
        """Body-frame vertices stood on the body (its rest offset added) -> world vertices (shown
        to the observer where ``seen``: the cloth's, not the regression's under it)."""
        vertices = world_vertices(stood, motion)
        return self.seen("world", vertices) if seen else vertices

    # 9. push-out
    @property
    def takes_back(self) -> bool:
        """Whether stage 9 takes the residual and detail modes' additions back first (:mod:`.take_back`): the
        drivers then decode the regression under them too."""
        settings = self.push_settings if self.push_settings is not None else collision.PUSH_OUT
        return self.run.push_out and settings.takes_back

    def push_out(
        self, vertices: np.ndarray, motion: Motion, capsules, report: bool = True, limits=None, base=None
    ) -> tuple[np.ndarray, PushOutReport | None]:
        """World vertices (n, V, 3) pushed out of the body ``capsules`` (a BodyModel posed by
        ``motion``, :class:`~.collision.PosedCapsules`, or the mesh the viewer sees,
        :class:`~.visible_push.PosedSkin`) where the run asks for it; the report
        where ``report`` and the push-out ran. ``limits``: the strain limit's
        (:class:`~.edge_limits.EdgeLimits`) where the frames rest on other bodies than the run's.
        ``base``: the same frames' regression, world vertices, where the run adds to it: the
        additions are taken back first where they carry the cloth into the body (:mod:`.take_back`)."""
        out = None
        if self.run.push_out:
            vertices, out = push_out(
                vertices,
                motion,
                self.bundle.template.faces,
                body=capsules,
                mean=self.smoothing,
                limits=self.push_limits if limits is None else limits,
                settings=self.push_settings,
                report=report,
                base=base,
            )
        self.seen("push_out", vertices)
        return vertices, out
