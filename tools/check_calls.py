"""Find calls that pass more than N positional arguments to a function of another package module.

    python tools/check_calls.py [--max 3] [PATH ...]      # default: hrr_garment/

A long positional argument list across a module boundary is where values get swapped silently
(two ``str | None`` side by side); such calls name their arguments instead. The check resolves
callees statically: a name imported from another ``hrr_garment`` module (``from .x import f``),
or an attribute of such a module (``from . import metrics as M``; ``M.pve_mm(...)``). Calls on
objects (``self.x.f(...)``) cannot be resolved without running the code and are not counted.
Exit 1 with one line per call where any is found.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

PACKAGE = "hrr_garment"


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _absolute(module: str, is_package: bool, level: int, name: str | None) -> str:
    """The absolute module a (possibly relative) ``from`` import names."""
    if level == 0:
        return name or ""
    base = module.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def imported_callables(tree: ast.Module, module: str, is_package: bool) -> tuple[set[str], set[str]]:
    """(names imported from other package modules, aliases of package modules)."""
    names, modules = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = _absolute(module, is_package, node.level, node.module)
            if not source.startswith(PACKAGE) or source == module:
                continue
            for alias in node.names:
                bound = alias.asname or alias.name
                # ``from . import metrics`` binds a module; ``from .x import f`` a callable or class
                (modules if alias.name[:1].islower() and node.module is None else names).add(bound)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith(PACKAGE) and alias.name != module:
                    modules.add(alias.asname or alias.name)
    return names, modules


def long_calls(path: Path, root: Path, limit: int) -> list[str]:
    """``path:line: callee(N positional)`` for each call over ``limit`` positional arguments."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    module = _module_name(path, root)
    names, modules = imported_callables(tree, module, path.name == "__init__.py")
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        positional = sum(not isinstance(a, ast.Starred) for a in node.args)
        if positional <= limit:
            continue
        func = node.func
        if isinstance(func, ast.Name) and func.id in names:
            callee = func.id
        elif (
            isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id in modules
        ):
            callee = f"{func.value.id}.{func.attr}"
        else:
            continue
        found.append(f"{path}:{node.lineno}: {callee}({positional} positional)")
    return found


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="*", type=Path, default=[Path(PACKAGE)])
    p.add_argument("--max", type=int, default=3, help="positional arguments allowed (default 3)")
    args = p.parse_args(argv)
    found = []
    for top in args.paths:
        root = top.resolve().parent if top.name == PACKAGE else Path.cwd()
        files = sorted(top.rglob("*.py")) if top.is_dir() else [top]
        for path in files:
            found += long_calls(path.resolve(), root, args.max)
    print(
        "\n".join(found)
        if found
        else f"no call passes more than {args.max} positional arguments across modules"
    )
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
