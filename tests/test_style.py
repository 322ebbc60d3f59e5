"""The habits that keep the code readable, checked on every test run.

- No function in ``swiptopt/``, ``planners/`` or ``rl/`` is longer than
  :data:`MAX_FUNCTION_LINES` lines, counted from its ``def`` line to its last line, docstring
  included, except those in :data:`LONG_FUNCTIONS`, each with its reason.
- ``ruff check`` (the configuration in ``pyproject.toml``: pycodestyle, pyflakes, import
  order, bugbear, pyupgrade and a McCabe complexity limit) reports nothing on the repository.
"""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("swiptopt", "planners", "rl")
MAX_FUNCTION_LINES = 80

#: (file, function) -> why it may be longer than :data:`MAX_FUNCTION_LINES` (a method is
#: named ``Class.method``).
LONG_FUNCTIONS = {
    ("swiptopt/kernel.py", "serve_pairs"): (
        "one AUV's part of a step, compiled by numba with the step and run as the Python reference "
        "from the same source: one pass over the covered pairs in the model's order (its def "
        "says more)"
    ),
}


def function_lengths(source: str) -> dict[str, int]:
    """Lines of each function and method in ``source`` (``def`` line to last line), by its
    dotted name within the module (``Class.method``, ``outer.inner``)."""
    out: dict[str, int] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    out[name] = child.end_lineno - child.lineno + 1  # type: ignore[operator]
                visit(child, name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return out


def too_long(lengths: dict[str, int], path: str) -> dict[str, int]:
    """The functions of ``path`` over the limit and not allowed to be."""
    return {
        name: n for name, n in lengths.items()
        if n > MAX_FUNCTION_LINES and (path, name) not in LONG_FUNCTIONS
    }


def _package_lengths() -> dict[str, dict[str, int]]:
    return {
        path.relative_to(ROOT).as_posix(): function_lengths(path.read_text(encoding="utf-8"))
        for package in PACKAGES
        for path in sorted((ROOT / package).rglob("*.py"))
    }


def test_functions_are_at_most_80_lines():
    found = {
        f"{path}:{name}": n
        for path, lengths in _package_lengths().items()
        for name, n in too_long(lengths, path).items()
    }
    assert not found, (
        f"functions over {MAX_FUNCTION_LINES} lines (split them into named steps, or add them to "
        f"LONG_FUNCTIONS with the reason): {found}"
    )


def test_every_long_function_allowed_is_still_there_and_still_long():
    """An entry of the allowlist goes once its function is split (or gone)."""
    lengths = _package_lengths()
    stale = [
        key for key in LONG_FUNCTIONS
        if lengths.get(key[0], {}).get(key[1], 0) <= MAX_FUNCTION_LINES
    ]
    assert not stale, f"no longer over {MAX_FUNCTION_LINES} lines: remove from LONG_FUNCTIONS: {stale}"


def test_the_length_check_can_fail():
    source = "def short():\n    return 1\n\n\nclass A:\n    def long(self):\n" + "        x = 1\n" * 80
    lengths = function_lengths(source)
    assert lengths == {"short": 2, "A.long": 81}
    assert too_long(lengths, "planners/x.py") == {"A.long": 81}
    assert too_long({"serve_pairs": 121}, "swiptopt/kernel.py") == {}


def test_ruff_reports_nothing():
    if importlib.util.find_spec("ruff") is None:
        pytest.skip("ruff is not installed")
    run = subprocess.run([sys.executable, "-m", "ruff", "check", "--quiet", str(ROOT)], cwd=ROOT,
                         capture_output=True, text=True)
    assert run.returncode == 0, f"ruff check:\n{run.stdout}{run.stderr}"
