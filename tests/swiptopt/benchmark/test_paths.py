"""Output paths and scheduler addresses are checked before anything runs: one line, exit 2,
no store created, nothing written."""

import shutil

import pytest

from swiptopt.benchmark.experiment import Experiment
from swiptopt.benchmark.runner import execute
from swiptopt.benchmark.store import ResultStore
from swiptopt.cli import main
from tests.swiptopt.benchmark.test_store import cli_unprivileged

TINY_TOML = """
name = "tiny-paths"
layouts = 1
episodes = 1
[scenario]
preset = "paper"
n_nodes = 4
[algorithms.random]
"""


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    path = tmp_path_factory.mktemp("paths") / "s.sqlite"
    with ResultStore(path) as s:
        execute(Experiment.from_toml(_write(path.parent / "e.toml", TINY_TOML)), s, workers=1)
    return path


def _write(path, text):
    path.write_text(text)
    return path


def refused(capsys, args, *words):
    code = main(args)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1, lines
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--output", "{tmp}/no/dir/t.md"], ["--output", "does not exist"]),
        (["--output", "{tmp}/e.toml/t.md"], ["--output", "is a file, not a directory"]),
        (["--output", "{tmp}"], ["--output", "directory"]),
        (["--scheduler", "::::"], ["scheduler = '::::'", "not a scheduler address"]),
        (["--scheduler", "local:-1"], ["scheduler = 'local:-1'"]),
        (["--workers", "0"], ["workers = 0"]),
        (["--workers", "2", "--scheduler", "local:2"], ["not both"]),
    ],
)
def test_run_refuses_bad_paths_and_addresses_before_any_task(tmp_path, capsys, extra, words):
    exp = _write(tmp_path / "e.toml", TINY_TOML)
    store = tmp_path / "s.sqlite"
    refused(capsys, ["run", str(exp), "--store", str(store), *[e.format(tmp=tmp_path) for e in extra]], *words)
    assert not store.exists()  # checked before the store opened, so before any task


def test_table_plot_and_reproduce_refuse_bad_outputs(stored, tmp_path, capsys):
    afile = _write(tmp_path / "afile", "x")
    refused(capsys, ["table", str(stored), "--output", str(tmp_path / "no" / "t.md")], "--output", "does not exist")
    refused(capsys, ["plot", str(stored), "--outdir", str(afile / "figs")], "--outdir", "is a file")
    refused(capsys, ["plot", str(stored), "--outdir", str(afile)], "--outdir")
    store = tmp_path / "new.sqlite"
    refused(capsys, ["reproduce", "paper", "--store", str(store), "--outdir", str(afile / "figs")], "--outdir")
    refused(capsys, ["reproduce", "paper", "--store", str(store), "--scheduler", "tcp://h"], "scheduler = ")
    assert not store.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_outputs_in_a_read_only_directory_are_refused(stored, tmp_path):
    closed = tmp_path / "closed"
    closed.mkdir()
    closed.chmod(0o555)
    try:
        for args in (["table", str(stored), "--output", str(closed / "t.md")],
                     ["plot", str(stored), "--outdir", str(closed / "figs")],
                     ["reproduce", "paper", "--store", str(tmp_path / "r.sqlite"), "--outdir", str(closed / "figs")]):
            result = cli_unprivileged(*args)
            lines = result.stderr.strip().splitlines()
            assert result.returncode == 2 and len(lines) == 1, result.stderr
            assert "not writable" in lines[0] and "Traceback" not in result.stderr
        assert list(closed.iterdir()) == [] and not (tmp_path / "r.sqlite").exists()
    finally:
        closed.chmod(0o755)


def test_table_writes_every_experiment_to_its_output(stored, tmp_path, capsys):
    store = tmp_path / "two.sqlite"
    shutil.copy(stored, store)
    other = Experiment.from_toml(_write(tmp_path / "o.toml", TINY_TOML.replace("tiny-paths", "second")))
    with ResultStore(store) as s:
        execute(other, s, workers=1)
    output = tmp_path / "t.md"
    assert main(["table", str(store), "--format", "markdown", "--output", str(output)]) == 0
    printed = capsys.readouterr().out
    assert output.read_text().count("| algorithm |") == 2 and printed.count("| algorithm |") == 2
