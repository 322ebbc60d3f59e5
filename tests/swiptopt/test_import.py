import subprocess
import sys

HEAVY = (
    "cvxpy", "ortools", "ompl", "dask", "distributed", "matplotlib", "sklearn", "numba", "pandas", "scipy", "rich",
    "click",
)


def test_import_is_light_and_silent():
    code = (
        "import sys, swiptopt, swiptopt.coverage, swiptopt.link;"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
    assert result.stderr == ""
    quiet = subprocess.run([sys.executable, "-c", "import swiptopt"], capture_output=True, text=True, check=True)
    assert quiet.stdout == "" and quiet.stderr == ""
