"""The one door user files come through (issue 88): regular files only, links resolved, sizes
bounded before reading, and what a running command read no output of it may replace, by any name."""

import os

import pytest

from hrr_garment.errors import InputError, OutputError
from hrr_garment.input_files import guarding_inputs, input_file, read_by_this_command, read_input
from hrr_garment.io_utils import atomic_write_text


def test_regular_files_read_and_the_rest_refused_unopened(tmp_path):
    good = tmp_path / "good.txt"
    good.write_text("hello")
    assert read_input(good, limit=5) == b"hello"
    with pytest.raises(InputError, match="is 5 bytes, more than a note may be"):
        read_input(good, limit=4, what="a note")
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "zero").symlink_to("/dev/zero")
    (tmp_path / "folder").mkdir()
    (tmp_path / "loop").symlink_to(tmp_path / "loop")
    for name, phrase in (
        ("pipe", "a pipe, a socket or a device, not a regular file"),
        ("zero", "(a link to /dev/zero), not a regular file"),
        ("folder", "is a folder"),
        ("missing", "no such file"),
        ("loop", "cannot open"),
    ):
        with pytest.raises(InputError, match=phrase.replace("(", r"\(").replace(")", r"\)")) as err:
            read_input(tmp_path / name, limit=1 << 20)
        assert str(err.value).startswith(f"{tmp_path / name}: ")


def test_a_file_read_by_the_running_command_is_never_replaced_by_any_name(tmp_path):
    source = tmp_path / "map.json"
    atomic_write_text(source, "{}")  # no command running: nothing remembered, nothing refused
    os.link(source, tmp_path / "hard.json")
    (tmp_path / "soft.json").symlink_to(source)
    with guarding_inputs():
        input_file(source)
        assert read_by_this_command(tmp_path / "hard.json") == str(source)
        for name in ("map.json", "hard.json", "soft.json"):
            with pytest.raises(OutputError, match=f"is the input {source}"):
                atomic_write_text(tmp_path / name, "overwritten")
        atomic_write_text(tmp_path / "other.json", "{}")  # another file is written as ever
    assert source.read_text() == "{}" and read_by_this_command(source) is None
    atomic_write_text(source, "[]")  # the command is over: its inputs are files again
