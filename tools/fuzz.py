"""Fuzz the command-line tools: mutate sample inputs, run the real CLIs, classify what they do.

    python tools/fuzz.py --cases 1000 --jobs 2            # report in hrr_work/fuzz/report.{json,md}

Sample inputs are made first (a tiny model trained on the simulator-free dataset, a native npz, an
AMASS-style npz, a BVH, an out.h5) unless they are already in the work folder. Each case copies
one, applies one to three mutations chosen by a seeded random generator (so ``--seed`` and the case
number reproduce it) and runs one CLI on it in a fresh output folder, with a time limit and a memory
limit. Outcomes:

- ``clean error``: exit 2, one ``error:`` line, no traceback, nothing at the output path;
- ``ok``: exit 0 and an output that reads back finite and plausible (a garment near the body);
- failures: ``traceback`` (or any other exit status, a crash), ``hang`` (past the time limit),
  ``memory`` (killed, or MemoryError), ``bad output`` (exit 0 with a non-finite or absurd result),
  ``partial file`` (a failed run that left its output or a temporary file), and ``vague error``
  (a clean error whose line names neither the input nor the output, or that warnings precede).

Failing cases are kept under ``WORK/failures/`` with their command, for reproduction.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from fuzz_doors import DOOR_KINDS, door_case, make_door_samples, unlock
from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
FAILURES = ("traceback", "hang", "memory", "bad output", "partial file", "lost input", "vague error")
TINY_CONFIG = """autoencoder:
  model: {channels: [8, 16]}
  train: {epochs: 2, batch_size: 16, max_minutes: null}
codespace:
  model: {groups: 16, classes: 4, embedding_dim: 4, hidden: 64, motion_hidden: 32, attention_heads: 2}
  train: {epochs: 2, learning_rate: 0.001, max_minutes: null}
"""


# ----------------------------------------------------------------------------- sample inputs


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


# ----------------------------------------------------------------------------- mutations

EXTREMES = [
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "-inf",
    "0",
    "-0",
    "1e6",
    "-1e6",
    "1e-300",
    "99999999999999999999",
    "1e20",
    "-1",
]


def _numbers(text: str) -> list[re.Match]:
    return list(re.finditer(r"(?<![A-Za-z_])-?\d+(\.\d+)?(e-?\d+)?", text))


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def mutate_text(text: str, rng: np.random.Generator) -> tuple[str, str]:
    """One mutation of a BVH's text: (mutated text, what was done)."""
    lines = text.split("\n")
    kind = rng.choice(
        [
            "number",
            "numbers",
            "delete line",
            "duplicate line",
            "truncate",
            "channels",
            "frame time",
            "frames",
            "nesting",
            "brace",
            "offsets",
            "keyword",
            "swap lines",
        ]
    )
    if kind in ("number", "numbers"):
        found = _numbers(text)
        for m in sorted(
            rng.choice(found, size=min(len(found), 1 if kind == "number" else 50), replace=False),
            key=lambda m: -m.start(),
        ):
            text = text[: m.start()] + str(rng.choice(EXTREMES)) + text[m.end() :]
        return text, kind
    if kind == "delete line":
        i = int(rng.integers(len(lines)))
        return "\n".join(lines[:i] + lines[i + 1 :]), f"{kind} {i}"
    if kind == "duplicate line":
        i = int(rng.integers(len(lines)))
        return "\n".join(lines[: i + 1] + lines[i:]), f"{kind} {i}"
    if kind == "swap lines":
        i, j = rng.integers(len(lines), size=2)
        lines[i], lines[j] = lines[j], lines[i]
        return "\n".join(lines), f"{kind} {i} {j}"
    if kind == "truncate":
        return text[: int(rng.integers(len(text)))], kind
    if kind == "channels":
        names = [
            "Xrotation",
            "Yrotation",
            "Zrotation",
            "Xposition",
            "Yposition",
            "Zposition",
            "Wrotation",
            "x",
        ]
        idx = [i for i, ln in enumerate(lines) if "CHANNELS" in ln]
        i = int(rng.choice(idx))
        parts = lines[i].split()
        if len(parts) > 2:
            parts[int(rng.integers(2, len(parts)))] = str(rng.choice(names))
        if rng.random() < 0.3:
            parts[1] = str(rng.choice(["0", "-3", "7", "1000000", "x"]))
        lines[i] = " ".join(parts)
        return "\n".join(lines), kind
    if kind == "frame time":
        value = rng.choice(["0", "-0.0333", "1e300", "100", "1e-9", "nan", "abc", "2"])
        return re.sub(r"Frame Time:.*", f"Frame Time: {value}", text), f"{kind} {value}"
    if kind == "frames":
        value = rng.choice(["0", "-1", "1000000000", "61", "59", "x", "1e3"])
        return re.sub(r"Frames:.*", f"Frames: {value}", text), f"{kind} {value}"
    if kind == "nesting":
        depth = int(rng.choice([65, 300, 5000]))
        chain = "".join(
            f"JOINT j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" for k in range(depth)
        )
        at = text.index("JOINT")
        return text[:at] + chain + "}\n" * depth + text[at:], f"{kind} {depth}"
    if kind == "brace":
        idx = [i for i, ln in enumerate(lines) if ln.strip() in ("{", "}")]
        i = int(rng.choice(idx))
        return "\n".join(lines[:i] + lines[i + 1 :]), kind
    if kind == "offsets":
        factor = float(rng.choice([-1.0, 0.0, 1e6, 1e-6, 1e308]))
        out = []
        for ln in lines:
            if ln.strip().startswith("OFFSET"):
                vals = [float(v) * factor if _is_number(v) else v for v in ln.split()[1:]]
                ln = "OFFSET " + " ".join(map(str, vals))
            out.append(ln)
        return "\n".join(out), f"{kind} x{factor:g}"
    word = str(rng.choice(["HIERARCHY", "ROOT", "JOINT", "End Site", "MOTION", "OFFSET"]))
    return text.replace(word, str(rng.choice(["", "Joint", "ROOT", "\x00"])), 1), f"keyword {word}"


def mutate_bytes(data: bytes, rng: np.random.Generator) -> tuple[bytes, str]:
    """Byte-level damage for any file: flips, truncation, an empty file, random bytes."""
    kind = rng.choice(["flip", "truncate", "empty", "random"], p=[0.6, 0.25, 0.05, 0.1])
    if not data and kind in ("flip", "truncate"):
        kind = "random"  # nothing left to damage
    if kind == "flip":
        buf = bytearray(data)
        n = int(rng.integers(1, 64))
        for i in rng.integers(len(buf), size=n):
            buf[i] = int(rng.integers(256))
        return bytes(buf), f"flip {n} bytes"
    if kind == "truncate":
        return data[: int(rng.integers(len(data)))], kind
    if kind == "empty":
        return b"", kind
    return rng.bytes(int(rng.integers(1, 4096))), kind


def mutate_arrays(arrays: dict, rng: np.random.Generator) -> tuple[dict, str]:
    """One mutation of an npz's arrays."""
    arrays = dict(arrays)
    key = str(rng.choice(sorted(arrays)))
    a = arrays[key]
    kind = rng.choice(["drop", "nan", "scale", "zero", "shape", "empty", "dtype", "value", "extra", "object"])
    if kind == "drop":
        del arrays[key]
    elif kind == "nan" and a.dtype.kind == "f" and a.size:
        a = a.copy()
        a.flat[int(rng.integers(a.size))] = rng.choice([np.nan, np.inf, -np.inf])
        arrays[key] = a
    elif kind == "scale" and a.dtype.kind in "fi":
        arrays[key] = a * float(rng.choice([1e3, -1.0, 1e300, 1e-300, 0.5]))
    elif kind == "zero":
        arrays[key] = np.zeros_like(a)
    elif kind == "shape" and a.ndim:
        arrays[key] = (
            a.reshape(-1)[: max(0, a.size - int(rng.integers(1, 4)))] if rng.random() < 0.5 else a[..., None]
        )
    elif kind == "empty" and a.ndim:
        arrays[key] = a[: int(rng.integers(0, 2))]
    elif kind == "dtype":
        dtype = rng.choice(["bool", "complex64", "int8", "U8", "S4", "datetime64[s]", "float16"])
        try:
            arrays[key] = a.astype(dtype)
        except (TypeError, ValueError):
            arrays[key] = np.zeros(a.shape, dtype)
    elif kind == "value":
        arrays[key] = np.array(rng.choice([0, -1, np.nan, np.inf, 1e-6, 1e9, "abc", 1j]))
    elif kind == "extra":
        arrays["surplus"] = rng.random((3, 3))
    else:
        arrays[key] = np.array([a, "x"], dtype=object) if a.ndim == 0 else a.astype(object)
    return arrays, f"{kind} {key}"


def _save_npz(path: Path, arrays: dict) -> None:
    with open(path, "wb") as fh:  # np.savez pickles object arrays: a hostile file, as intended
        np.savez(fh, **arrays)


def mutate_bundle(src: Path, dst: Path, rng: np.random.Generator) -> str:
    """Copy the model bundle and tamper with it."""
    import hashlib

    from safetensors.numpy import load_file, save_file

    from hrr_garment.artifacts.manifest import manifest_hash

    shutil.copytree(src, dst)
    meta_path = dst / "bundle.json"
    meta = json.loads(meta_path.read_text())
    files = sorted(meta["files"])

    def rehash(name: str) -> None:  # what a forger does: every hash recomputed (a hash is not a signature)
        meta["files"][name] = hashlib.sha256((dst / name).read_bytes()).hexdigest()
        meta["content_hash"] = hashlib.sha256(json.dumps(meta["files"], sort_keys=True).encode()).hexdigest()[
            :16
        ]
        meta["manifest_hash"] = manifest_hash(meta)

    # (hostile values in its fields, re-hashed: mutate_manifest)
    kind = rng.choice(
        [
            "drop key",
            "drop files",
            "drop entry",
            "edit hash",
            "escape",
            "json bytes",
            "file bytes",
            "file bytes rehashed",
            "nan weights",
            "delete file",
            "list",
        ]
    )
    if kind == "drop key":
        key = str(rng.choice(sorted(meta)))
        del meta[key]
        kind = f"{kind} {key}"
    elif kind == "drop files":
        del meta["files"]
    elif kind == "drop entry":
        del meta["files"][str(rng.choice(files))]
    elif kind == "edit hash":
        meta["content_hash"] = "0" * 16
    elif kind == "escape":
        meta["files"]["../../../../etc/hostname"] = (
            hashlib.sha256(Path("/etc/hostname").read_bytes()).hexdigest()
            if Path("/etc/hostname").exists()
            else "0" * 64
        )
    elif kind == "list":
        meta = [meta]
    if kind in ("json bytes",):
        meta_path.write_bytes(mutate_bytes(meta_path.read_bytes(), rng)[0])
        return kind
    if kind in ("file bytes", "file bytes rehashed", "nan weights", "delete file"):
        name = str(rng.choice(files))
        if kind == "delete file":
            (dst / name).unlink()
        elif kind == "nan weights":
            tensors = load_file(dst / name)
            floats = [k for k, v in tensors.items() if v.dtype.kind == "f" and v.size]
            if floats:
                k = str(rng.choice(floats))
                tensors[k] = tensors[k].copy()
                tensors[k].flat[int(rng.integers(tensors[k].size))] = np.nan
            save_file(tensors, dst / name)
            rehash(name)
        else:
            (dst / name).write_bytes(mutate_bytes((dst / name).read_bytes(), rng)[0])
            if kind == "file bytes rehashed":
                rehash(name)
        kind = f"{kind} {name}"
    meta_path.write_text(json.dumps(meta, indent=2))
    return kind


def mutate_h5(src: Path, dst: Path, rng: np.random.Generator, arrays: tuple[str, ...]) -> str:
    """Copy an HDF5 file (a dataset or an out.h5) and damage it: its bytes, its arrays or its attributes."""
    import h5py

    kind = rng.choice(["bytes", "nan", "delete", "shape", "attribute", "scale"])
    if kind == "bytes":
        data, what = mutate_bytes(src.read_bytes(), rng)
        dst.write_bytes(data)
        return what
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        names: list[str] = []
        f.visit(
            lambda n: (
                names.append(n) if isinstance(f[n], h5py.Dataset) and n.split("/")[-1] in arrays else None
            )
        )
        name = str(rng.choice(names))
        d = f[name]
        if kind == "nan" and d.dtype.kind == "f":
            v = d[()]
            v.flat[int(rng.integers(v.size))] = np.nan
            d[...] = v
        elif kind == "scale" and d.dtype.kind in "fi":
            d[...] = d[()] * float(rng.choice([1e6, -1, 0]))
        elif kind == "shape":
            v = d[()]
            del f[name]
            f[name] = v[..., :-1] if v.ndim > 1 else v[:-1]
        elif kind == "attribute":
            holder = f[name].parent if rng.random() < 0.5 else f
            attrs = list(holder.attrs)
            if attrs:
                holder.attrs[str(rng.choice(attrs))] = str(rng.choice(["{not json", "-1", "nan", "[]"]))
        else:
            del f[name]
        return f"{kind} {name}"


# bundle.json leaves a forger may change (every hash recomputed) and what it may put there
MANIFEST_SKIP = {"files", "content_hash", "manifest_hash"}
HOSTILE_VALUES = [
    1e6,
    -5,
    0,
    1e308,
    -1e308,
    float("nan"),
    float("inf"),
    "x",
    "",
    None,
    [1, 2],
    {"a": 1},
    True,
    "dress",
    "skirt",
    2**63,
    0.5,
    1e-300,
]


def _leaves(meta: dict, prefix: tuple = ()) -> list[tuple]:
    out = []
    for key, value in meta.items():
        if not prefix and key in MANIFEST_SKIP:
            continue
        if isinstance(value, dict) and value:
            out += _leaves(value, (*prefix, key))
        else:
            out.append((*prefix, key))
    return out


def mutate_manifest(src: Path, dst: Path, rng: np.random.Generator) -> str:
    """Copy the model bundle and set one field of bundle.json to a hostile value with the manifest
    hash recomputed, as a forger would: only the load's own checks stand between it and a run."""
    from hrr_garment.artifacts.manifest import manifest_hash

    shutil.copytree(src, dst)
    meta = json.loads((dst / "bundle.json").read_text())
    leaves = _leaves(meta)
    path = leaves[int(rng.integers(len(leaves)))]
    value = HOSTILE_VALUES[int(rng.integers(len(HOSTILE_VALUES)))]
    holder = meta
    for key in path[:-1]:
        holder = holder[key]
    holder[path[-1]] = value
    meta["manifest_hash"] = manifest_hash(meta)
    (dst / "bundle.json").write_text(json.dumps(meta, indent=2))
    return f"{'.'.join(path)} = {value!r}"


# Python API calls with a hostile value V (an expression), each with the words its refusal should use
API_PRELUDE = """
import sys, warnings
import numpy as np
from hrr_garment.inference.animator import Animator
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.motion import Motion
animator, clip, out = Animator.load(sys.argv[1]), load_motion(sys.argv[2]), sys.argv[3]
R, T = clip.local_rotations, clip.root_translation
def save(vertices, root):  # relative to the pelvis: check_output judges the reach
    np.save(out, np.asarray(vertices, np.float64) - np.asarray(root, np.float64).reshape(-1, 1, 3))
try:
{call}
except (ValueError, TypeError, KeyError) as exc:
    print(f"api: error: {{type(exc).__name__}}: {{exc}}", file=sys.stderr)
    sys.exit(2)
"""
API_CALLS = {
    "stream root": (
        "v = animator.stream().push(rotation=R[0], root=V); save(v[None], V)",
        ["root"],
        [
            "[1e39, 0.95, 0]",
            "[1e30, 0.95, 0]",
            "[np.nan, 0.9, 0]",
            "[1, 2]",
            "'abc'",
            "[[0, 0.9, 0]] * 2",
            "np.array([0, 0.9, 0], complex)",
            "[1e4 - 1, 0.9, 0]",
        ],
    ),
    "stream rotation": (
        "v = animator.stream().push(rotation=V, root=T[0]); save(v[None], T[0])",
        ["rotation", "quaternion", "axis-angle", "matrix"],
        [
            "R[0] * 1000",
            "np.full((22, 4), 1e39)",
            "np.zeros((22, 4))",
            "np.full((22, 3), 1e39)",
            "R[0].astype(complex)",
            "np.ones((21, 4))",
            "np.full((22, 3), np.nan)",
            "-R[0]",
            "np.random.default_rng(0).normal(size=(22, 3, 3))",
        ],
    ),
    "teleport": (
        "s = animator.stream()\n    for t in range(5): s.push(rotation=R[t], root=T[t])\n"
        "    root = T[5] + np.array(V, float)\n    v = s.push(rotation=R[5], root=root); save(v[None], root)",
        ["root"],
        ["[50, 0, 0]", "[1e38, 0, 0]", "[0, 3, 0]", "[9000, 0, 0]", "[0.01, 0, 0]"],
    ),
    "motion fps": (
        "m = Motion(R, T, fps=V); a = animator.animate(m); save(a.vertices, a.joints[:, 0])",
        ["frame rate"],
        ["1e-300", "1e300", "0", "-30", "np.nan", "'30'", "True", "None", "complex(30, 1)"],
    ),
    "motion root": (
        "r = T.copy(); r[3] = V; a = animator.animate(Motion(R, r, fps=clip.fps)); "
        "save(a.vertices, a.joints[:, 0])",
        ["pelvis", "non-finite", "root"],
        ["1e39", "1e30", "np.nan", "[1e5, 0, 0]", "-np.inf"],
    ),
    "motion rotation": (
        "q = R.copy(); q[3, 5] = V; a = animator.animate(Motion(q, T, fps=clip.fps)); "
        "save(a.vertices, a.joints[:, 0])",
        ["rotation", "non-finite"],
        ["q[3, 5] * 1000", "0", "np.nan", "-q[3, 5]", "np.diag([1, 1, -1])"],
    ),
    "motion edited": (
        "clip.local_rotations[3, 5] = V\n    a = animator.animate(clip); save(a.vertices, a.joints[:, 0])",
        ["read-only"],
        ["np.nan", "0", "R[3, 5] * 1000"],
    ),
    "tau": (
        "a = animator.animate(clip, tau=V); save(a.vertices, a.joints[:, 0])",
        ["tau"],
        ["np.nan", "-1", "np.inf", "'x'", "None", "1e308", "0.0", "True"],
    ),
    "exclude_sequence": (
        "a = animator.animate(clip, mode='retrieval', exclude_sequence=V); save(a.vertices, a.joints[:, 0])",
        ["exclude_sequence"],
        ["999", "-1", "1.5", "'x'", "True", "0", "np.int64(1)", "2**63"],
    ),
}


def _api_case(number: int, samples: Samples, out: Path, rng: np.random.Generator) -> Case:
    name = str(rng.choice(sorted(API_CALLS)))
    call, words, values = API_CALLS[name]
    value = values[int(rng.integers(len(values)))]
    code = API_PRELUDE.format(call="    " + call.replace("V", f"({value})"))
    return Case(
        number,
        "api",
        f"{name}: {value}",
        [sys.executable, "-c", code, str(samples.model), str(samples.native), str(out / "api.npy")],
        out / "api.npy",
        words,
    )


def _output_is_input_case(number: int, samples: Samples, folder: Path, rng: np.random.Generator) -> Case:
    """An output path that is (or links to) an input: refused, the input untouched."""
    anim, clip, bvh = folder / "in.h5", folder / "clip.npz", folder / "clip.bvh"
    shutil.copy(samples.animation, anim)
    shutil.copy(samples.native, clip)
    shutil.copy(samples.bvh, bvh)
    (folder / "link.glb").symlink_to(anim)
    choices = {
        "export onto its input": (_cli("export", anim, "--to", "glb", "-o", anim), anim),
        "export pc2 onto its input": (_cli("export", anim, "--to", "pc2", "-o", anim), anim),
        "export through a link to its input": (
            _cli("export", anim, "-o", folder / "link.glb"),
            folder / "link.glb",
        ),
        "preview onto its input": (_cli("preview", anim, "-o", anim, "--size", 64, "--frames", 2), anim),
        "animate onto its motion": (_cli("animate", clip, "--model", samples.model, "-o", clip), clip),
        "features onto its motion": (_cli("motion", "features", bvh, "-o", bvh), bvh),
        "synth over a bvh": (_cli("motion", "synth", "walk", "-o", bvh), bvh),
        "animate onto the model": (
            _cli("animate", clip, "--model", samples.model, "-o", samples.model / "bundle.json"),
            samples.model / "bundle.json",
        ),
    }
    what = str(rng.choice(sorted(choices)))
    command, target = choices[what]
    case = Case(number, "output = input", what, command, target, [target.name])
    case.keep = {str(p): _digest(p) for p in (anim, clip, bvh, samples.model / "bundle.json")}
    return case


def _digest(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def _interrupt_case(number: int, samples: Samples, out: Path, rng: np.random.Generator) -> Case:
    """Ctrl-C or SIGTERM while a command works: exit 130 / 143, nothing at the output, no temporary file."""
    sig = int(rng.choice([signal.SIGINT, signal.SIGTERM]))
    if rng.random() < 0.6:
        command, target = (
            _cli("animate", samples.native, "--model", samples.model, "-o", out / "out.h5"),
            out / "out.h5",
        )
    else:
        command, target = _cli("preview", samples.animation, "-o", out / "a.mp4", "--size", 96), out / "a.mp4"
    delay = float(rng.uniform(0.0, 1.5))
    case = Case(
        number,
        "interrupt",
        f"{signal.Signals(sig).name} {delay:.2f} s into {command[3]}",
        command,
        target,
        [target.name],
    )
    case.interrupt = (sig, delay)
    return case


# ----------------------------------------------------------------------------- cases


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


KINDS = {
    "bvh": 0.22,
    "native npz": 0.08,
    "amass npz": 0.08,
    "bundle": 0.1,
    "manifest": 0.08,
    "dataset": 0.08,
    "animation": 0.08,
    "api": 0.12,
    "output path": 0.05,
    "output = input": 0.06,
    "interrupt": 0.05,
    **DOOR_KINDS,
}


def make_case(number: int, samples: Samples, work: Path, rng: np.random.Generator) -> Case:
    kind = str(rng.choice(list(KINDS), p=np.array(list(KINDS.values())) / sum(KINDS.values())))
    folder = work / "cases" / f"{number:05d}"
    shutil.rmtree(folder, ignore_errors=True)
    (folder / "out").mkdir(parents=True)
    out = folder / "out"
    if kind == "bvh":
        return _bvh_case(number, samples, folder, rng)
    if kind in ("native npz", "amass npz"):
        seed = samples.native if kind == "native npz" else samples.amass
        src = folder / "clip.npz"
        if rng.random() < 0.2:
            data, what = mutate_bytes(seed.read_bytes(), rng)
            src.write_bytes(data)
        else:
            with np.load(seed) as z:
                arrays = dict(z)
            done = []
            for _ in range(int(rng.integers(1, 3))):
                arrays, w = mutate_arrays(arrays, rng)
                done.append(w)
            _save_npz(src, arrays)
            what = "; ".join(done)
        return _motion_case(number, kind, what, src, samples, out, rng)
    if kind == "bundle":
        what = mutate_bundle(samples.model, folder / "model", rng)
        return Case(
            number,
            kind,
            what,
            _cli("animate", samples.native, "--model", folder / "model", "-o", out / "out.h5"),
            out / "out.h5",
            ["model"],
        )
    if kind == "dataset":
        src = folder / "skirt.h5"
        what = mutate_h5(
            samples.dataset,
            src,
            rng,
            (
                "garment",
                "joints",
                "local_rotations",
                "root_translation",
                "vertices",
                "faces",
                "attached",
                "test",
                "train",
                "val",
            ),
        )
        if rng.random() < 0.3:
            return Case(
                number,
                kind,
                what,
                _cli("train", "--dataset", src, "--config", samples.config, "-o", out / "model", "--quiet"),
                out / "model",
                [src.name],
            )
        return Case(
            number,
            kind,
            what,
            _cli(
                "eval",
                "--model",
                samples.model,
                "--dataset",
                src,
                "--ensemble",
                0,
                "--no-sweep",
                "--no-plots",
                "--quiet",
                "-o",
                out / "report",
            ),
            out / "report",
            [src.name],
        )
    if kind == "animation":
        src = folder / "out.h5"
        what = mutate_h5(
            samples.animation,
            src,
            rng,
            ("vertices", "faces", "joints", "capsules", "radii", "retrieved", "entropy", "match"),
        )
        target = rng.choice(["a.glb", "a.pc2", "a.usda", "a.png"])
        if target == "a.png":
            command = _cli("preview", src, "-o", out / target, "--size", 64, "--frames", 2)
        else:
            command = _cli("export", src, "-o", out / target)
        return Case(number, kind, what, command, out / target, [src.name])
    if kind == "manifest":
        what = mutate_manifest(samples.model, folder / "model", rng)
        return Case(
            number,
            kind,
            what,
            _cli("animate", samples.native, "--model", folder / "model", "-o", out / "out.h5"),
            out / "out.h5",
            ["model", "bundle.json"],
        )
    if kind in DOOR_KINDS:
        doors = make_door_samples(work / "samples" / "doors", samples.model, samples.native)
        case = door_case(
            kind,
            doors,
            folder,
            rng,
            cli=_cli,
            hostile=HOSTILE_VALUES,
            damage=mutate_bytes,
        )
        return Case(
            number,
            case.kind,
            case.mutation,
            case.command,
            case.output,
            case.names,
            keep={str(p): _digest(p) for p in case.keep if p.is_file()},
            env=case.env,
        )
    if kind == "api":
        return _api_case(number, samples, out, rng)
    if kind == "output = input":
        return _output_is_input_case(number, samples, folder, rng)
    if kind == "interrupt":
        return _interrupt_case(number, samples, out, rng)
    return _output_case(number, samples, folder, rng)


def _bvh_case(number: int, samples: Samples, folder: Path, rng: np.random.Generator) -> Case:
    """The sample BVH with one to three mutations of its text or bytes."""
    text, done = samples.bvh.read_text(), []
    for _ in range(int(rng.integers(1, 4))):
        if rng.random() < 0.15:
            data, what = mutate_bytes(text.encode(), rng)
            text = data.decode("latin-1")
            done.append(what)
        else:
            try:
                text, what = mutate_text(text, rng)
            except ValueError:  # an earlier mutation removed what this one edits: damage bytes instead
                data, what = mutate_bytes(text.encode("latin-1", errors="replace"), rng)
                text = data.decode("latin-1")
            done.append(what)
    src = folder / "clip.bvh"
    src.write_bytes(text.encode("latin-1", errors="replace"))
    return _motion_case(number, "bvh", "; ".join(done), src, samples, folder / "out", rng)


def _motion_case(
    number: int, kind: str, what: str, src: Path, samples: Samples, out: Path, rng: np.random.Generator
) -> Case:
    """A mutated motion through ``hrr-motion features`` (parsing, retargeting) or ``hrr-animate``."""
    if rng.random() < 0.6:
        return Case(
            number,
            kind,
            what,
            _cli("motion", "features", src, "-o", out / "f.npy"),
            out / "f.npy",
            [src.name],
        )
    return Case(
        number,
        kind,
        what,
        _cli("animate", src, "--model", samples.model, "-o", out / "out.h5"),
        out / "out.h5",
        [src.name],
    )


def _output_case(number: int, samples: Samples, folder: Path, rng: np.random.Generator) -> Case:
    """Outputs that cannot be written: special files, folders in the way, paths under a file, long names."""
    (folder / "a_file").write_text("x")
    (folder / "a_folder.glb").mkdir()
    targets = {
        "proc": Path("/proc/hrr-fuzz.h5"),
        "device": Path("/dev/full"),
        "folder": folder / "a_folder.glb",
        "under a file": folder / "a_file" / "out.h5",
        "long name": folder / ("n" * 300 + ".h5"),
        "sys": Path("/sys/hrr-fuzz.glb"),
    }
    what = str(rng.choice(sorted(targets)))
    target = targets[what]
    if rng.random() < 0.5 or target.suffix == ".glb":
        command = _cli("export", samples.animation, "-o", target, "--to", "glb")
    else:
        command = _cli("animate", samples.native, "--model", samples.model, "-o", target)
    return Case(number, "output path", what, command, target, [target.name[:40]])


# ----------------------------------------------------------------------------- running and judging


def _limits(memory_gib: float):
    def apply():
        os.setsid()
        limit = int(memory_gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return apply


def run_case(case: Case, timeout: float, memory_gib: float) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", **case.env}
    start = time.perf_counter()
    proc = subprocess.Popen(
        case.command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        stdin=subprocess.DEVNULL,
        preexec_fn=_limits(memory_gib),
        errors="replace",
    )
    err_parts: list[str] = []
    reader = threading.Thread(
        target=lambda: err_parts.extend(iter(lambda: proc.stderr.read(256), "")), daemon=True
    )
    reader.start()
    if case.interrupt is not None:  # once it works (its first progress bar), the signal, then the wait
        sig, delay = case.interrupt
        while proc.poll() is None and "|" not in "".join(err_parts) and time.perf_counter() - start < timeout:
            time.sleep(0.05)
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
    try:
        proc.wait(timeout=max(1.0, timeout - (time.perf_counter() - start)))
        hung = False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        hung = True
    reader.join(timeout=10)
    proc.stdout.close()
    err = "".join(err_parts)
    seconds = time.perf_counter() - start
    outcome, detail = judge(case, proc.returncode, err, hung)
    return {
        **asdict(case),
        "output": str(case.output),
        "command": case.command,
        "rc": proc.returncode,
        "seconds": round(seconds, 2),
        "outcome": outcome,
        "detail": detail,
        "stderr": err[-2000:],
    }


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:  # a name too long for the system: nothing can be there
        return False


def judge(case: Case, rc: int, err: str, hung: bool) -> tuple[str, str]:
    special = str(case.output).startswith(("/proc", "/sys", "/dev"))
    leftovers = (
        [p.name for p in case.output.parent.glob(f".{case.output.name[:40]}*")]
        if not special and _exists(case.output.parent)
        else []
    )
    if hung:
        return "hang", "past the time limit"
    changed = [
        Path(p).name for p, digest in case.keep.items() if not Path(p).exists() or _digest(Path(p)) != digest
    ]
    if changed:
        return "lost input", f"changed or removed: {', '.join(changed)}"
    # interrupted (130, 143) or, in the instant after the command restored the default handlers, ended
    # by the signal itself: its output either complete or absent, no temporary file
    if (
        case.interrupt is not None
        and rc in (130, 143, -signal.SIGINT, -signal.SIGTERM)
        and "Traceback" not in err
    ):
        problem = check_output(case.output) if _exists(case.output) else ""
        if leftovers or problem:
            return "partial file", f"left {leftovers or problem} after the signal"
        return "clean error", err.strip().splitlines()[-1][-200:] if err.strip() else f"exit {rc}"
    if rc in (-9, 137) or "MemoryError" in err or "Cannot allocate memory" in err:
        return "memory", err.strip().splitlines()[-1] if err.strip() else "killed"
    if "Traceback" in err or "Segmentation fault" in err or rc not in (0, 2):
        last = err.strip().splitlines()[-1] if err.strip() else f"exit {rc}"
        return "traceback", last[-300:]
    if rc == 2:
        if leftovers or (
            not special
            and _exists(case.output)
            and case.kind not in ("output path", "output = input", "new output = input")
        ):
            return "partial file", f"left {leftovers or case.output.name}"
        lines = [ln for ln in err.splitlines() if "error:" in ln]
        if not lines:
            return "vague error", "exit 2 without an error line"
        if case.names and not any(n in lines[-1] for n in case.names) and "usage:" not in err:
            return "vague error", lines[-1][-300:]
        if "Warning" in err:  # warnings printed before the one line bury it
            return "vague error", "warnings before the error: " + next(
                ln for ln in err.splitlines() if "Warning" in ln
            )[-200:]
        return "clean error", lines[-1][-200:]
    if leftovers:
        return "partial file", f"left {leftovers}"
    if case.output.name == "none":  # a command that only prints (hrr-motion info, hrr-body info)
        return "ok", ""
    problem = check_output(case.output)
    return ("bad output", problem) if problem else ("ok", "")


def check_output(path: Path) -> str:
    """'' when a successful run's output reads back finite and plausible; else what is wrong."""
    if not _exists(path):
        return "exit 0 but no output"
    try:
        if path.suffix == ".h5":
            from hrr_garment.data.animation_file import read_animation_h5

            anim = read_animation_h5(path)
            if not (np.isfinite(anim.vertices).all() and np.isfinite(anim.joints).all()):
                return "non-finite vertices or joints"
            reach = np.linalg.norm(anim.vertices[:, :, None] - anim.joints[:, None], axis=-1).min(-1).max()
            return f"a garment vertex {reach:.2f} m from every joint" if reach > 1.5 else ""
        if (
            path.suffix == ".npy" and path.name == "api.npy"
        ):  # an API case: garment vertices relative to the pelvis
            rel = np.load(path, allow_pickle=False)
            if not np.isfinite(rel).all():
                return "non-finite vertices"
            return (
                f"a garment vertex {np.abs(rel).max():.3g} m from the pelvis"
                if np.abs(rel).max() > 2.5
                else ""
            )
        if path.suffix in (".npz", ".npy"):
            loaded = np.load(path, allow_pickle=False)
            arrays = [loaded] if isinstance(loaded, np.ndarray) else [loaded[k] for k in loaded.files]
            return "" if all(np.isfinite(a).all() for a in arrays) else "non-finite features"
        if path.suffix == ".glb":
            from hrr_garment.export.glb_read import read_glb_keyframes

            _, verts, _ = read_glb_keyframes(path)
            return "" if np.isfinite(verts).all() else "non-finite keyframes"
        if path.suffix == ".pc2":
            from hrr_garment.export.pointcache import read_pc2

            return "" if np.isfinite(read_pc2(path)[0]).all() else "non-finite points"
        if path.suffix == ".json":  # body.json and the like: strict JSON, no NaN or Infinity
            json.loads(path.read_text(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        if path.is_dir() and (path / "bundle.json").exists():
            from hrr_garment.artifacts.bundle_loader import load_bundle

            load_bundle(path)
        elif path.is_dir() and (path / "report.json").exists():
            json.loads(
                (path / "report.json").read_text(),
                parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)),
            )
        return "" if path.is_dir() or path.stat().st_size > 0 else "empty output"
    except Exception as exc:  # noqa: BLE001 - anything that fails to read back is a bad output
        return f"output does not read back: {type(exc).__name__}: {str(exc)[:200]}"


def _special_files(folder: str, names: list[str]) -> list[str]:
    """The names in ``folder`` that are neither files, folders nor links (pipes, sockets)."""
    paths = [Path(folder) / n for n in names]
    return [p.name for p in paths if not (p.is_symlink() or p.is_file() or p.is_dir())]


def write_report(results: list[dict], work: Path, seconds: float) -> str:
    kinds = sorted({r["kind"] for r in results})
    outcomes = ["clean error", "ok", *FAILURES]
    counts = Counter((r["kind"], r["outcome"]) for r in results)
    rows = ["| input kind | cases | " + " | ".join(outcomes) + " |", "|---|---:|" + "---:|" * len(outcomes)]
    for k in kinds:
        rows.append(
            f"| {k} | {sum(counts[k, o] for o in outcomes)} | "
            + " | ".join(str(counts[k, o]) for o in outcomes)
            + " |"
        )
    total = Counter(r["outcome"] for r in results)
    rows.append(f"| all | {len(results)} | " + " | ".join(str(total[o]) for o in outcomes) + " |")
    failures = [r for r in results if r["outcome"] in FAILURES]
    lines = [f"{len(results)} cases in {seconds / 60:.1f} min; failures: {len(failures)}", "", *rows]
    if failures:
        lines += ["", "Failures:"] + [
            f"- #{r['number']} {r['kind']} ({r['mutation']}): {r['outcome']}: {r['detail']}" for r in failures
        ]
    text = "\n".join(lines) + "\n"
    (work / "report.md").write_text(text)
    (work / "report.json").write_text(json.dumps({"seconds": seconds, "results": results}, indent=1))
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--cases", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--timeout", type=float, default=60.0, help="seconds before a run counts as a hang")
    p.add_argument("--memory-gib", type=float, default=8.0, help="address-space limit per run")
    p.add_argument("--only", choices=list(KINDS), default=None, help="one input kind")
    p.add_argument("--work", type=Path, default=ROOT / "hrr_work" / "fuzz")
    args = p.parse_args(argv)
    args.work = args.work.resolve()  # a relative folder would make the cases' links dangle
    samples = make_samples(args.work / "samples")
    shutil.rmtree(args.work / "failures", ignore_errors=True)

    def one(n: int) -> dict:
        """Make case ``n`` (its own seeded generator: reproducible alone) and run it."""
        rng = np.random.default_rng([args.seed, n])
        folder = args.work / "cases" / f"{n:05d}"
        case = None
        try:
            case = make_case(n, samples, args.work, rng)
            while args.only and case.kind != args.only:
                case = make_case(n, samples, args.work, rng)
            r = run_case(case, args.timeout, args.memory_gib)
        except Exception as exc:  # noqa: BLE001 - a fuzzer bug must not hide the other cases; it counts as a failure
            r = {
                "number": n,
                "kind": case.kind if case else "fuzzer",
                "mutation": case.mutation if case else "",
                "command": case.command if case else [],
                "output": str(case.output) if case else "",
                "rc": None,
                "seconds": 0.0,
                "outcome": "traceback",
                "detail": f"fuzzer error: {type(exc).__name__}: {exc}",
                "stderr": "",
            }
        unlock(folder)
        if r["outcome"] in FAILURES:
            kept = args.work / "failures" / folder.name
            # links kept as links and pipes left out: a copy through a link to /dev/zero never ends
            shutil.copytree(folder, kept, symlinks=True, ignore=_special_files, dirs_exist_ok=True)
            (kept / "command.txt").write_text(" ".join(map(str, r["command"])) + "\n\n" + r["stderr"])
        shutil.rmtree(folder, ignore_errors=True)
        return r

    start = time.perf_counter()
    with ThreadPoolExecutor(args.jobs) as pool:
        futures = [pool.submit(one, n) for n in range(args.cases)]
        results = [
            f.result() for f in tqdm(as_completed(futures), total=len(futures), desc="fuzz", unit="case")
        ]
    results.sort(key=lambda r: r["number"])
    print(write_report(results, args.work, time.perf_counter() - start))
    return 1 if any(r["outcome"] in FAILURES for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
