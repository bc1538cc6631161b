"""The fuzzer's mutations (tools/fuzz.py): each takes a valid input and returns it damaged, with a
few words saying how, drawn from a seeded generator so that a case number reproduces it: numbers in
text set to extremes and keywords broken, bytes flipped or cut, arrays reshaped, retyped or filled
with NaN, a model bundle's files tampered with (its hashes redone or not), an out.h5 or dataset's
arrays damaged, bundle.json's fields set to hostile values with the manifest signed again."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np

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


def save_npz(path: Path, arrays: dict) -> None:
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
