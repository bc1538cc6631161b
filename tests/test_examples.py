"""The examples (examples/): each runs headless against the tiny model."""

import pytest

pytestmark = pytest.mark.tool


def test_game_loop_example_runs_headless(trained, tmp_path, capsys):
    import importlib.util
    from pathlib import Path

    root, _, _ = trained
    spec = importlib.util.spec_from_file_location(
        "game_loop", Path(__file__).parents[1] / "examples" / "game_loop.py"
    )
    game_loop = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(game_loop)
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
