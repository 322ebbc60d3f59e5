"""The ``swiptopt`` command line.

Every command turns bad input (an invalid scenario value, an unknown key, a malformed or
missing file, a wrong option) into one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.scenario import PRESETS, Scenario, ScenarioError

EXIT_BAD_INPUT = 2


def load_scenario(spec: str) -> Scenario:
    """A preset name or a path to a TOML scenario file."""
    if spec in PRESETS:
        return Scenario.preset(spec)
    path = Path(spec)
    if path.suffix.lower() == ".toml" or path.exists():
        return Scenario.from_toml(path)
    raise ScenarioError(
        f"{spec!r} is neither a preset{did_you_mean(spec, PRESETS)} ({', '.join(sorted(PRESETS))}) nor a .toml file"
    )


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

    from swiptopt.benchmark.report import scenario_tables

    console = Console()
    for table in scenario_tables(load_scenario(spec)):
        console.print(table)


# ------------------------------------------------------------------ benchmark

_store_option = click.option(
    "--store", "store_path", type=click.Path(dir_okay=False), default=None,
    help="SQLite results file (default: results/swiptopt.sqlite).",
)
_run_options = [
    click.option("--quick", is_flag=True, help="Shrink the experiment to a smoke test."),
    _store_option,
    click.option("--workers", type=int, default=None, help="Local worker processes (default: all cores)."),
    click.option("--scheduler", default=None, help="Dask scheduler address, or local:N for a local cluster."),
    click.option("--format", "fmt", type=click.Choice(["terminal", "markdown", "csv", "latex"]), default="terminal",
                 help="How to print the table."),
    click.option("--output", type=click.Path(dir_okay=False), default=None, help="Also write the table to this file."),
]


def _with_run_options(fn):  # type: ignore[no-untyped-def]
    for option in reversed(_run_options):
        fn = option(fn)
    return fn


def _run_and_report(experiment, quick, store_path, workers, scheduler, fmt, output) -> None:  # type: ignore[no-untyped-def]
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from swiptopt.benchmark.runner import execute
    from swiptopt.benchmark.store import DEFAULT_STORE, ResultStore

    if quick:
        experiment = experiment.quick()
    console = Console(stderr=True)
    with ResultStore(store_path or DEFAULT_STORE) as store:
        with Progress(
            TextColumn(f"[bold]{experiment.name}[/]"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=console, transient=False,
        ) as progress:
            bar = progress.add_task(experiment.name, total=None)

            def update(done: int, todo: int) -> None:
                progress.update(bar, completed=done, total=todo)

            report = execute(experiment, store, workers=workers, scheduler=scheduler, on_progress=update)
        console.print(
            f"{report.total} tasks: {report.cached} already stored, {report.ran} run in {report.seconds:.1f} s "
            f"-> {store.path}"
        )
        _print_table(experiment, store, fmt, output)


def _print_table(experiment, store, fmt, output) -> None:  # type: ignore[no-untyped-def]
    from rich.console import Console

    from swiptopt.benchmark import tables

    rows, missing = tables.aggregate(experiment, store)
    title = f"{experiment.name}: mean ± 95 % CI over layouts" + (f" ({missing} tasks missing)" if missing else "")
    if fmt == "terminal":
        Console(width=max(160, Console().width)).print(tables.to_rich(rows, title))
        text = tables.to_markdown(rows)  # what --output writes
    else:
        text = tables.render(rows, fmt)
        click.echo(text, nl=False)
    pairs = tables.paired(experiment, store)
    if pairs:
        paired_title = tables.paired_title(experiment)
        if fmt == "terminal":
            Console(width=max(160, Console().width)).print(tables.paired_to_rich(pairs, paired_title))
            paired_text = tables.render_paired(pairs, "markdown")
        else:
            paired_text = tables.render_paired(pairs, fmt)
            click.echo("")  # a blank line ends the first table
            click.echo(paired_text, nl=False)
        text += "\n" + paired_text
    if output:
        from pathlib import Path

        Path(output).write_text(text, encoding="utf-8")


def _builtin_list() -> list[tuple[str, str]]:
    from swiptopt.benchmark.experiment import builtin_experiments

    return [(name, e.description) for name, e in builtin_experiments().items()]


class _ListsExperiments(click.Command):
    """A command whose help ends with the built-in experiments, one line each."""

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Built-in experiments"):
            formatter.write_dl(_builtin_list())
        super().format_epilog(ctx, formatter)


class _DescribesSuite(click.Command):
    """``compare``: its help ends with what the standard suite holds, read from the experiment."""

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        from swiptopt.benchmark.experiment import builtin_experiments

        suite = builtin_experiments()["compare"]
        scenario = ", ".join(f"{k} = {v}" for k, v in suite.scenario.items())
        rows = [
            ("scenario", scenario),
            ("algorithms", ", ".join(suite.algorithms)),
            ("layouts", f"{suite.layouts} node layouts (layout seeds 0..{suite.layouts - 1}), {suite.seeds} seed each"),
            ("episodes", f"{suite.episodes} greedy evaluation episodes per task"),
            ("baseline", suite.baseline or "none"),
        ]
        with formatter.section("The standard suite (built-in experiment 'compare')"):
            formatter.write_dl(rows)
        super().format_epilog(ctx, formatter)


@cli.command(cls=_DescribesSuite)
@_with_run_options
def compare(quick, store_path, workers, scheduler, fmt, output) -> None:  # type: ignore[no-untyped-def]
    """Every algorithm on the standard suite, as one table (the main job).

    Prints every metric with a 95 % confidence interval over layouts, then every algorithm
    against the baseline, layout by layout. Finished tasks go to the store, so a second
    run only prints.
    """
    from swiptopt.benchmark.experiment import builtin_experiments

    _run_and_report(builtin_experiments()["compare"], quick, store_path, workers, scheduler, fmt, output)


def _print_builtins(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    width = max(len(name) for name, _ in _builtin_list())
    for name, description in _builtin_list():
        click.echo(f"{name:<{width}}  {description}")
    ctx.exit(0)


@cli.command(cls=_ListsExperiments)
@click.argument("spec", metavar="NAME|FILE.toml")
@click.option("--list", "list_", is_flag=True, expose_value=False, is_eager=True, callback=_print_builtins,
              help="List the built-in experiments and exit.")
@_with_run_options
def run(spec, quick, store_path, workers, scheduler, fmt, output) -> None:  # type: ignore[no-untyped-def]
    """Run a built-in experiment (by NAME) or a TOML experiment file and print its table."""
    from swiptopt.benchmark.experiment import load_experiment

    _run_and_report(load_experiment(spec), quick, store_path, workers, scheduler, fmt, output)


@cli.command()
@click.argument("what", type=click.Choice(["paper"]))
@click.option("--quick", is_flag=True, help="Shrink every experiment to a smoke test.")
@_store_option
@click.option("--workers", type=int, default=None, help="Local worker processes (default: all cores).")
@click.option("--scheduler", default=None, help="Dask scheduler address, or local:N.")
@click.option("--outdir", type=click.Path(file_okay=False), default="figures", help="Where figures and data go.")
def reproduce(what, quick, store_path, workers, scheduler, outdir) -> None:  # type: ignore[no-untyped-def]
    """Run every experiment of the paper's figures and write the figures and their data."""
    from rich.console import Console

    from swiptopt.benchmark import plots
    from swiptopt.benchmark.experiment import builtin_experiments
    from swiptopt.benchmark.runner import execute
    from swiptopt.benchmark.store import DEFAULT_STORE, ResultStore

    console = Console(stderr=True)
    written = plots.coverage_figure(outdir, quick=quick)
    console.print(f"coverage probability -> {', '.join(map(str, written))}")
    with ResultStore(store_path or DEFAULT_STORE) as store:
        for name, experiment in builtin_experiments().items():
            if not experiment.figure:
                continue
            if quick:
                experiment = experiment.quick()
            report = execute(experiment, store, workers=workers, scheduler=scheduler)
            figure = plots.experiment_figure(experiment, store, outdir)
            drawn = ", ".join(map(str, figure.paths)) or f"no figure: {figure.skipped}"
            console.print(f"{name}: {report.ran} run, {report.cached} stored -> {drawn}")


@cli.command()
@click.argument("store_path", metavar="STORE", type=click.Path(dir_okay=False))
@click.option("--experiment", "name", default=None, help="Only this experiment (default: every one in the store).")
@click.option("--format", "fmt", type=click.Choice(["terminal", "markdown", "csv", "latex"]), default="terminal")
@click.option("--output", type=click.Path(dir_okay=False), default=None)
def table(store_path, name, fmt, output) -> None:  # type: ignore[no-untyped-def]
    """Print the tables of the experiments recorded in a results store."""
    from swiptopt.benchmark.experiment import Experiment
    from swiptopt.benchmark.store import ResultStore

    with ResultStore(store_path, create=False) as store:
        runs = [r for r in store.runs() if name is None or r["experiment"] == name]
        if not runs:
            raise ConfigError(f"no run of {name!r} in {store_path}" if name else f"no runs in {store_path}", "experiment")
        for r in runs:
            _print_table(Experiment(**r["config"]), store, fmt, output)


@cli.command()
@click.argument("store_path", metavar="STORE", type=click.Path(dir_okay=False))
@click.option("--outdir", type=click.Path(file_okay=False), default="figures")
def plot(store_path, outdir) -> None:  # type: ignore[no-untyped-def]
    """Draw the figure of every experiment in a results store that defines one."""
    from swiptopt.benchmark import plots
    from swiptopt.benchmark.experiment import Experiment
    from swiptopt.benchmark.store import ResultStore

    with ResultStore(store_path, create=False) as store:
        drawn = []
        for r in store.runs():
            experiment = Experiment(**r["config"])
            if not experiment.figure:
                continue
            figure = plots.experiment_figure(experiment, store, outdir)
            if figure.skipped:
                click.echo(f"{experiment.name}: no figure: {figure.skipped}", err=True)
            drawn += figure.paths
    if not drawn:
        raise ConfigError(f"no figure to draw from {store_path}", "figure")
    click.echo("\n".join(map(str, drawn)))


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
