"""The analysis notebooks run top to bottom, stay stripped and match their sources.

Each notebook is written as a Jupytext percent-format script (``notebooks/NN_name.py``, the
file to read and edit) paired with a committed ``.ipynb`` without outputs
(``jupytext --sync notebooks/*.py`` refreshes the pair).

Each notebook is executed with nbclient on small settings (``SWIPTOPT_NOTEBOOK_QUICK=1``)
in a kernel that runs this interpreter, from a temporary working directory, so a notebook
that no longer works with the library fails here instead of rotting. One test per
notebook, so pytest-xdist spreads them over workers.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
jupytext = pytest.importorskip("jupytext")
pytest.importorskip("ipykernel")

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
SOURCES = sorted(NOTEBOOK_DIR.glob("[0-9][0-9]_*.py"))
CELL_TIMEOUT_S = 300

# Run first in the kernel: fail unless the kernel is this interpreter, and record every
# figure whose axes lack labels (checked by AXES_CHECK at the end). The figure check runs
# after each cell, before the inline backend shows and closes the cell's figures (so the
# notebooks leave figures to the backend rather than calling plt.show()).
KERNEL_SETUP = """
import sys
assert sys.executable == {executable!r}, f"the kernel runs {{sys.executable}}, not {executable!r}"

def _unlabelled_axes():
    import matplotlib.pyplot as plt

    def labelled(ax, axis):
        # a twin axes shares the label of its sibling (3D axes have no shared z axes)
        shared = getattr(ax, f"get_shared_{{axis}}_axes", None)
        siblings = shared().get_siblings(ax) if shared else [ax]
        return any(getattr(a, f"get_{{axis}}label")().strip() for a in siblings)

    found = []
    for number in plt.get_fignums():
        for ax in plt.figure(number).axes:
            # axes switched off (axis("off")) need no labels; 3D axes always report axison False
            if not ax.get_visible() or (ax.name != "3d" and not ax.axison):
                continue
            if ax.get_label() == "<colorbar>":
                if not (ax.get_xlabel().strip() or ax.get_ylabel().strip()):
                    found.append(f"figure {{number}}: a colour bar without a label")
                continue
            axes = ("x", "y", "z") if ax.name == "3d" else ("x", "y")
            missing = [a for a in axes if not labelled(ax, a)]
            if missing:
                found.append(f"figure {{number}}, axes {{ax.get_title()!r}}: no {{'/'.join(missing)}} label")
    return found

def _record_unlabelled():
    # IPython only prints what a callback raises: record it, so the final check fails
    try:
        _unlabelled.extend(_unlabelled_axes())
    except Exception as exc:
        _unlabelled.append(f"the axes check itself failed: {{exc!r}}")

_unlabelled = []
get_ipython().events.callbacks["post_execute"].insert(0, _record_unlabelled)
"""

AXES_CHECK = """
assert not _unlabelled, "axes without labels: " + "; ".join(_unlabelled)
"""


@pytest.fixture
def kernel_home(tmp_path, monkeypatch):
    """A ``python3`` kernel spec that runs this interpreter, found first on JUPYTER_PATH,
    and the quick settings in the kernel's environment."""
    from ipykernel.kernelspec import make_ipkernel_cmd

    spec_dir = tmp_path / "jupyter" / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = {
        "argv": make_ipkernel_cmd(executable=sys.executable),
        "display_name": "Python 3 (swiptopt tests)",
        "language": "python",
    }
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("IPYTHONDIR", str(tmp_path / "ipython"))
    monkeypatch.setenv("SWIPTOPT_NOTEBOOK_QUICK", "1")
    monkeypatch.setenv("PYDEVD_DISABLE_FILE_VALIDATION", "1")
    workdir = tmp_path / "work"
    workdir.mkdir()
    return workdir


def test_every_source_has_its_notebook():
    assert len(SOURCES) >= 4
    assert [p.stem for p in NOTEBOOKS] == [p.stem for p in SOURCES]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_runs(path, kernel_home):
    nb = nbformat.read(path, as_version=4)
    setup = nbformat.v4.new_code_cell(KERNEL_SETUP.format(executable=sys.executable), id="test-setup")
    check = nbformat.v4.new_code_cell(AXES_CHECK, id="test-axes-check")
    nb.cells = [setup, *nb.cells, check]
    client = nbclient.NotebookClient(
        nb,
        kernel_name="python3",
        timeout=CELL_TIMEOUT_S,
        resources={"metadata": {"path": str(kernel_home)}},
    )
    client.execute()  # raises CellExecutionError, naming the cell, on any error
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_stripped(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [], f"{path.name}: a code cell has outputs"
            assert cell.execution_count is None, f"{path.name}: a code cell has an execution count"
    assert nb.metadata.get("kernelspec", {}).get("name") == "python3"


def _cells(nb) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source) for c in nb.cells]


@pytest.mark.parametrize("source", SOURCES, ids=lambda p: p.stem)
def test_notebook_matches_its_source(source):
    paired = source.with_suffix(".ipynb")
    script = jupytext.read(source)
    notebook = nbformat.read(paired, as_version=4)
    assert _cells(notebook) == _cells(script), f"{paired.name} differs from {source.name}: run jupytext --sync {source}"
    assert notebook.metadata.get("jupytext", {}).get("formats") == "ipynb,py:percent"


def test_the_source_check_can_fail(tmp_path):
    # a notebook whose cell was edited without syncing is caught
    source = SOURCES[0]
    script = jupytext.read(source)
    notebook = nbformat.read(source.with_suffix(".ipynb"), as_version=4)
    notebook.cells[1].source += "\nprint('edited in the notebook only')"
    assert _cells(notebook) != _cells(script)
