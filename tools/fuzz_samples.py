"""The fuzzer's valid inputs and what a case is (tools/fuzz.py): a tiny model trained on the
simulator-free dataset, a native npz, an AMASS-style npz, a BVH and an out.h5, made once in the work
folder; a case's mutated input, the command that runs it and what its refusal must name."""

from __future__ import annotations

import hashlib
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TINY_CONFIG = """autoencoder:
  model: {channels: [8, 16]}
  train: {epochs: 2, batch_size: 16, max_minutes: null}
codespace:
  model: {groups: 16, classes: 4, embedding_dim: 4, hidden: 64, motion_hidden: 32, attention_heads: 2}
  train: {epochs: 2, learning_rate: 0.001, max_minutes: null}
"""


@dataclass
class Samples:
    """The valid inputs the mutations start from."""

    model: Path
    dataset: Path
    config: Path
    bvh: Path
    native: Path
    amass: Path
    animation: Path


def make_samples(folder: Path) -> Samples:
    """The inputs every mutation starts from; made once per work folder."""
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.cli.train import main as train_main
    from hrr_garment.data.synthetic import write_synthetic_dataset
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.bvh_write import write_bvh
    from hrr_garment.motion.io import save_amass, save_motion
    from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS
    from hrr_garment.motion.synth import synthesize

    s = Samples(
        folder / "model",
        folder / "skirt.h5",
        folder / "tiny.yaml",
        folder / "walk.bvh",
        folder / "walk.npz",
        folder / "walk_amass.npz",
        folder / "out.h5",
    )
    if all(p.exists() for p in asdict(s).values()):
        return s
    folder.mkdir(parents=True, exist_ok=True)
    motion = synthesize("walk", 2.0, seed=7)
    save_motion(motion, s.native)
    save_amass(motion, s.amass)
    write_bvh(
        s.bvh,
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        1 / 30,
    )
    write_synthetic_dataset(s.dataset, make_garment("skirt", 300))
    s.config.write_text(TINY_CONFIG)
    if (
        train_main(["--dataset", str(s.dataset), "--config", str(s.config), "-o", str(s.model), "--quiet"])
        != 0
    ):
        raise SystemExit("fuzz: could not train the sample model")
    if animate_main([str(s.native), "--model", str(s.model), "-o", str(s.animation)]) != 0:
        raise SystemExit("fuzz: could not animate the sample motion")
    return s


@dataclass
class Case:
    """One mutated input and the command that runs it."""

    number: int
    kind: str
    mutation: str
    command: list[str]
    output: Path
    names: list[str] = field(default_factory=list)  # file names an error line should mention (any one)
    keep: dict = field(default_factory=dict)  # inputs that must come out unchanged: path -> sha256
    interrupt: tuple | None = None  # (signal, seconds after the command starts working)
    env: dict = field(default_factory=dict)  # settings the command runs under (trusted keys and the like)


def _cli(module: str, *args: object) -> list[str]:
    return [
        sys.executable,
        "-c",
        f"import sys; from hrr_garment.cli.{module} import main; sys.exit(main())",
        *map(str, args),
    ]


def file_digest(path: Path) -> str:
    """A file's sha256: what an input that must come out unchanged is checked against."""
    return hashlib.sha256(path.read_bytes()).hexdigest()
