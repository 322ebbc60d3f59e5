"""The ``swiptopt`` command line.

Every command turns bad input (an invalid scenario value, an unknown key, a malformed or
missing file, a wrong option) into one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from swiptopt.errors import ConfigError
from swiptopt.scenario import PRESETS, Scenario, ScenarioError

EXIT_BAD_INPUT = 2


def load_scenario(spec: str) -> Scenario:
    """A preset name or a path to a TOML scenario file."""
    if spec in PRESETS:
        return Scenario.preset(spec)
    path = Path(spec)
    if path.suffix.lower() == ".toml" or path.exists():
        return Scenario.from_toml(path)
    raise ScenarioError(f"{spec!r} is neither a preset ({', '.join(sorted(PRESETS))}) nor a .toml file")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="swiptopt")
def cli() -> None:
    """swiptopt: RL agents versus classical planners for an AUV serving an underwater
    sensor network with acoustic SWIPT."""


@cli.group()
def scenario() -> None:
    """Inspect scenarios (presets or TOML files)."""


@scenario.command("show")
@click.argument("spec", metavar="PRESET|FILE.toml")
def scenario_show(spec: str) -> None:
    """Print a scenario's parameters with units, its link budget and the AUV's power."""
    from rich.console import Console

    from swiptopt.report import scenario_tables

    console = Console()
    for table in scenario_tables(load_scenario(spec)):
        console.print(table)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    try:
        cli.main(args=argv, prog_name="swiptopt", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 1
    except click.UsageError as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return EXIT_BAD_INPUT
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)
        return exc.exit_code
    except ConfigError as exc:
        click.echo(f"error: {exc}".splitlines()[0], err=True)
        return EXIT_BAD_INPUT
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
