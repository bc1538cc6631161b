"""The fuzz suite's file-level doors (tools/fuzz_doors.py draws them): a model signed and checked
with a key pair, trusted keys set as a hostile user would; a special file (a pipe, a link to
/dev/zero, a folder) where a file is expected; an output that is one of the command's inputs; an
output folder that cannot be written (``unlock`` restores it after the run)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Callable

import numpy as np
from fuzz_doors import DoorCase, DoorSamples


def signature_case(samples: DoorSamples, folder: Path, rng: np.random.Generator, cli: Callable) -> DoorCase:
    """Signed bundles and trusted keys against forgeries, under HRR_REQUIRE_SIGNATURE."""
    model, clip = samples.model, samples.clip
    copy, other = folder / "model", folder / "other"
    shutil.copytree(model, copy)
    public = samples.key.with_suffix(".pub")
    env = {"HRR_TRUSTED_KEYS": str(public), "HRR_REQUIRE_SIGNATURE": "1"}
    sign = [
        sys.executable,
        "-c",
        "import sys; from hrr_garment.cli.sign import main; sys.exit(main())",
        "sign",
    ]
    forgeries = [
        "unsigned",
        "untrusted signer",
        "swapped signature",
        "tampered after signing",
        "nested signature",
        "key is a device",
        "signed with the public key",
        "keygen over its public key",
    ]
    what = str(rng.choice(forgeries))
    if what == "untrusted signer":
        subprocess.run([*sign, str(copy), "--key", str(samples.key)], capture_output=True, check=True)
        env["HRR_TRUSTED_KEYS"] = str(folder / "nobody.pub")
        (folder / "nobody.pub").write_text("# hrr-sign ed25519 public key\n" + "A" * 43 + "=\n")
    elif what == "swapped signature":
        shutil.copytree(model, other)
        meta = json.loads((other / "bundle.json").read_text())
        meta["created"] = "elsewhere"
        (other / "bundle.json").write_text(json.dumps(meta))
        subprocess.run([*sign, str(other), "--key", str(samples.key)], capture_output=True)
        if (other / "bundle.sig").exists():
            shutil.copy(other / "bundle.sig", copy / "bundle.sig")
    elif what == "tampered after signing":
        subprocess.run([*sign, str(copy), "--key", str(samples.key)], capture_output=True, check=True)
        meta = json.loads((copy / "bundle.json").read_text())
        meta["validation_mm"] = 0.001
        (copy / "bundle.json").write_text(json.dumps(meta))
    elif what == "nested signature":
        (copy / "bundle.sig").write_text("[" * 5000 + "]" * 5000)
    elif what == "key is a device":
        env["HRR_TRUSTED_KEYS"] = str(folder / "zero.pub")
        (folder / "zero.pub").symlink_to("/dev/zero")
    if what == "signed with the public key":
        command = cli("sign", "sign", copy, "--key", public)
        return DoorCase("signature", what, command, copy / "bundle.sig", [public.name], [public], {})
    if what == "keygen over its public key":
        command = cli("sign", "keygen", "-o", folder / "out" / "mine.pub")
        return DoorCase("signature", what, command, folder / "out" / "mine.pub", ["mine.pub"], [], {})
    command = cli("animate", clip, "--model", copy, "-o", folder / "out" / "out.h5")
    return DoorCase(
        "signature",
        what,
        command,
        folder / "out" / "out.h5",
        ["model", "HRR_", "bundle", "zero.pub", "nobody.pub"],
        [],
        env,
    )


def special_case(samples: DoorSamples, folder: Path, rng: np.random.Generator, cli: Callable) -> DoorCase:
    """A pipe, a device (or a link to one) or a folder where a file argument or a key is expected."""
    model = samples.model
    special = folder / str(rng.choice(["x.glb", "x.json", "map.yaml", "idx.txt", "x.key"]))
    how = str(rng.choice(["fifo", "zero", "urandom", "folder"]))
    if how == "fifo":
        os.mkfifo(special)
    elif how == "folder":
        special.mkdir()
    else:
        special.symlink_to(f"/dev/{how}")
    out = folder / "out"
    commands = {
        ".glb": (cli("body", "fit", special, "-o", out / "b.json"), out / "b.json"),
        ".json": (cli("body", "info", special), out / "none"),
        ".yaml": (
            cli("body", "fit", samples.character, "--joint-map", special, "-o", out / "b.json"),
            out / "b.json",
        ),
        ".txt": (
            cli(
                "simulate",
                "--template",
                samples.garment,
                "--attached-file",
                special,
                "--made-for",
                samples.body,
                "--preset",
                "tiny",
                "-o",
                out / "d.h5",
            ),
            out / "d.h5",
        ),
        ".key": (cli("sign", "sign", folder / "m", "--key", special), folder / "m" / "bundle.sig"),
    }
    if special.suffix == ".key":
        shutil.copytree(model, folder / "m")
    command, target = commands[special.suffix]
    return DoorCase("special file", f"{how} as {special.name}", command, target, [special.name], [], {})


def output_is_input_case(
    samples: DoorSamples, folder: Path, rng: np.random.Generator, cli: Callable
) -> DoorCase:
    """An output named as one of the new doors' inputs: refused, the input untouched."""
    model, clip = samples.model, samples.clip
    joint_map = folder / "map.json"
    shutil.copy(samples.body, folder / "body.json")
    local_clip = folder / "walk.tensors.npz"
    shutil.copy(clip, local_clip)
    choices = {
        "fit onto its joint map": (
            cli("body", "fit", samples.character, "--joint-map", joint_map, "-o", joint_map),
            joint_map,
        ),
        "export-model's tensors onto its check clip": (
            cli(
                "export_model",
                "--model",
                model,
                "--onnx",
                "--no-push-out",
                "--check",
                local_clip,
                "-o",
                folder / "walk.onnx",
            ),
            local_clip,
        ),
        "animate onto its body": (
            cli(
                "animate",
                clip,
                "--model",
                model,
                "--body",
                folder / "body.json",
                "--allow-outside-body",
                "-o",
                folder / "body.json",
            ),
            folder / "body.json",
        ),
    }
    from hrr_garment.motion.joint_maps import NAMING_SCHEMES

    mixamo = {joint: "mixamorig:" + names[0] for joint, names in NAMING_SCHEMES["mixamo"].items()}
    joint_map.write_text(json.dumps(mixamo))  # the character's whole rig: the map itself is good
    what = str(rng.choice(sorted(choices)))
    command, target = choices[what]
    return DoorCase(
        "new output = input",
        what,
        command,
        target,
        [target.name],
        [joint_map, local_clip, folder / "body.json"],
        {},
    )


LOCKED = "locked"  # the unwritable-output cases' folder, unlocked by :func:`unlock` after the run


def unwritable_case(samples: DoorSamples, folder: Path, rng: np.random.Generator, cli: Callable) -> DoorCase:
    """An output in a folder that takes no new file (read-only permissions; for root, who ignores
    them, the immutable attribute), or in a missing folder below it: one line naming the output,
    exit 2, before any work."""
    locked = folder / LOCKED
    locked.mkdir()
    locked.chmod(0o555)
    if os.access(locked, os.W_OK):  # root
        subprocess.run(["chattr", "+i", str(locked)], capture_output=True)
    if os.access(locked, os.W_OK):
        raise SystemExit("fuzz: cannot make a folder unwritable here (root without chattr)")
    where = locked / "missing" if rng.random() < 0.3 else locked
    model, clip = samples.model, samples.clip
    commands = {
        "simulate": cli("simulate", "--garment", "skirt", "--preset", "tiny", "-o", where / "d.h5"),
        "train": cli("train", "--garment", "skirt", "--preset", "tiny", "-o", where / "model"),
        "make": cli("make", samples.body, "--garment", "skirt", "-o", where / "made"),
        "animate": cli("animate", clip, "--model", model, "-o", where / "out.h5"),
        "export-model": cli(
            "export_model", "--model", model, "--onnx", "--no-push-out", "-o", where / "m.onnx"
        ),
        "body fit": cli("body", "fit", samples.character, "-o", where / "body.json"),
        "keygen": cli("sign", "keygen", "-o", where / "mine.key"),
        "motion poses": cli("motion", "poses", clip, "-o", where / "poses.npz"),
        "blender add-on": cli("blender_addon", "-o", where / "addon.zip"),
    }
    what = str(rng.choice(sorted(commands)))
    command = commands[what]
    output = Path(command[-1])
    return DoorCase(
        "unwritable output", f"{what} into {output.parent.name}/", command, output, [output.name], [], {}
    )


def unlock(case_folder: Path) -> None:
    """Make an unwritable-output case's folder removable again."""
    locked = case_folder / LOCKED
    if locked.is_dir() and not locked.is_symlink():
        subprocess.run(["chattr", "-i", str(locked)], capture_output=True)
        locked.chmod(0o755)
