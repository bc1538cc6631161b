"""What a run is asked to do, as one settings object: :class:`DetailLook` and :class:`RunSettings`,
and :class:`~.resolved_run.ResolvedRun`, the same settings resolved against one model.

    settings = RunSettings(mode="detail", detail=DetailLook(base="residual", strength=1.0), body="hero.json")
    anim = animator.animate(motion, settings)              # or animator.animate(motion, mode="detail", ...)
    crowd = animator.crowd(settings.replace(push_out=False, device="native"))

A :class:`RunSettings` holds what the caller chose; a field left at None takes the model's
calibrated value (bundle.json). Values are checked when the object is made, so a bad tau or
strength is refused where it enters, naming the field. :meth:`RunSettings.resolve` fills in the
model's values once, against one bundle, and refuses what that model cannot run (a residual base
without a residual calibration, a named mode given another mode's settings). Everything below the
API (the gate, the streams, the evaluation, the calibration) takes the :class:`ResolvedRun`; out.h5
and report.json record :meth:`ResolvedRun.record`, written from this one place.

The settings hold the whole run request: the look (mode, gate, detail, swing), the push-out
(``push_out``, ``push``), the body and its exclusions (``body``, ``allow_outside``,
``exclude_sequence``), the arithmetic (``decoder``, ``precision``) and where a crowd runs
(``device``). New per-run choices (the material) arrive here as fields, not as new arguments on
every function that hands a run on. Each default is written once, here (:data:`DECODERS`,
:data:`PUSHES`, :data:`~hrr_garment.native.PRECISIONS`: the first of each).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..artifacts.gate_signals import GATE_SIGNALS
from ..artifacts.manifest import DETAIL_BASES, MAX_DETAIL_STRENGTH, BundleError, valid_detail_strength
from ..native import PRECISIONS
from .modes import Mode
from .resolved_run import ResolvedRun
from .run_material import run_material
from .settle import MAX_SETTLE_S, valid_settle
from .swing import MAX_GAIN, valid_gain

if TYPE_CHECKING:  # the bundle's models import torch, which a command that only reads settings does not need
    from ..artifacts.bundle import Bundle
    from .character_body import CharacterBody

DECODERS = (
    "full",
    "fast",
)  # the mesh autoencoder's decoder, or its distilled subspace decoder (models/subspace.py)
PUSHES = (
    "mesh",
    "subspace",
)  # the collision push-out alone, or after the push in the garment's subspace (subspace_push.py)

PUSH_BODIES = ("visible", "capsules")  # what the push-out pushes out of (RunSettings.push_body)
MAX_SEED = 2**32 - 1  # the sample mode's seeds: 0 .. MAX_SEED

#: keyword arguments of the API before the settings objects, and what replaced them
RENAMED = {"detail_base": "detail=DetailLook(base=...)", "detail_strength": "detail=DetailLook(strength=...)"}
#: old names of settings, still taken as keywords: old name -> the field
OLD_NAMES = {"collision": "push_out"}


def _new_names(changes: dict) -> dict:
    """``changes`` with old setting names (:data:`OLD_NAMES`) under their fields' names."""
    if not any(k in OLD_NAMES for k in changes):
        return changes
    out = {}
    for key, value in changes.items():
        name = OLD_NAMES.get(key, key)
        if name in out:
            raise TypeError(f"{key} is the old name of {name}: give one of them")
        out[name] = value
    return out


def _taking_old_names(cls):
    """The dataclass ``cls`` whose constructor also takes the old names of its fields."""
    init = cls.__init__

    def __init__(self, *args, **changes):
        init(self, *args, **_new_names(changes))

    __init__.__doc__, __init__.__wrapped__ = init.__doc__, init
    cls.__init__ = __init__
    return cls


def _number(value: object, what: str) -> float:
    """A real number as a Python float (numpy scalars included); a TypeError for anything else."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"{what} must be a number, got {type(value).__name__} {value!r}")
    return float(value)


@dataclass(frozen=True)
class DetailLook:
    """The detail mode's look: what its simulated folds ride on and how strong they are.

    ``base``: "regression" (the regression's shape) or "residual" (the residual mode's, which brings
    the matched window's swing); ``strength``: the folds at this multiple of their simulated size, in
    (0, 2] (1: as simulated). None takes the model's calibrated value (bundle.json ``auto``)."""

    base: str | None = None
    strength: float | None = None

    def __post_init__(self) -> None:
        if self.base is not None and self.base not in DETAIL_BASES:
            raise ValueError(f"the detail mode's base is one of {', '.join(DETAIL_BASES)}, got {self.base!r}")
        if self.strength is not None:
            strength = _number(self.strength, "the detail mode's strength")
            if not valid_detail_strength(strength):
                raise ValueError(
                    f"the detail mode's strength must be in (0, {MAX_DETAIL_STRENGTH:g}], got {strength!r}"
                )
            object.__setattr__(self, "strength", strength)

    @property
    def chosen(self) -> bool:
        """Whether the caller chose anything (a base or a strength)."""
        return self.base is not None or self.strength is not None


@_taking_old_names
@dataclass(frozen=True)
class RunSettings:
    """How to animate, as asked (see the module docstring). None: the model's calibrated value."""

    # auto (the model's calibrated choice) | hybrid | regression | retrieval | residual | detail |
    # naive-nn | direct (the baseline, offline only, where the bundle has it)
    mode: Mode | str = Mode.AUTO
    # the hybrid's gate signal (entropy | similarity | distance) and its threshold: with the default
    # mode, either one runs the hybrid, whose settings they are
    gate: str | None = None
    tau: float | None = None
    # the detail mode's look: with the default mode, a chosen look runs the detail mode
    detail: DetailLook = field(default_factory=DetailLook)
    push_out: bool = True  # the collision push-out against the body (old name: collision)
    causal: bool = False  # no future frames: what the streaming API gives
    # the mesh decoder: "full" (the autoencoder's) or "fast" (its distilled subspace decoder, a few
    # times cheaper: crowds in a game's budget; where the bundle has one). None: full
    decoder: str | None = None
    # how the push-out takes the cloth out of the body: "mesh" (each vertex to the nearest surface,
    # its tears limited) or "subspace" (first the whole garment along its fast decoder's principal
    # components, then the mesh push: fewer tears, about 2.5 x the push-out's cost; where the bundle
    # has a fast decoder; docs/decisions/0032). None: mesh
    push: str | None = None
    # what the push-out pushes the cloth out of: "visible" (the mesh the viewer sees, where the body
    # has one: an anny body's, a character's own; the mannequin's is its capsules) or "capsules"
    # (the 20 collision capsules: cheaper, but skin shows through where the mesh lies outside them);
    # the subspace push measures the same body. None: visible
    push_body: str | None = None
    # the hem's swing restored on free cloth (inference/swing.py): the gain on the latents' departure
    # from their recent course, 1: as predicted. None: the model's calibrated gain in the mode auto
    # picks, 1 in a mode named
    swing: float | None = None
    # the cloth settling after a stop (inference/settle.py): the time constant (s) of the latents'
    # lag towards the model's prediction, fading out over four of them after the stop; 0: none
    settle: float = 0.0
    # the body animated on: a body.json or character file's path, a BodyRecord, a CharacterBody, a
    # dataset's DressedBody (Animator.body); None: the model's own. ``allow_outside``: one unlike the
    # model's training bodies too (warned)
    body: object = field(default=None, hash=False)
    allow_outside: bool = False
    # the cloth animated: a Material, a fabric's name or values as --material takes them ("silk",
    # "density=0.12,bend=4e-6"), a mapping; None: the model's default cloth. A model across cloths
    # takes any within the range it was trained in (``allow_outside_material``: beyond it too,
    # warned); a model of one cloth, that cloth (inference/run_material.py)
    material: object = field(default=None, hash=False)
    allow_outside_material: bool = False
    exclude_sequence: int | None = None  # a database sequence retrieval may not use (evaluation)
    # the full mesh decoder's arithmetic for batches of frames: "float32" or "bfloat16" (AMX on recent
    # Intel Xeons, InferenceDecoder). None: float32
    precision: str | None = None
    # where a crowd runs: "native" (the CPU kernels), or a torch device ("cuda", "cpu": the regression
    # as one torch step, torch_crowd.py). None: CUDA for a regression crowd where torch sees a GPU
    device: str | None = None
    # the sample mode's draw: its seed (the same seed, the same cloth; another, another as likely)
    # and the generative decoder's integration steps a frame (None: the steps it was trained for)
    seed: int = 0
    sample_steps: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "mode", Mode(self.mode))
        if self.swing is not None:
            swing = _number(self.swing, "swing")
            if not valid_gain(swing):
                raise ValueError(
                    f"swing is a gain in (0, {MAX_GAIN:g}] (1: the swing as predicted), got {self.swing!r}"
                )
            object.__setattr__(self, "swing", swing)
        settle = _number(self.settle, "settle")
        if not valid_settle(settle):
            raise ValueError(
                f"settle is a time constant in [0, {MAX_SETTLE_S:g}] seconds (0: no lag), got {self.settle!r}"
            )
        object.__setattr__(self, "settle", settle)
        if self.gate is not None and self.gate not in GATE_SIGNALS:
            raise ValueError(f"gate must be one of {', '.join(GATE_SIGNALS)}, got {self.gate!r}")
        if self.tau is not None:
            tau = _number(self.tau, "tau")
            if not math.isfinite(tau) or tau < 0:
                raise ValueError(
                    f"tau must be a finite number >= 0 (the gate's doubt is never negative), got {tau!r}"
                )
            object.__setattr__(self, "tau", tau)
        if self.decoder is not None and self.decoder not in DECODERS:
            raise ValueError(f"decoder must be one of {', '.join(DECODERS)}, got {self.decoder!r}")
        if self.push is not None and self.push not in PUSHES:
            raise ValueError(f"push must be one of {', '.join(PUSHES)}, got {self.push!r}")
        if self.push_body is not None and self.push_body not in PUSH_BODIES:
            raise ValueError(f"push_body must be one of {', '.join(PUSH_BODIES)}, got {self.push_body!r}")
        if not isinstance(self.detail, DetailLook):
            raise TypeError(f"detail must be a DetailLook, got {type(self.detail).__name__}")
        if self.precision is not None and self.precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {self.precision!r}")
        if self.device is not None and not isinstance(self.device, str):
            raise TypeError(f"device must be a name such as 'native' or 'cuda', got {self.device!r}")
        object.__setattr__(self, "seed", whole_number(self.seed, "seed", bounds=(0, MAX_SEED)))
        if self.sample_steps is not None:
            object.__setattr__(
                self, "sample_steps", whole_number(self.sample_steps, "sample_steps", bounds=(1, 64))
            )
        if self.sample_steps is not None and self.mode not in (Mode.SAMPLE, Mode.AUTO):
            raise ValueError(f"sample_steps sets the sample mode's draw; mode {self.mode.value} draws none")
        for name in ("push_out", "causal", "allow_outside", "allow_outside_material"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name} must be True or False, got {value!r}")
            object.__setattr__(self, name, bool(value))
        if self.mode is Mode.AUTO and self.hybrid_chosen and self.detail.chosen:
            raise ValueError(
                "a gate or tau sets the hybrid and a detail base or strength the detail mode: name the mode"
            )
        if self.detail.chosen and self.mode not in (Mode.AUTO, Mode.DETAIL):
            raise ValueError(
                f"a detail base or strength sets the detail mode; mode {self.mode.value} does not use them"
            )

    @property
    def hybrid_chosen(self) -> bool:
        """Whether the caller chose a gate or a tau (the hybrid's settings)."""
        return self.gate is not None or self.tau is not None

    def replace(self, **changes) -> RunSettings:
        """A copy with ``changes`` (field names, or their :data:`OLD_NAMES`); a TypeError naming any
        other keyword."""
        changes = _new_names(changes)
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            hints = [f"{k} (now {RENAMED[k]})" for k in unknown if k in RENAMED]
            raise TypeError(
                f"unknown run setting(s) {', '.join(unknown)}; the settings are "
                f"{', '.join(f.name for f in dataclasses.fields(self))}"
                + (f": {'; '.join(hints)}" if hints else "")
            )
        return dataclasses.replace(self, **changes) if changes else self

    def resolve(self, bundle: Bundle, body: CharacterBody) -> ResolvedRun:
        """These settings with the model's calibrated values filled in, checked against ``bundle``;
        ``body``: :attr:`body` made ready for the model (:meth:`~.animator.Animator.body`)."""
        mode, calibrated = self.mode, False
        if mode is Mode.AUTO:
            calibrated = not (self.hybrid_chosen or self.detail.chosen)
            mode = (
                Mode.HYBRID
                if self.hybrid_chosen
                else Mode.DETAIL
                if self.detail.chosen
                else Mode(bundle.auto_mode)
            )
        gate = bundle.gate if self.gate is None else self.gate
        tau = bundle.gate_tau(gate) if self.tau is None else self.tau
        look = None
        if mode is Mode.DETAIL:
            bundle.require_folds()
            look = DetailLook(
                bundle.detail_base if self.detail.base is None else self.detail.base,
                bundle.detail_strength if self.detail.strength is None else self.detail.strength,
            )
            if look.base == "residual":
                bundle.require_residual()
                if bundle.residual_weight <= 0:
                    raise BundleError(
                        bundle.folder,
                        "its residual weight is calibrated to 0, so the residual mode is "
                        "the regression: run the detail mode on the regression",
                    )
        elif mode is Mode.RESIDUAL:
            bundle.require_residual()
        elif mode is Mode.SAMPLE:
            bundle.require_sampler()
        decoder = self.decoder or DECODERS[0]
        if decoder == "fast":
            bundle.require_subspace()
        push = self.push or PUSHES[0]
        if push == "subspace":
            bundle.require_subspace("the subspace push")
        push_body = self.push_body or PUSH_BODIES[0]
        swing = self.swing if self.swing is not None else bundle.swing_gain if calibrated else 1.0
        return ResolvedRun(
            mode=mode,
            gate=gate,
            tau=tau,
            detail=look,
            push_out=self.push_out,
            causal=self.causal or mode is Mode.SAMPLE,  # a sample is drawn frame after frame
            decoder=decoder,
            swing=swing,
            settle=self.settle,
            push=push,
            push_body=push_body,
            body=body,
            exclude_sequence=database_sequence(bundle, self.exclude_sequence),
            precision=self.precision or PRECISIONS[0],
            device=self.device,
            seed=self.seed,
            sample_steps=(self.sample_steps or bundle.sampler.config.steps) if mode is Mode.SAMPLE else None,
            material=run_material(bundle, self.material, self.allow_outside_material),
        )


def whole_number(value: object, name: str, *, bounds: tuple[int, int]) -> int:
    """``value`` as an int (a numpy integer too); a ValueError naming ``name`` and the range unless
    it is a whole number in ``bounds`` (both included; a bool is not)."""
    least, most = bounds
    if isinstance(value, np.integer):
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or not least <= value <= most:
        raise ValueError(f"{name} must be a whole number in [{least}, {most}], got {value!r}")
    return value


def database_sequence(bundle: Bundle, index: object) -> int | None:
    """``index`` (None: none) as one of ``bundle``'s database sequences; a ValueError naming the range."""
    if index is None:
        return None
    if isinstance(index, np.integer):
        index = int(index)
    count = len(bundle.database.names)
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < count:
        raise ValueError(
            f"exclude_sequence must be a database sequence index in 0..{count - 1}, got {index!r}"
        )
    return index


def run_settings(settings: RunSettings | None, changes: dict) -> RunSettings:
    """``settings`` (default :class:`RunSettings`) with the API call's keyword ``changes``."""
    if settings is not None and not isinstance(settings, RunSettings):
        raise TypeError(
            f"settings must be a RunSettings, got {type(settings).__name__} (modes go as mode=...)"
        )
    return (settings or RunSettings()).replace(**changes)
