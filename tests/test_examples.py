"""The examples (examples/): each runs headless against the tiny model."""

import pytest

from tests.scripts import load_script

pytestmark = pytest.mark.tool


def test_game_loop_example_runs_headless(trained, tmp_path, capsys):

    root, _, _ = trained
    game_loop = load_script("examples/game_loop.py")
    frames = tmp_path / "frames"
    assert (
        game_loop.main(
            [
                "--model",
                str(root / "model"),
                "--headless",
                "--seconds",
                "1",
                "--frames-dir",
                str(frames),
                "--save-every",
                "8",
                "--size",
                "64",
            ]
        )
        == 0
    )
    assert sorted(p.name for p in frames.iterdir()) == [f"frame_{t:05d}.png" for t in range(0, 30, 8)]
    assert "crowd.push p50" in capsys.readouterr().out
