"""Outputs that the storage refuses: a full disk, a read-only folder, special files.

Each writer must end in the one-line ``PROGRAM: error: PATH: ...`` and exit status 2, with no
traceback and nothing left behind (no final file, no temporary file). The full disk is a real one
where the test can mount it (a 64 KiB tmpfs in a private mount namespace); where it cannot, the
kernel's file-size limit (RLIMIT_FSIZE, 8 KiB per file) makes the writes fail in the same places.
"""

from __future__ import annotations

import functools
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from hrr_garment.motion.io import save_motion
from hrr_garment.motion.synth import synthesize

LIMIT_BYTES = 64 * 1024
_MARK = "--- left in the folder ---"


@functools.cache
def _can_mount_tmpfs() -> bool:
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(
        ["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
        capture_output=True,
        timeout=30,
    )
    return probe.returncode == 0


def _cli(module: str, *args: str) -> list[str]:
    return [
        sys.executable,
        "-c",
        f"import sys; from hrr_garment.cli.{module} import main; sys.exit(main())",
        *args,
    ]


def _run_on_small_disk(
    command: list[str], folder: Path, read_only: bool = False
) -> tuple[int, str, list[str]]:
    """Run ``command`` with ``folder`` on a full (or read-only) disk; (exit status, stderr, what the
    folder holds afterwards, seen from inside)."""
    folder.mkdir(parents=True, exist_ok=True)
    if _can_mount_tmpfs():
        ro = f' && mount -o remount,ro "{folder}"' if read_only else ""
        script = (
            f'mount -t tmpfs -o size={LIMIT_BYTES} tmpfs "{folder}"{ro} || exit 99; '
            f'"$@"; rc=$?; echo {_MARK}; ls -A "{folder}"; exit $rc'
        )
        done = subprocess.run(
            ["unshare", "-rm", "sh", "-c", script, "sh", *command],
            capture_output=True,
            text=True,
            timeout=300,
            stdin=subprocess.DEVNULL,
        )
        assert done.returncode != 99, done.stderr
        return done.returncode, done.stderr, done.stdout.split(_MARK)[-1].split()
    if read_only:
        pytest.skip("read-only folders need a private mount namespace here (root ignores permissions)")

    def limit():
        # per file, and one OBJ frame is about 16 KB: 8 KiB makes every output's first file fail
        resource.setrlimit(resource.RLIMIT_FSIZE, (8 * 1024, 8 * 1024))

    done = subprocess.run(
        command, capture_output=True, text=True, timeout=300, preexec_fn=limit, stdin=subprocess.DEVNULL
    )
    return done.returncode, done.stderr, sorted(p.name for p in folder.iterdir())


@pytest.fixture(scope="module")
def animation(trained, tmp_path_factory) -> tuple[Path, Path, Path]:
    """(model folder, motion clip, an out.h5 of it) made on a healthy disk."""
    from hrr_garment.cli.animate import main as animate_main

    root, _, _ = trained
    folder = tmp_path_factory.mktemp("full_disk")
    clip = folder / "walk.npz"
    save_motion(synthesize("walk", 4.0, seed=2), clip)
    out = folder / "out.h5"
    assert animate_main([str(clip), "-o", str(out), "--model", str(root / "model")]) == 0
    assert out.stat().st_size > 2 * LIMIT_BYTES  # too big for the small disk: the write must fail
    return root / "model", clip, out


CASES = {
    "animate": lambda m, clip, h5, d: _cli("animate", str(clip), "--model", str(m), "-o", str(d / "out.h5")),
    "export glb": lambda m, clip, h5, d: _cli("export", str(h5), "-o", str(d / "a.glb"), "--tolerance", "0"),
    "export pc2": lambda m, clip, h5, d: _cli("export", str(h5), "-o", str(d / "a.pc2")),
    "export obj": lambda m, clip, h5, d: _cli("export", str(h5), "--to", "obj", "-o", str(d / "frames")),
    "preview gif": lambda m, clip, h5, d: _cli("preview", str(h5), "-o", str(d / "a.gif"), "--size", "256"),
    "motion features": lambda m, clip, h5, d: _cli("motion", "features", str(clip), "-o", str(d / "f.npy")),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_full_disk_is_one_line_and_leaves_nothing(case, animation, tmp_path):
    model, clip, h5 = animation
    folder = tmp_path / "disk"
    if case == "motion features":  # its output is small: make it too big for the disk by repeating the clip
        long_clip = tmp_path / "long.npz"
        save_motion(synthesize("walk", 60.0, seed=3), long_clip)
        clip = long_clip
    rc, err, left = _run_on_small_disk(CASES[case](model, clip, h5, folder), folder)
    assert rc == 2, err
    assert "Traceback" not in err and "error:" in err
    message = [line for line in err.splitlines() if "error:" in line]
    assert len(message) == 1 and str(folder) in message[0], err
    assert left == [], f"left behind: {left}"


@pytest.mark.parametrize("case", ["animate", "export glb", "motion features"])
def test_a_read_only_folder_is_one_line(case, animation, tmp_path):
    model, clip, h5 = animation
    folder = tmp_path / "disk"
    rc, err, left = _run_on_small_disk(CASES[case](model, clip, h5, folder), folder, read_only=True)
    assert rc == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "Read-only file system" in err or "not a writable folder" in err, err
    assert left == []


def test_special_paths_are_refused(animation, tmp_path, capsys):
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.cli.export import main as export_main

    model, clip, h5 = animation
    assert animate_main([str(clip), "--model", str(model), "-o", "/proc/hrr-out.h5"]) == 2
    assert "/proc/hrr-out.h5: cannot write the output" in capsys.readouterr().err
    # a folder (or a device) where a file belongs is refused, and left as it was
    (tmp_path / "taken.glb").mkdir()
    assert export_main([str(h5), "-o", str(tmp_path / "taken.glb")]) == 2
    assert "not a regular file" in capsys.readouterr().err and (tmp_path / "taken.glb").is_dir()
    assert (
        export_main([str(h5), "-o", "/dev/null", "--to", "pc2"]) == 2
    )  # a device, and no .pc2 name: refused
    assert "/dev/null: " in capsys.readouterr().err
