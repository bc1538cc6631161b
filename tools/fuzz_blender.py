"""The fuzz suite's Blender door (issue 88): the add-on's import (File > Import > hrr_garment
animation) given damaged exports, in a real Blender (``HRR_BLENDER``: the program, or a Python with
bpy). Drawn by tools/fuzz.py through tools/fuzz_doors.py only where Blender is there.

Samples (made once, beside the other doors' samples): the sample clip's animation exported as a
GLB with its timeline and as a PC2 with its OBJ, and the add-on's zip. A case damages one of them
(a GLB property or its timeline set to a hostile value, its bytes; a PC2's header fields, its
length, its bytes; the OBJ beside a PC2 damaged or missing) and runs tools/blender_addon_import.py,
which exits as the package's commands do (0 imported, 2 one error line, 1 a traceback).
"""

from __future__ import annotations

import shutil
import struct
import subprocess
import sys
from pathlib import Path
from typing import Callable

import numpy as np

from hrr_garment.blender import blender_command

ROOT = Path(__file__).resolve().parents[1]
PC2_FIELDS = {"version": 12, "points": 16, "start": 20, "rate": 24, "samples": 28}  # byte offsets


def blender_samples(folder: Path) -> tuple[Path, Path, Path]:
    """(an exported GLB, an exported PC2 with its OBJ beside it, the add-on's zip), made from the
    doors' exported clip (``walk.h5`` in ``folder``) once."""
    glb, pc2, addon = folder / "export.glb", folder / "export.pc2", folder / "addon.zip"
    if not (glb.exists() and pc2.exists() and addon.exists()):
        cli = "import sys; from hrr_garment.cli.{} import main; sys.exit(main())"
        for args in (
            ("export", folder / "walk.h5", "-o", glb),
            ("export", folder / "walk.h5", "-o", pc2),
            ("blender_addon", "-o", addon),
        ):
            done = subprocess.run(
                [sys.executable, "-c", cli.format(args[0]), *map(str, args[1:])],
                capture_output=True,
                cwd=ROOT,
            )
            if done.returncode:
                raise SystemExit(f"fuzz: could not make a Blender sample: {args}\n{done.stderr.decode()}")
    return glb, pc2, addon


def _hostile_pc2(data: bytes, rng: np.random.Generator, hostile: list, damage: Callable) -> tuple[bytes, str]:
    roll = rng.random()
    if roll < 0.2:
        return damage(data, rng)
    if roll < 0.35:
        cut = int(rng.integers(0, len(data)))
        return data[:cut], f"cut to {cut} of {len(data)} bytes"
    field = str(rng.choice(sorted(PC2_FIELDS)))
    at = PC2_FIELDS[field]
    number = hostile[int(rng.integers(len(hostile)))]
    if not isinstance(number, (int, float)) or isinstance(number, bool):
        number = int(rng.choice([0, -1, 2**31 - 1, 7]))
    if field in ("start", "rate"):
        packed = struct.pack("<f", float(np.clip(number, -3e38, 3e38)))
    else:
        packed = struct.pack("<i", int(np.clip(np.nan_to_num(number), -(2**31), 2**31 - 1)))
    return data[:at] + packed + data[at + 4 :], f"header {field} = {number!r}"


def blender_case(samples, folder: Path, rng: np.random.Generator, *, hostile: list, damage: Callable):
    """A case of the Blender door (a :class:`fuzz_doors.DoorCase`)."""
    from fuzz_doors import DoorCase, _glb, _glb_parts, mutate_gltf

    glb, pc2, addon = blender_samples(samples.character.parent)
    roll = rng.random()
    if roll < 0.45:
        src = folder / "hostile.glb"
        if rng.random() < 0.5:
            doc, binary = _glb_parts(glb.read_bytes())
            scene = doc["scenes"][doc.get("scene", 0)]
            key = str(rng.choice(["fps", "frames", "extras", "scene"]))
            value = hostile[int(rng.integers(len(hostile)))]
            if key == "extras":
                scene["extras"] = value
            elif key == "scene":
                doc["scene"] = value
            else:
                scene.setdefault("extras", {})[key] = value
            data, what = _glb(doc, binary), f"timeline {key} = {value!r}"
        else:
            data, what = mutate_gltf(glb.read_bytes(), rng, hostile, damage)
        src.write_bytes(data)
    else:
        src = folder / "hostile.pc2"
        obj = src.with_suffix(".obj")
        if roll < 0.55:
            shutil.copy(pc2, src)
            what = "its OBJ missing"
        elif roll < 0.65:
            src.write_bytes(pc2.read_bytes())
            text, what = damage(pc2.with_suffix(".obj").read_bytes(), rng)
            obj.write_bytes(text)
            what = f"its OBJ: {what}"
        else:
            data, what = _hostile_pc2(pc2.read_bytes(), rng, hostile, damage)
            src.write_bytes(data)
            shutil.copy(pc2.with_suffix(".obj"), obj)
    command = [
        *blender_command(),
        str(ROOT / "tools" / "blender_addon_import.py"),
        "--",
        f"--addon={addon}",
        str(src),
    ]
    # Blender writes its preferences and extensions under its user resources: the case's own folder
    env = {"BLENDER_USER_RESOURCES": str(folder / "blender")}
    names = [src.name, src.with_suffix(".obj").name] if src.suffix == ".pc2" else [src.name]
    return DoorCase("blender add-on", what, command, folder / "out" / "none", names, [], env)
