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
