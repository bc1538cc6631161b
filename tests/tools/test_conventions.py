"""The package's conventions that no linter holds: calls across modules name their arguments past
the third (tools/check_calls.py)."""

import textwrap
from pathlib import Path

from tests.scripts import load_script

ROOT = Path(__file__).resolve().parents[2]


def _check_calls():
    return load_script("tools/check_calls.py")


def test_no_call_passes_more_than_three_positional_arguments_to_another_module():
    check = _check_calls()
    found = [
        line
        for path in sorted((ROOT / "hrr_garment").rglob("*.py"))
        for line in check.long_calls(path, ROOT, 3)
    ]
    assert not found, "\n".join(found)


def test_the_call_check_finds_long_calls_across_modules_only(tmp_path):
    check = _check_calls()
    package = tmp_path / "hrr_garment"
    (package / "inner").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "inner" / "__init__.py").write_text("")
    (package / "low.py").write_text("def f(a, b, c, d):\n    return a\n")
    (package / "inner" / "user.py").write_text(
        textwrap.dedent("""\
        from ..low import f
        from .. import low as L

        def g(a, b, c, d):
            return a

        f(1, 2, 3, 4)
        f(1, 2, 3, d=4)
        L.f(1, 2, 3, 4)
        g(1, 2, 3, 4)
        """)
    )
    found = check.long_calls(package / "inner" / "user.py", tmp_path, 3)
    assert [line.split(": ", 1)[1] for line in found] == ["f(4 positional)", "L.f(4 positional)"]
    assert [int(line.split(":")[1]) for line in found] == [7, 9]
