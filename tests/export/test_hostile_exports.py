"""Exports against hostile settings (issue 88): a program that is not Blender, named by HRR_BLENDER,
is refused in one line naming the variable, whether it prints forever, hangs, or prints bytes that
are not text (never a hang, a traceback or memory filled by its output); a tolerance that is no
distance is refused naming the option."""

import os
import time
from pathlib import Path

import pytest

from hrr_garment import blender
from hrr_garment.errors import InputError

IMPOSTORS = {
    "prints forever": "while :; do echo 'not blender at all'; done",
    "hangs": "exec sleep 1000",
    "prints no text": "printf '\\377\\376\\375'; exit 1",
    "prints a mark it did not earn": "echo HRR-BLENDER; exit 3",
}


@pytest.fixture(autouse=True)
def fresh_probe(monkeypatch):
    blender._checked_blender.cache_clear()
    monkeypatch.setattr(blender, "PROBE_TIMEOUT_S", 2)
    yield
    blender._checked_blender.cache_clear()


@pytest.mark.parametrize("case", list(IMPOSTORS))
def test_an_impostor_is_refused_quickly(tmp_path, monkeypatch, case):
    program = tmp_path / "fake-tool"
    program.write_text(f"#!/bin/sh\n{IMPOSTORS[case]}\n")
    program.chmod(0o755)
    monkeypatch.setenv("HRR_BLENDER", str(program))
    start = time.monotonic()
    with pytest.raises(InputError, match="HRR_BLENDER: .*fake-tool is not Blender") as err:
        blender.run_blender_script(Path("x.py"), [], subject=tmp_path / "out.blend", what="writing .blend")
    assert time.monotonic() - start < 30 and "\n" not in str(err.value)
    assert not (tmp_path / "out.blend").exists()


def test_the_export_command_says_so_in_one_line(tmp_path, monkeypatch, capsys):
    from hrr_garment.cli.export import main

    fixture = Path(__file__).parents[1] / "fixtures" / "out-31b4ef9" / "auto.h5"
    monkeypatch.setenv("HRR_BLENDER", str(Path(os.devnull)))  # a device, not a program
    assert main([str(fixture), "--to", "blend", "-o", str(tmp_path / "dress.blend")]) == 2
    err = capsys.readouterr().err
    assert "HRR_BLENDER" in err and "Traceback" not in err and not (tmp_path / "dress.blend").exists()


@pytest.mark.parametrize("tolerance", ["nan", "inf", "-1"])
def test_a_tolerance_that_is_no_distance_is_refused(tmp_path, capsys, tolerance):
    from hrr_garment.cli.export import main

    fixture = Path(__file__).parents[1] / "fixtures" / "out-31b4ef9" / "auto.h5"
    assert main([str(fixture), "--to", "glb", "--tolerance", tolerance, "-o", str(tmp_path / "d.glb")]) == 2
    err = capsys.readouterr().err
    assert "--tolerance" in err and "Traceback" not in err and not (tmp_path / "d.glb").exists()
