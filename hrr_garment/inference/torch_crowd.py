"""A crowd on a torch device (a CUDA GPU): :class:`DeviceCrowd`, the regression path of
:class:`~.stream.CrowdStream` as one torch step (:class:`~.torch_step.StreamStep`: poses, features,
window step, mesh decoder, push-out and strain limit, every character in one batch), the
characters' state kept on the device between frames.

    crowd = animator.crowd(mode="regression", decoder="fast")      # on CUDA where torch sees one
    vertices = crowd.push(rotations, roots, keys)                  # (N, 22, 4) quaternions x y z w, (N, 3)
    tensor = crowd.push(rotations, roots, keys, as_tensor=True)    # (N, V, 3) left on the device

What it runs: the regression (the window step's own latents, no database: a retrieval is a search
the GPU step does not hold), or the sample mode's draw (each character's white noise from its own
seeded generator, the run's seed or :meth:`DeviceCrowd.set_seed`'s, as the native crowd draws it),
one body for every character, poses as local quaternions on the canonical skeleton. On the CPU
(``device="cpu"``) it gives what the native crowd gives within float rounding (tested); a
character's first frame starts it as a stream starts (zero velocities, its window that frame
repeated); a character whose pelvis jumps (a respawn) starts afresh there, with its cloth and seed,
as in the native crowd (:func:`~.crowd_state.teleported`).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
import torch

from ..errors import InputError
from ..models.sampler import characters_noise
from ..motion.motion import FPS
from ..motion.skeleton import NUM_JOINTS
from .crowd_state import character_seed, check_keys, teleported
from .frame_path import FramePath
from .modes import Mode
from .run_material import cloth_columns
from .run_settings import ResolvedRun
from .torch_step import SAMPLE_STATE, SETTLE_STATE, STATE, state_shapes, stream_step


class DeviceCrowd:
    """Many characters of one body streamed on ``device`` in one call per frame; see the module docstring."""

    def __init__(self, animator, run: ResolvedRun):
        """``run``: the settings resolved for ``animator``'s model: its body every character's, its
        ``device`` the torch device the step runs on."""
        if run.mode not in (Mode.REGRESSION, Mode.SAMPLE):
            raise ValueError(
                f"a crowd on a torch device runs the regression or the sample mode (mode='regression' or "
                f"'sample'), not {run.mode.value!r}: the database's retrieval, residual and folds run in "
                "the native crowd (device='native')"
            )
        if run.swing != 1.0:
            raise ValueError(
                f"a crowd on a torch device runs the swing as predicted (swing=1), not {run.swing:g}: "
                "the restored swing runs in the native crowd (device='native')"
            )
        self.device = torch.device(run.device)
        self.run, self.body = run, run.body
        path = FramePath(animator, run)
        self.step = stream_step(path, movable=True).to(self.device)
        self._run_cloth = path.cloth  # the run's cloth values (None: the model reads none)
        self._shapes = state_shapes(self.step)
        self._state = {
            name: torch.zeros((0, *shape), device=self.device) for name, shape in self._shapes.items()
        }
        self._slots: dict[Hashable, int] = {}
        self._free: list[int] = []
        # the sample mode's draw: each character's seed and its generator of white noise
        self._seeds: dict[Hashable, int] = {}
        self._generators: dict[Hashable, torch.Generator] = {}
        self._animator = animator
        self._cloths: dict[Hashable, np.ndarray] = {}  # characters in a cloth of their own (set_material)
        # each character's last pushed pelvis position, kept on the host: a jump restarts it
        self._roots: dict[Hashable, np.ndarray] = {}

    @property
    def mode(self) -> Mode:
        return self.run.mode

    @property
    def characters(self) -> list:
        """The keys of the characters streamed so far and not left, in the order they joined."""
        return list(self._slots)

    def leave(self, key: Hashable) -> None:
        """Forget a character: pushed again later, it starts afresh."""
        if key not in self._slots:
            raise KeyError(f"no character {key!r} in this crowd (characters: {self.characters})")
        self._free.append(self._slots.pop(key))
        self._roots.pop(key, None)
        self._seeds.pop(key, None)
        self._generators.pop(key, None)
        self._cloths.pop(key, None)

    def set_material(self, key: Hashable, material, *, allow_outside: bool = False) -> None:
        """Dress character ``key`` in a cloth of its own, as :meth:`CrowdStream.set_material` does
        (the step takes each character's cloth values, docs/materials.md)."""
        cloth = cloth_columns(self._animator.bundle, material, allow_outside)
        if cloth is not None:  # a model of one cloth reads none: the cloth is checked, nothing more
            self._cloths[key] = cloth

    def _materials(self, keys: list) -> torch.Tensor | None:
        """(N, m) each character's cloth values where some have their own, else None (the run's)."""
        if not any(k in self._cloths for k in keys):
            return None
        rows = np.stack([self._cloths.get(k, self._run_cloth) for k in keys]).astype(np.float32)
        return torch.from_numpy(rows).to(self.device)

    def set_seed(self, key: Hashable, seed: int) -> None:
        """Give character ``key`` a seed of its own for the sample mode's draw (the run's seed is every
        other character's), before it joins (one that has: :meth:`leave` it first)."""
        if key in self._slots:
            raise ValueError(f"character {key!r} has joined: leave it first to draw it afresh from a seed")
        self._seeds[key] = character_seed(seed)

    def _white_noise(self, keys: list) -> torch.Tensor:
        """(N, 2, L) each character's white noise this frame, from its seeded generator (on the CPU,
        in the order the native crowd draws it). A character without a generator yet is at its first
        frame (a new, a returning or a respawned one: :meth:`leave` and a teleport drop it), so the
        device's ``started`` need not be read back."""
        first = [key not in self._generators for key in keys]
        for key, new in zip(keys, first):
            if new:
                self._generators[key] = torch.Generator().manual_seed(self._seeds.get(key, self.run.seed))
        generators = [self._generators[key] for key in keys]
        return characters_noise(generators, self.step.sample.size, first).to(self.device)

    def _restart_teleported(self, keys: list, roots: np.ndarray) -> None:
        """Start afresh the characters whose pelvis jumped since their last push: their state rows
        zeroed (``started`` 0: their first frame) and their draw restarted from their seed, their
        cloth and seed kept (:meth:`CrowdStream._restart_teleported` does the same)."""
        for i in teleported(keys, [self._roots.get(k) for k in keys], roots, fps=FPS):
            slot = self._slots[keys[i]]
            for t in self._state.values():
                t[slot] = 0.0
            self._generators.pop(keys[i], None)

    def _slots_of(self, keys: list) -> torch.Tensor:
        """Each key's row of the state (new keys get a free row, zeroed: ``started`` 0)."""
        fresh = [k for k in keys if k not in self._slots]
        grow = len(fresh) - len(self._free)
        if grow > 0:  # room for the newcomers: the state's rows doubled at least
            start = len(self._state["started"])
            extra = max(grow, start)
            self._state = {
                name: torch.cat([t, torch.zeros((extra, *t.shape[1:]), device=self.device)])
                for name, t in self._state.items()
            }
            self._free += list(range(start + extra - 1, start - 1, -1))
        for key in fresh:
            slot = self._free.pop()
            self._slots[key] = slot
            for t in self._state.values():
                t[slot] = 0.0
        return torch.tensor([self._slots[k] for k in keys], device=self.device)

    @torch.no_grad()
    def push(
        self,
        rotations: np.ndarray,
        roots: np.ndarray,
        keys: Sequence[Hashable] | None = None,
        *,
        as_tensor: bool = False,
    ) -> np.ndarray | torch.Tensor:
        """One frame of N characters: ``rotations`` (N, 22, 4) local quaternions (x, y, z, w), ``roots``
        (N, 3) pelvis positions (metres, Y up), ``keys`` one id per character (default 0 .. N-1) ->
        (N, V, 3) world vertices, float32 (a tensor on the device with ``as_tensor``)."""
        rotations, roots = (
            torch.as_tensor(rotations, dtype=torch.float32),
            torch.as_tensor(roots, dtype=torch.float32),
        )
        keys = list(range(len(rotations))) if keys is None else list(keys)
        if rotations.shape[1:] != (NUM_JOINTS, 4) or roots.shape != (len(rotations), 3):
            raise InputError(
                "push",
                f"a device crowd takes (N, {NUM_JOINTS}, 4) quaternions and (N, 3) roots; got "
                f"{tuple(rotations.shape)} and {tuple(roots.shape)}",
            )
        check_keys(keys, len(rotations))
        if not (torch.isfinite(rotations).all() and torch.isfinite(roots).all()):
            raise InputError("push", "non-finite rotations or roots")
        host_roots = roots.double().cpu().numpy()
        self._restart_teleported(keys, host_roots)
        rows = self._slots_of(keys)
        state = [self._state[name][rows] for name in STATE]
        state.append(self._state[SETTLE_STATE][rows] if SETTLE_STATE in self._state else None)
        drawing = []
        if self.step.sample is not None:
            drawing = [self._white_noise(keys), *(self._state[name][rows] for name in SAMPLE_STATE)]
        out = self.step(
            rotations.to(self.device), roots.to(self.device), *state, *drawing, material=self._materials(keys)
        )
        for name, value in zip(self._shapes, out[3:]):
            self._state[name][rows] = value
        self._roots.update(zip(keys, host_roots))  # as the native crowd: once the frame has run
        return out[0] if as_tensor else out[0].cpu().numpy()
