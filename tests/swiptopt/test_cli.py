import subprocess
import sys

import pytest

from swiptopt.cli import main


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "swiptopt.cli", *args], capture_output=True, text=True)


@pytest.mark.parametrize("preset", ["paper", "harbour", "tiny"])
def test_scenario_show_prints_parameters_and_link_budget(preset, capsys):
    assert main(["scenario", "show", preset]) == 0
    out = capsys.readouterr().out
    for text in ("n_nodes", "source level", "noise level", "harvested", "energy of one move", "197.79"):
        assert text in out
    assert "81.85" in out or preset == "harbour"  # the paper's noise level, dB re 1 uPa


def test_scenario_show_paper_table1(capsys):
    assert main(["scenario", "show", "paper-table1"]) == 0
    out = capsys.readouterr().out
    # Table I: the nodes' 170 dB re 1 uPa @ 1 m, on the uplink, 100-byte packets, 100 mW circuit
    for text in ("Scenario 'paper-table1'", "uplink", "170.00", "800", "0.1", "Uplink (each node to the AUV"):
        assert text in out
    # node to AUV at 10 m: 197.79 - 170.00 = 27.79 dB below the AUV's 100.88 dB
    assert "73.07" in out


def test_scenario_show_a_file(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text('preset = "tiny"\nsplit_ratio = 0.25\n')
    assert main(["scenario", "show", str(path)]) == 0
    assert "split ratio 0.25" in capsys.readouterr().out


@pytest.mark.parametrize(
    "content, words",
    [
        ("n_nodes = -3\n", ["n_nodes", "-3"]),
        ("split_ratio = 1.5\n", ["split_ratio", "1.5"]),
        ("frequency = 24.0\n", ["frequency"]),
        ("n_nodes = [\n", ["malformed TOML"]),
    ],
)
def test_bad_file_prints_one_line_and_exits_2(tmp_path, content, words):
    path = tmp_path / "bad.toml"
    path.write_text(content)
    result = run_cli("scenario", "show", str(path))
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr
    for word in words:
        assert word in lines[0]


def test_unknown_preset_and_command_exit_2():
    for args in (("scenario", "show", "ocean"), ("scenario", "shw", "paper")):
        result = run_cli(*args)
        assert result.returncode == 2
        assert len(result.stderr.strip().splitlines()) == 1


def test_run_help_and_list_name_every_builtin_experiment(capsys):
    from swiptopt.benchmark.experiment import builtin_experiments

    builtins = builtin_experiments()
    for args in (["run", "--help"], ["run", "--list"]):
        assert main(args) == 0
        out = capsys.readouterr().out
        for name in builtins:
            assert name in out, f"{args}: {name} not listed"
    # --list prints exactly one line per experiment, name first, with its description
    assert main(["run", "--list"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [line.split()[0] for line in lines] == list(builtins)
    assert all(builtins[line.split()[0]].description in line for line in lines)


def test_compare_help_describes_the_suite(capsys):
    from swiptopt.benchmark.experiment import builtin_experiments

    suite = builtin_experiments()["compare"]
    assert main(["compare", "--help"]) == 0
    out = capsys.readouterr().out
    assert "standard suite" in out and f"{suite.layouts} node layouts" in out
    assert all(name in out for name in suite.algorithms)


@pytest.mark.parametrize(
    "args, suggestion",
    [
        (("run", "fig-efficency-vs-nodes"), "fig-efficiency-vs-nodes"),
        (("scenario", "show", "papr"), "paper"),
    ],
)
def test_mistyped_names_suggest_the_closest(args, suggestion):
    result = run_cli(*args)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"did you mean {suggestion!r}" in result.stderr


def test_mistyped_algorithm_suggests_the_closest(tmp_path):
    path = tmp_path / "e.toml"
    path.write_text('name = "e"\n[algorithms.qlearning]\n')
    result = run_cli("run", str(path))
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "did you mean 'q_learning'" in result.stderr
