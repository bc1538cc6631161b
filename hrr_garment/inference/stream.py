"""Streaming: poses in as a game has them each frame, garment frames out, causal, for many
characters in one call (:class:`CrowdStream`; one character: :mod:`.character_stream`).

    crowd = animator.crowd()                            # hybrid, the model's tau, push-out on
    for frame in game:
        vertices = crowd.push(rotations, roots, keys)   # (N, J, 4) quaternions, (N, 3) -> (N, V, 3)
    crowd.leave("npc_7")                                # a character that left the scene
    crowd.set_body("npc_8", "tall.json")                # a character of its own body (a model across bodies)
    vertices = crowd.push(rotations, roots, keys, lod=levels)   # levels of detail per character (.lod)

Each character keeps its own state: its last pose, its motion memory, its last W feature frames,
its inertialization and, in the detail mode, its fold playhead (:mod:`.fold_track`). A push runs
every stage of the frame path (:mod:`.frame_path`) once for all the characters in it: the features, the
window step (motion encoder, gate, code-space decoder), the mesh decoder and the collision
push-out, each batched through the native kernels. So N characters pushed together give what
each gives pushed alone (tested), and a character's output is frame t of
``animator.animate(motion, causal=True)`` on its clip (tested to 1e-5).

Poses are local joint rotations, parent-relative, as quaternions (x, y, z, w: glTF, Unity and
Unreal order), axis-angle vectors or 3 x 3 matrices, on the canonical skeleton
(:data:`~hrr_garment.motion.skeleton.JOINT_NAMES`, 22 joints) or on a source rig through the
same joint map and retargeting as its files (:class:`~hrr_garment.motion.stream_rig.StreamRig`);
roots are the pelvis positions in metres, Y up. A character whose pelvis jumps further in one
frame than a body moves (over 100 m/s: a respawn, a cut to another place) starts afresh there, as
after :meth:`CrowdStream.leave`, with a :class:`~hrr_garment.errors.TeleportWarning`: its windows and
blend would otherwise sweep the cloth across the jump.
"""

from __future__ import annotations

import time
from collections.abc import Hashable, Mapping, Sequence
from functools import partial

import numpy as np

from ..errors import InputError
from ..models.codes import traced_window_codes
from ..models.sampler import SampleTrack
from ..motion.features import pair_features_batch
from ..motion.memory import motion_memory
from ..motion.motion import Motion
from ..motion.poses import poses_to_motion
from ..native import pin_workers
from .blending import Inertializer
from .character_body import CrowdBodies
from .crowd_state import STREAM_STAGES, CrowdCharacter, CrowdTimings, character_seed, check_keys, teleported
from .crowd_windows import CrowdWindows
from .decoding import flush_denormals
from .fold_track import FoldTrack, follow_folds
from .frame_path import FramePath, with_conditions
from .gate import frame_gates
from .lod import crowd_bases, crowd_decode, crowd_latents, decoder_of, levels
from .modes import Mode
from .run_material import cloth_columns
from .run_settings import ResolvedRun
from .settle import settle_crowd
from .swing import swing_crowd


class CrowdStream:
    """Many characters streamed in one call per frame; see the module docstring. ``rig``: a
    :class:`~hrr_garment.motion.stream_rig.StreamRig` when poses come on a source skeleton."""

    def __init__(self, animator, run: ResolvedRun, *, rig=None):
        """``run``: the settings, resolved for ``animator``'s model (:meth:`~.animator.Animator.crowd`
        makes both); they hold for the stream's life. Its body (``run.body``, a
        :class:`~.character_body.CharacterBody`) is every character's but those given one of their own
        (:meth:`set_body`); poses on the canonical skeleton are played by it, as
        :meth:`~.animator.Animator.animate` plays a clip."""
        self.animator, self.run, self.rig = animator, run, rig
        self.path = FramePath(animator, run)  # the stages, run once a push for the whole crowd
        self.body = run.body
        self._bodies: dict[Hashable, object] = {}  # characters with a body of their own (set_body)
        self._seeds: dict[Hashable, int] = {}  # characters with a seed of their own (set_seed)
        # characters in a cloth of their own (set_material): the cloth's values as the model reads them
        self._cloths_of: dict[Hashable, np.ndarray] = {}
        self._stacked: tuple = ((), None)  # the last mixed crowd's bodies and their stacked arrays
        self._characters: dict[Hashable, CrowdCharacter] = {}
        self._windows = CrowdWindows(animator.window)
        self._inertia = Inertializer(animator.blend, paths=0)  # every character's latent path, a row each
        self.timings = CrowdTimings()
        regression = run.mode.regresses
        bundle = animator.bundle
        self._decoders = {
            "full": animator.mesh_decoder(run.precision),
            "fast": bundle.subspace,
        }  # by name, as levels of detail pick them
        self._step = self.path.step or traced_window_codes(
            bundle.codespace, animator.window, bundle.codespace.features, regression=regression
        )

    @property
    def mode(self) -> Mode:
        """The mode the stream runs (``auto`` resolved)."""
        return self.run.mode

    @property
    def characters(self) -> list:
        """The keys of the characters streamed so far and not left, in the order they joined."""
        return list(self._characters)

    def set_body(self, key: Hashable, body, *, allow_outside: bool = False) -> None:
        """Give character ``key`` a body of its own (what :meth:`~.animator.Animator.body` takes: a
        body file, a record, a CharacterBody), before it joins or between frames: its poses are played
        by that body, the model reads its measures, the garment stands on it and the push-out uses
        its capsules. Characters of different bodies still go through one batched step."""
        self._bodies[key] = self.animator.body(body, allow_outside=allow_outside)

    def set_material(self, key: Hashable, material, *, allow_outside: bool = False) -> None:
        """Dress character ``key`` in a cloth of its own (what ``RunSettings.material`` takes: a
        fabric's name, values, a Material), before it joins or between frames; the run's cloth is
        every other character's. Checked against the model's range of cloths as the run's is
        (:func:`~.run_material.run_material`); characters in different cloths still go through one
        batched step."""
        cloth = cloth_columns(self.animator.bundle, material, allow_outside)
        if cloth is not None:  # a model of one cloth reads none: the cloth is checked, nothing more
            self._cloths_of[key] = cloth

    def set_seed(self, key: Hashable, seed: int) -> None:
        """Give character ``key`` a seed of its own for the sample mode's draw (the run's seed is
        every other character's): before it joins, or to start its draw afresh from that seed."""
        self._seeds[key] = character_seed(seed)
        if key in self._characters:
            self._characters[key].sample = None

    def leave(self, key: Hashable) -> None:
        """Forget a character: pushed again later, it starts afresh (as from a standstill)."""
        if key not in self._characters:
            raise KeyError(f"no character {key!r} in this stream (characters: {self.characters})")
        self._forget(key)
        self._bodies.pop(key, None)
        self._seeds.pop(key, None)
        self._cloths_of.pop(key, None)

    def _forget(self, key: Hashable) -> None:
        """Drop a character's state (it starts afresh if pushed again), its inertialization's row freed."""
        self._inertia.remove_path(self._characters.pop(key).inertia)

    def push(
        self, rotations: np.ndarray, roots: np.ndarray, keys: Sequence[Hashable] | None = None, *, lod=None
    ) -> np.ndarray:
        """One frame of N characters: ``rotations`` (N, J, 4) quaternions (x, y, z, w), (N, J, 3)
        axis-angle or (N, J, 3, 3) matrices, local; ``roots`` (N, 3) pelvis positions, metres; ``keys``
        one id per character (default 0 .. N-1; a new id joins); ``lod``: each character's level of
        detail (:mod:`.lod`; None: all at 0). -> (N, V, 3) world vertices, float32."""
        rotations, roots = np.asarray(rotations), np.asarray(roots)
        for name, value in (("rotations", rotations), ("roots", roots)):
            if value.dtype.kind not in "iuf" or value.ndim < 2:
                raise TypeError(
                    f"{name} must be numbers, a row per character, got {value.dtype} of shape {value.shape}"
                )
        keys = list(range(len(rotations))) if keys is None else list(keys)
        if self.rig is not None:
            poses = self.rig.to_canonical(rotations, roots)
        else:
            poses = poses_to_motion(rotations, roots)
        return self._push(keys, poses, lod)

    def push_motions(self, poses: Mapping[Hashable, Motion], *, lod=None) -> np.ndarray:
        """One frame of each character as a one-frame :class:`Motion` on the canonical skeleton ->
        (N, V, 3), rows in the mapping's order; ``lod`` as :meth:`push`."""
        for key, pose in poses.items():
            if pose.num_frames != 1:
                raise InputError(pose.source or str(key), f"push one frame at a time (got {pose.num_frames})")
        motions = list(poses.values())
        stacked = motions[0] if len(motions) == 1 else Motion.concatenate(motions)
        return self._push(list(poses), stacked, lod)

    def _push(self, keys: list, poses: Motion, lod=None) -> np.ndarray:
        """``poses``: one frame per key, as an N-frame motion (frames are characters here)."""
        t0 = time.perf_counter()
        check_keys(keys, poses.num_frames)
        lv = levels(lod, len(keys))
        with flush_denormals():
            vertices = self._step_frame(keys, poses, lv)
        self.timings.latency_s.append(time.perf_counter() - t0)
        return vertices

    def _with_memory(self, chars: list[CrowdCharacter], features: np.ndarray, fps: float) -> np.ndarray:
        """The pushed frame's features (N, 124) with each character's motion memory, carried one
        frame on (:mod:`hrr_garment.motion.memory`), as offline causal computes it over the clip."""
        spec = self.animator.bundle.codespace.config.memory
        if not spec:
            return features
        memory = motion_memory(spec, float(fps))
        state = memory.advance([c.memory for c in chars], features)
        for c, s in zip(chars, state):
            c.memory = s
        return np.concatenate([features, memory.values(state)], 1)

    def _folds(self, chars: list[CrowdCharacter], source: np.ndarray) -> np.ndarray:
        """(N, V, 3): each character's folds this frame, its :class:`FoldTrack` stepped on the last
        frame of its window's match (as :func:`~.fold_track.causal_proposals`)."""
        store, window = self.animator.bundle.folds, self.animator.window
        steps = []
        for c, (sequence, start) in zip(chars, source):
            if c.fold_track is None:
                c.fold_track = FoldTrack(store.offsets)
            steps.append(c.fold_track.step(sequence, start + window - 1))
        return store.folds(np.stack([r for r, _ in steps]), np.stack([w for _, w in steps]))

    def _follow(self, chars: list[CrowdCharacter]):
        """The detail mode's fold term -> as each character's folds follow in time
        (:func:`~.fold_track.follow_folds`, its state kept on the character)."""

        def follow(term: np.ndarray) -> np.ndarray:
            states = [c.followed for c in chars]
            followed = follow_folds(term, states, self.animator.smoothing)
            for c, state in zip(chars, states):
                c.followed = state
            return followed

        return follow

    def _played(self, keys: list, poses: Motion) -> tuple[Motion, "CrowdBodies"]:
        """The pushed poses (one per character, on the canonical skeleton) each played by its
        character's body, and those bodies as arrays (one row per character, or one body for all)."""
        bodies = [self._bodies.get(k, self.body) for k in keys]
        if all(b is bodies[0] for b in bodies):
            return bodies[0].play(poses), CrowdBodies.of_one(bodies[0])
        ids = tuple(map(id, bodies))
        if self._stacked[0] != ids:
            self._stacked = (ids, CrowdBodies.of_many(bodies))
        stacked = self._stacked[1]
        return poses.on_skeletons(stacked.skeletons, stacked.root_scale), stacked

    def _cloths(self, keys: list) -> np.ndarray | None:
        """The cloth values the model reads (:func:`~.run_material.material_columns`): the run's for
        all, or one row per character where some have their own; None for a model of one cloth."""
        run_cloth = self.path.cloth
        if run_cloth is None or not any(k in self._cloths_of for k in keys):
            return run_cloth
        return np.stack([self._cloths_of.get(k, run_cloth) for k in keys])

    def _latents(
        self, chars: list[CrowdCharacter], windows: np.ndarray, gates: np.ndarray | None, lv: np.ndarray
    ) -> np.ndarray:
        """The window step (motion encoder, gate, code-space decoder) of the characters whose level
        of detail runs it now (all, at level 0), the others' held: (N, nodes, C) inertialized
        latents; each character's ``lod`` keeps its database match. ``gates``: the windows' frames'
        GRU input gates (None: the step computes them)."""

        def choose(rows):
            pick = slice(None) if rows is None else rows  # all: the arrays themselves
            gated = None if gates is None else gates[pick]
            return self.path.choose(windows[pick], last_frame=True, gates=gated, step=self._step)

        rows = np.array([c.inertia for c in chars])
        return crowd_latents(
            chars, lv, choose=choose, inertialize_rows=partial(self._inertia.step_rows, rows=rows)
        )

    def _restart_teleported(self, keys: list, poses: Motion) -> None:
        """Forget the characters whose pelvis jumped since their last push (:func:`.crowd_state.teleported`:
        they start afresh this frame, each with a warning)."""
        last = [self._characters[k].root if k in self._characters else None for k in keys]
        for i in teleported(keys, last, poses.root_translation, fps=poses.fps):
            self._forget(keys[i])

    def _bases(self, chars: list, names: list[str], bodies, poses: Motion):
        """Stage 9's regressions under the mode's additions, world vertices (:mod:`.take_back`), or
        None where the mode adds nothing to the regression."""
        local = crowd_bases(chars, names, decoders=self._decoders)
        return None if local is None else self.path.world(bodies.stand(local), poses, seen=False)

    def _step_frame(self, keys: list, poses: Motion, lv: np.ndarray) -> np.ndarray:
        """The frame path's nine stages (:mod:`.frame_path`), each once for the whole crowd."""
        path, t = self.path, [time.perf_counter()]
        pin_workers()  # a game loop idles between frames: its next frame must not wait for workers to move
        self._restart_teleported(keys, poses)
        for k in keys:
            if (
                k not in self._characters
            ):  # not setdefault: that built a new character's state for every key every frame
                self._characters[k] = CrowdCharacter(*self._windows.start(), self._inertia.add_path())
        chars = [self._characters[k] for k in keys]
        roots = poses.root_translation  # as pushed, before a body plays them
        poses, bodies = self._played(keys, poses)
        # 1. features
        features = self._with_memory(
            chars, pair_features_batch([c.previous for c in chars], poses), poses.fps
        )
        features = path.seen(
            "features", with_conditions(path.bundle, features, bodies.vector, cloth=self._cloths(keys))
        )
        # 2. windows: each frame's gates once, as it comes
        gates = frame_gates(path.bundle, self._step, features)
        windows, window_gates = self._windows.push(
            tuple(keys), chars, features, gates
        )  # (N, W, F), (N, W, 3H)
        path.seen("windows", windows)
        t.append(time.perf_counter())
        # 3. choice and 4. blending
        latents = self._latents(chars, windows, window_gates, lv)
        if self.run.mode is Mode.SAMPLE:  # each character's draw departs from its regression
            for k, c in zip(keys, chars):
                if c.sample is None:
                    c.sample = SampleTrack(path.bundle.sampler, self._seeds.get(k, self.run.seed))
            latents = path.draw(features, latents, [c.sample for c in chars])
        path.seen("blending", latents)
        # 5. swing: the free cloth's swing restored, each character's course kept on it
        gain = path.swing_gain(poses.fps)
        latents = latents if gain is None else swing_crowd(gain, chars, latents)
        lag = path.settle_lag(poses.fps)  # then the cloth settling after a stop
        if lag is not None:
            latents = settle_crowd(lag, chars, latents, features=features)
        latents = path.seen("swing", latents)
        t.append(time.perf_counter())
        # 6. decoding
        has_fast = self._decoders["fast"] is not None
        names = [decoder_of(int(level), self.run.decoder, has_fast) for level in lv]
        local = path.seen("decoding", crowd_decode(chars, latents, names, decoders=self._decoders))
        # 7. folds: each character's playhead one frame on
        if self.run.mode is Mode.DETAIL:
            folds = self._folds(chars, np.stack([c.lod.match for c in chars]))
            local = path.add_folds(local, folds, follow=self._follow(chars))
        path.seen("folds", local)
        t.append(time.perf_counter())
        # 8. world: as offline, the same push-out inputs
        vertices = path.world(bodies.stand(local), poses)
        t.append(time.perf_counter())
        # 9. push-out
        push_body = (
            bodies.push_body(poses, visible=self.run.push_body == "visible") if self.run.push_out else None
        )
        limits = (
            bodies.push_limits(path.edge_limits, path.bundle.template.vertices) if self.run.push_out else None
        )
        base = self._bases(chars, names, bodies, poses) if path.takes_back else None
        vertices, _ = path.push_out(vertices, poses, push_body, report=False, limits=limits, base=base)
        t.append(time.perf_counter())
        for i, c in enumerate(chars):
            c.previous = (poses.global_rotations[i], poses.joint_positions[i])
            c.root = roots[i]
            c.frames += 1
        for name, start, stop in zip(STREAM_STAGES, t, t[1:]):
            self.timings.stage_s[name].append(stop - start)
        return vertices.astype(np.float32, copy=False)
