"""An output folder the storage will not let the command write (no permission, immutable): every
command ends in one line ``PROGRAM: error: PATH: ...`` naming the output, exit status 2, before any
long work and without a traceback (issue 88: hrr-simulate and hrr-train ended in a PermissionError
traceback; hrr-eval found out only after its protocols had run)."""

from __future__ import annotations

import errno
import os
import shutil
import stat
import subprocess
from pathlib import Path

import pytest

from hrr_garment.body.body_file import write_body
from hrr_garment.body.mannequin import mannequin_record
from hrr_garment.cli._common import run_cli
from hrr_garment.motion.io import save_motion
from hrr_garment.motion.synth import synthesize

FIXTURES = Path(__file__).parents[1] / "fixtures" / "out-31b4ef9"


@pytest.fixture
def unwritable(tmp_path):
    """A folder no new file can be created in: read-only permissions for an ordinary user; for root,
    who ignores permissions, the immutable attribute where the file system has it."""
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    immutable = False
    if os.access(folder, os.W_OK) and shutil.which("chattr"):
        immutable = subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode == 0
    if os.access(folder, os.W_OK):
        folder.chmod(0o755)
        pytest.skip("no way to make a folder unwritable here (root without chattr)")
    yield folder
    if immutable:
        subprocess.run(["chattr", "-i", str(folder)], check=True)
    folder.chmod(0o755)


def _one_line(capsys, where: Path) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert "Traceback" not in err and len(lines) == 1, err
    assert str(where) in lines[0] and "not a writable folder" in lines[0], err
    return lines[0]


def test_long_commands_refuse_an_unwritable_output_before_they_start(trained, unwritable, capsys):
    from hrr_garment.cli import eval as eval_cli
    from hrr_garment.cli import make as make_cli
    from hrr_garment.cli import simulate as simulate_cli
    from hrr_garment.cli import train as train_cli

    root, data, _ = trained
    body = root.parent / f"{root.name}-body.json"
    if not body.exists():
        write_body(body, mannequin_record())
    runs = {
        "simulate": lambda out: simulate_cli.main(["--garment", "skirt", "--preset", "tiny", "-o", str(out)]),
        "train": lambda out: train_cli.main(
            ["--dataset", str(data), "--config", str(root / "cfg.yaml"), "-o", str(out), "--quiet"]
        ),
        "eval": lambda out: eval_cli.main(
            ["--model", str(root / "model"), "--dataset", str(data), "-o", str(out), "--no-plots"]
        ),
        "make": lambda out: make_cli.main([str(body), "--garment", "skirt", "-o", str(out)]),
    }
    for name, run in runs.items():
        for out in (unwritable / f"{name}.h5", unwritable / "missing" / "deeper" / f"{name}.h5"):
            if name != "simulate":
                out = out.with_suffix("")  # these write folders
            assert run(out) == 2, name
            _one_line(capsys, out)
    assert list(unwritable.iterdir()) == []


def test_writers_refuse_an_unwritable_output(trained, unwritable, tmp_path, capsys):
    from hrr_garment.cli import animate as animate_cli
    from hrr_garment.cli import export as export_cli
    from hrr_garment.cli import sign as sign_cli

    root, _, _ = trained
    clip = tmp_path / "walk.npz"
    save_motion(synthesize("walk", seconds=1.0, seed=0), clip)
    out = unwritable / "sub" / "out.h5"
    assert animate_cli.main([str(clip), "--model", str(root / "model"), "-o", str(out)]) == 2
    _one_line(capsys, out)
    assert export_cli.main([str(FIXTURES / "auto.h5"), "-o", str(unwritable / "a.glb")]) == 2
    assert "a.glb: cannot write the output" in capsys.readouterr().err
    assert sign_cli.main(["keygen", "-o", str(unwritable / "mine.key")]) == 2
    assert "mine.key: cannot write the output" in capsys.readouterr().err
    assert list(unwritable.iterdir()) == []


def test_a_storage_error_nobody_wrapped_is_one_line_and_a_bug_keeps_its_traceback(capsys):
    def refused(argv):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), "/srv/out/lock")

    assert run_cli(refused, [], "hrr-x") == 2
    assert capsys.readouterr().err.strip() == "hrr-x: error: /srv/out/lock: Permission denied"

    def broken_pipe(argv):
        raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE), "/srv/out/pipe")

    with pytest.raises(BrokenPipeError):  # not the storage: a bug or a closed reader, reported as such
        run_cli(broken_pipe, [], "hrr-x")

    def nameless(argv):
        raise OSError(errno.EACCES, "denied")

    with pytest.raises(OSError):  # no path to name: keep the traceback that says where
        run_cli(nameless, [], "hrr-x")
