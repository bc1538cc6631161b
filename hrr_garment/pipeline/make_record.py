"""hrr-make's record of a run, ``OUT/make.json``: what was asked, what each stage was made from (its
key) and took, and the plan, so that a re-run goes on where the last one stopped and redoes exactly
the stages whose inputs changed.

    record = MakeRecord.open(out)
    if not record.current("body", key):
        ...                                   # fit the character
        record.finish("body", key, seconds, notes={...})

A stage's key hashes its own inputs and the keys of the stages it is made from, so a changed
garment changes the keys of the dataset, the model and the outputs and of nothing before them. The
file is rewritten atomically after every stage; one written by a later format is refused rather than
misread.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from ..io_utils import atomic_write_text, strict_json
from .make_budget import OUTPUT_STAGES

MAKE_RECORD_FORMAT = 1
RECORD_NAME = "make.json"


def content_key(parts: list) -> str:
    """A short, stable hash of ``parts`` (JSON-able values: paths as strings, other keys, settings)."""
    text = json.dumps([str(p) if isinstance(p, Path) else p for p in parts], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def file_key(path: Path) -> str:
    """The hash of a file's bytes (what a stage read, not where it lay)."""
    digest = hashlib.sha256()
    with Path(path).open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()[:16]


@dataclass(frozen=True)
class MakeRequest:
    """What the user asked hrr-make for (the command line's options)."""

    character: Path  # a skinned .glb / .gltf, or a body.json
    garment: str  # a built-in template's name, or an OBJ modelled on the character
    out: Path
    budget_s: float = 3600.0
    library: str = "real-quick-commercial"
    attached: str = "auto"  # the OBJ's group that follows the body ('auto': the band on the torso)
    fit: bool = False  # the OBJ is in another convention: detect its unit and up axis
    made_for: Path | None = (
        None  # the body the OBJ was modelled on (body.json, a body mesh OBJ); None: the character
    )
    selection: str = "coverage"
    jobs: int | None = None
    device: str | None = None
    batch: int = 0  # sequences simulated together in one model (a GPU: hrr-simulate --batch)
    progress: bool = True
    seed: int = 0
    skip: tuple[str, ...] = ()  # outputs not to make: any of OUTPUT_STAGES
    # the cloth the library is simulated in (a fabric, values, a material file; None: the preset's)
    # the air's drag coefficient and the cloth's viscosity, m^2/s (None: the preset's)
    material: str | None = None
    air_drag: float | None = None
    cloth_viscosity: float | None = None

    def to_dict(self) -> dict:
        return {k: str(v) if isinstance(v, Path) else v for k, v in self.__dict__.items()}

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(s for s in OUTPUT_STAGES if s not in self.skip)


@dataclass
class MakeRecord:
    """``OUT/make.json`` (see the module docstring)."""

    folder: Path
    request: dict = field(default_factory=dict)
    stages: dict[str, dict] = field(default_factory=dict)  # name -> key, seconds, estimate_s, notes
    plan: dict = field(default_factory=dict)  # the budget's plan and the selection, once made

    @property
    def path(self) -> Path:
        return self.folder / RECORD_NAME

    @classmethod
    def open(cls, folder: Path) -> "MakeRecord":
        """The record in ``folder``, or a new one where there is none."""
        path = Path(folder) / RECORD_NAME
        if not path.exists():
            return cls(Path(folder))
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(path, f"cannot read hrr-make's record: {exc}; remove it to start over") from None
        if not isinstance(data, dict) or data.get("format", 0) > MAKE_RECORD_FORMAT:
            raise InputError(path, "was written by a newer hrr-make (or is not its record)")
        return cls(Path(folder), data.get("request", {}), data.get("stages", {}), data.get("plan", {}))

    def current(self, stage: str, key: str) -> bool:
        """Whether ``stage`` finished from the inputs ``key`` names."""
        return self.stages.get(stage, {}).get("key") == key and "seconds" in self.stages[stage]

    def finish(self, stage: str, key: str, seconds: float, notes: dict | None = None) -> None:
        """Record ``stage`` finished from ``key`` in ``seconds`` (its estimate, where the plan made one,
        kept beside), and write the record."""
        estimate = self.plan.get("estimates", {}).get(stage)
        entry = {"key": key, "seconds": round(seconds, 1), **({"estimate_s": estimate} if estimate else {})}
        self.stages[stage] = {**entry, **(notes or {})}
        self.write()

    def forget(self, stages: list[str]) -> None:
        """Drop the records of ``stages`` (their inputs changed)."""
        for stage in stages:
            self.stages.pop(stage, None)
        self.write()

    def write(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        data = {
            "format": MAKE_RECORD_FORMAT,
            "request": self.request,
            "stages": self.stages,
            "plan": self.plan,
        }
        atomic_write_text(self.path, strict_json(data, indent=2, default=str))
