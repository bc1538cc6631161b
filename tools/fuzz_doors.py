"""The fuzz suite's newer doors (issue 88): a character and its animations in glTF, body.json, a
garment modelled on a body, the ONNX export, signatures and trusted keys, and special files where
any of them is expected, each mutated as a hostile user would and run through the real commands,
and, where Blender is there, the add-on's import (``tools/fuzz_blender.py``). ``tools/fuzz.py``
draws these kinds beside its older ones and judges them alike.

Samples (made once in the work folder, from nothing outside it): anny's average body as a skinned
GLB (``tools/studies/make_characters.py --styles plain``; the ``bodies`` extra), its body.json
(``hrr-body fit``), the sample clip played on it and exported with the character (a GLB with a skin
and an animation), a dress modelled on it (``tools/made_for_example.py``) and a key pair.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from hrr_garment.blender import blender_command

ROOT = Path(__file__).resolve().parents[1]
DOOR_KINDS = {
    "gltf": 0.08,
    "body.json": 0.06,
    "made-for garment": 0.03,
    "onnx export": 0.02,
    "signature": 0.04,
    "special file": 0.04,
    "new output = input": 0.03,
    "unwritable output": 0.03,
}
if blender_command() is not None:  # the add-on's door needs Blender (tools/fuzz_blender.py)
    DOOR_KINDS["blender add-on"] = 0.04
GLTF_SECTIONS = ("accessors", "bufferViews", "buffers", "nodes", "skins", "meshes", "animations")


@dataclass
class DoorSamples:
    """The valid inputs the doors' mutations start from."""

    character: Path  # a skinned GLB, no animation
    animated: Path  # a skinned GLB with one animation (the character playing the sample clip)
    body: Path  # the character's body.json
    garment: Path  # a dress modelled on the character (OBJ, a band group)
    key: Path  # a private key (its .pub beside it)
    model: Path  # the suite's tiny model
    clip: Path  # its sample clip (npz)


@dataclass
class DoorCase:
    """What :func:`door_case` hands tools/fuzz.py to wrap in its ``Case``."""

    kind: str
    mutation: str
    command: list[str]
    output: Path
    names: list[str]
    keep: list[Path]
    env: dict


def _run(*command: object) -> None:
    done = subprocess.run([sys.executable, *map(str, command)], capture_output=True, text=True, cwd=ROOT)
    if done.returncode:
        raise SystemExit(f"fuzz: could not make a door sample: {' '.join(map(str, command))}\n{done.stderr}")


_SAMPLES_LOCK = threading.Lock()  # the fuzz's worker threads ask at once on a fresh work folder


def make_door_samples(folder: Path, model: Path, clip: Path) -> DoorSamples:
    """The doors' valid inputs; ``model`` the suite's tiny model, ``clip`` its sample motion."""
    with _SAMPLES_LOCK:
        return _door_samples(folder, model, clip)


def _door_samples(folder: Path, model: Path, clip: Path) -> DoorSamples:
    s = DoorSamples(
        folder / "plain.glb",
        folder / "plain_walk.glb",
        folder / "plain.json",
        folder / "dress.obj",
        folder / "k.key",
        model=model,
        clip=clip,
    )
    if all(p.exists() for p in vars(s).values()):
        return s
    folder.mkdir(parents=True, exist_ok=True)
    cli = "import sys; from hrr_garment.cli.{} import main; sys.exit(main())"
    _run("tools/studies/make_characters.py", "-o", folder, "--styles", "plain")
    _run("-c", cli.format("body"), "fit", s.character, "-o", s.body)
    _run(
        "-c",
        cli.format("animate"),
        clip,
        "--model",
        model,
        "--body",
        s.character,
        "--allow-outside-body",
        "-o",
        folder / "walk.h5",
    )
    _run("-c", cli.format("export"), folder / "walk.h5", "--character", s.character, "-o", s.animated)
    _run("tools/made_for_example.py", "--body", s.body, "-o", folder / "madefor")
    shutil.copy(folder / "madefor" / "dress.obj", s.garment)
    _run("-c", cli.format("sign"), "keygen", "-o", s.key)
    return s


# -- glTF -------------------------------------------------------------------------------------------


def _glb_parts(data: bytes) -> tuple[dict, bytes]:
    size = int.from_bytes(data[12:16], "little")
    doc = json.loads(data[20 : 20 + size])
    rest = data[20 + size :]
    return doc, rest[8 : 8 + int.from_bytes(rest[:4], "little")] if len(rest) >= 8 else b""


def _glb(doc: dict, binary: bytes, nested: int = 0) -> bytes:
    """The GLB of ``doc`` and ``binary``; ``nested``: an "extras" of lists that deep, written as text
    (the fuzzer's own json cannot build it)."""
    text = json.dumps(doc).encode()
    if nested:
        text = text[:-1] + b', "extras": ' + b"[" * nested + b"]" * nested + b"}"
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = len(text).to_bytes(4, "little") + b"JSON" + text
    chunks += len(binary).to_bytes(4, "little") + b"BIN\0" + binary
    return b"glTF" + (2).to_bytes(4, "little") + (12 + len(chunks)).to_bytes(4, "little") + chunks


def mutate_gltf(data: bytes, rng: np.random.Generator, hostile: list, damage: Callable) -> tuple[bytes, str]:
    """One hostile change to a GLB: a property of a buffer, view, accessor, node, skin, mesh or
    animation set to a hostile value, deep nesting, a skin of thousands of joints, keys far apart,
    or the bytes damaged."""
    doc, binary = _glb_parts(data)
    roll = rng.random()
    if roll < 0.1:
        return damage(data, rng)
    if roll < 0.15:
        return _glb(doc, binary, nested=100_000), "extras nested 100,000 deep"
    if roll < 0.2 and doc.get("skins"):
        doc["skins"][0]["joints"] = list(range(int(rng.choice([1025, 20022]))))
        return _glb(doc, binary), f"skin of {len(doc['skins'][0]['joints'])} joints"
    sections = [s for s in GLTF_SECTIONS if doc.get(s)]
    section = str(rng.choice(sections))
    item = doc[section][int(rng.integers(len(doc[section])))]
    holder = item
    if section == "animations":
        part = str(rng.choice(["samplers", "channels"]))
        holder = item[part][int(rng.integers(len(item[part])))]
        if part == "channels" and rng.random() < 0.5:
            holder = holder["target"]
    elif section == "meshes":
        holder = item["primitives"][int(rng.integers(len(item["primitives"])))]
        if rng.random() < 0.5:
            holder = holder["attributes"]
    keys = sorted(holder) or ["count"]
    key = str(rng.choice(keys))
    value = hostile[int(rng.integers(len(hostile)))]
    holder[key] = value
    return _glb(doc, binary), f"{section} {key} = {value!r}"


# -- the cases --------------------------------------------------------------------------------------


def door_case(
    kind: str,
    samples: DoorSamples,
    folder: Path,
    rng: np.random.Generator,
    *,
    cli: Callable,
    hostile: list,
    damage: Callable,
) -> DoorCase:
    """A case of ``kind`` (one of :data:`DOOR_KINDS`) in ``folder`` (its ``out`` made)."""
    out, model, clip = folder / "out", samples.model, samples.clip
    if kind == "gltf":
        base = samples.animated if rng.random() < 0.6 else samples.character
        data, what = mutate_gltf(base.read_bytes(), rng, hostile, damage)
        src = folder / "hostile.glb"
        src.write_bytes(data)
        commands = {
            "info": (cli("motion", "info", src), out / "none"),
            "fit": (cli("body", "fit", src, "-o", out / "body.json"), out / "body.json"),
            "animate": (cli("animate", src, "--model", model, "-o", out / "out.h5"), out / "out.h5"),
        }
        name = str(rng.choice(sorted(commands)))
        command, target = commands[name]
        return DoorCase(kind, f"{name}: {what}", command, target, [src.name], [], {})
    if kind == "body.json":
        src, what = _hostile_body(samples, folder, rng, hostile)
        if rng.random() < 0.5:
            return DoorCase(
                kind, f"info: {what}", cli("body", "info", src, "--json"), out / "none", [src.name], [], {}
            )
        command = cli(
            "animate", clip, "--model", model, "--body", src, "--allow-outside-body", "-o", out / "out.h5"
        )
        return DoorCase(kind, f"animate: {what}", command, out / "out.h5", [src.name], [], {})
    if kind == "made-for garment":
        text, what = _mutate_obj(samples.garment.read_text(), rng, hostile)
        src = folder / "dress.obj"
        src.write_text(text)
        command = cli(
            "simulate",
            "--template",
            src,
            "--attached",
            "band",
            "--made-for",
            samples.body,
            "--body",
            samples.body,
            "--preset",
            "tiny",
            "--motions",
            "walk",
            "--seconds",
            1,
            "-o",
            out / "d.h5",
        )
        return DoorCase(kind, what, command, out / "d.h5", [src.name], [], {})
    if kind == "onnx export":
        src, what = _hostile_body(samples, folder, rng, hostile)
        command = cli(
            "export_model",
            "--model",
            model,
            "--onnx",
            "--body",
            src,
            "--allow-outside-body",
            "--no-push-out",
            "-o",
            out / "x.onnx",
        )
        return DoorCase(kind, what, command, out / "x.onnx", [src.name], [], {})
    from fuzz_door_files import output_is_input_case, signature_case, special_case, unwritable_case

    if kind == "signature":
        return signature_case(samples, folder, rng, cli)
    if kind == "special file":
        return special_case(samples, folder, rng, cli)
    if kind == "unwritable output":
        return unwritable_case(samples, folder, rng, cli)
    if kind == "blender add-on":
        from fuzz_blender import blender_case

        return blender_case(samples, folder, rng, hostile=hostile, damage=damage)
    return output_is_input_case(samples, folder, rng, cli)


def _hostile_body(
    samples: DoorSamples, folder: Path, rng: np.random.Generator, hostile: list
) -> tuple[Path, str]:
    """The sample body.json mutated once, written into ``folder``: (its path, what was done)."""
    data = json.loads(samples.body.read_text())
    what = _mutate_body(data, rng, hostile)
    src = folder / "body.json"
    src.write_text(json.dumps(data))
    return src, what


def _mutate_body(data: dict, rng: np.random.Generator, hostile: list) -> str:
    roll = rng.random()
    capsules = data["capsules"]
    if roll < 0.1:
        capsules[0]["name"] = "pelvis_bone"
        return "a capsule renamed"
    if roll < 0.2:
        capsules[0], capsules[1] = capsules[1], capsules[0]
        return "capsules reordered"
    if roll < 0.25:
        data["capsules"] = capsules[1:]
        return "hips missing"
    if roll < 0.3:
        data["offsets"] = [[x, -y, z] for x, y, z in data["offsets"]]
        return "upside down"
    if roll < 0.35:
        data["offsets"] = [[-x, y, z] for x, y, z in data["offsets"]]
        return "mirrored"
    if roll < 0.4:
        data["fit"] = str(rng.choice(["good", "[1, 2]"]))
        return "fit not an object"
    value = hostile[int(rng.integers(len(hostile)))]
    where = str(rng.choice(["pelvis_height", "stature", "offsets", "capsule", "format_version", "shape"]))
    if where == "offsets":
        data["offsets"][int(rng.integers(22))][int(rng.integers(3))] = value
    elif where == "capsule":
        capsule = capsules[int(rng.integers(len(capsules)))]
        field = str(rng.choice(["a", "b", "radius", "joint"]))
        if field in ("a", "b"):
            capsule[field][int(rng.integers(3))] = value
        else:
            capsule[field] = value
        where = f"capsule {capsule.get('name')} {field}"
    else:
        data[where] = value
    return f"{where} = {value!r}"


def _mutate_obj(text: str, rng: np.random.Generator, hostile: list) -> tuple[str, str]:
    lines = text.splitlines()
    roll = rng.random()
    if roll < 0.15:
        return "v 0 1.2 0.1\nv 0.1 1.2 0.1\nv 0 1.1 0.1\ng band\nf 1 2 3\n", "one triangle"
    vertices = [i for i, line in enumerate(lines) if line.startswith("v ")]
    faces = [i for i, line in enumerate(lines) if line.startswith("f ")]
    if roll < 0.5:
        i = vertices[int(rng.integers(len(vertices)))]
        parts = lines[i].split()
        parts[1 + int(rng.integers(3))] = str(rng.choice(["nan", "inf", "-inf", "1e300", "x", "0x10"]))
        lines[i] = " ".join(parts)
        return "\n".join(lines) + "\n", f"vertex line {i + 1}: {lines[i]}"
    if roll < 0.75:
        i = faces[int(rng.integers(len(faces)))]
        lines[i] = "f " + " ".join(str(v) for v in rng.choice([0, -99999, 10**9, 1], size=3))
        return "\n".join(lines) + "\n", f"face line {i + 1}: {lines[i]}"
    keep = rng.random(len(lines)) > 0.5
    return "\n".join(line for line, k in zip(lines, keep) if k) + "\n", "half the lines dropped"
