"""The fuzzer's cases (tools/fuzz.py): which kind of input a case number draws, and the mutated
copy and command each kind makes."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from fuzz_api import _api_case, _interrupt_case, _output_is_input_case
from fuzz_doors import DOOR_KINDS, door_case, make_door_samples
from fuzz_mutations import (
    HOSTILE_VALUES,
    mutate_arrays,
    mutate_bundle,
    mutate_bytes,
    mutate_h5,
    mutate_manifest,
    mutate_text,
    save_npz,
)
from fuzz_samples import Case, Samples, _cli, file_digest

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
            save_npz(src, arrays)
            what = "; ".join(done)
        return _motion_case(number, kind, what, src, samples, out, rng)
    if kind == "bundle":
        what = mutate_bundle(samples.model, folder / "model", rng)
        return _tampered_model_case(number, kind, what, samples, folder, ["model"])
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
        return _tampered_model_case(number, kind, what, samples, folder, ["model", "bundle.json"])
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
            keep={str(p): file_digest(p) for p in case.keep if p.is_file()},
            env=case.env,
        )
    if kind == "api":
        return _api_case(number, samples, out, rng)
    if kind == "output = input":
        return _output_is_input_case(number, samples, folder, rng)
    if kind == "interrupt":
        return _interrupt_case(number, samples, out, rng)
    return _output_case(number, samples, folder, rng)


def _tampered_model_case(
    number: int, kind: str, what: str, samples: Samples, folder: Path, names: list[str]
) -> Case:
    """hrr-animate with the model bundle tampered with in ``folder / "model"``: its refusal names one
    of ``names``."""
    out = folder / "out"
    command = _cli("animate", samples.native, "--model", folder / "model", "-o", out / "out.h5")
    return Case(number, kind, what, command, out / "out.h5", names)


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
