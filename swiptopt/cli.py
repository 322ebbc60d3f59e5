"""The ``swiptopt`` command line.

Every command turns bad input (an invalid scenario value, an unknown key, a malformed or
missing file, a wrong option) into one line on stderr and exit code 2, never a traceback.

An experiment file's ``[plugins]`` (code it names, to import and run) are honoured only
with ``--allow-plugins``; ``table`` and ``plot`` read a store without running any code it
names.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections import Counter
from pathlib import Path

import click

from swiptopt.errors import ConfigError, did_you_mean
from swiptopt.files import existing_ancestor
from swiptopt.scenario import PRESETS, Scenario, ScenarioError

EXIT_BAD_INPUT = 2
#: Exit code of a run that finished but recorded failed tasks (the table is still printed).
EXIT_TASKS_FAILED = 1


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

    from swiptopt.scenario_report import scenario_tables

    console = Console()
    for table in scenario_tables(load_scenario(spec)):
        console.print(table)


# ------------------------------------------------------------------ benchmark


def check_output_file(path: str | None, option: str) -> None:
    """Refuse, before anything runs, an output file that cannot be written: a directory, a
    missing or non-directory parent, or no write permission."""
    if path is None:
        return
    target = Path(path)
    parent = target.parent
    if target.is_dir():
        raise ConfigError(f"{option} {path}: is a directory; give a file name", option)
    if not parent.exists():
        raise ConfigError(f"{option} {path}: the directory {str(parent)!r} does not exist", option)
    if not parent.is_dir():
        raise ConfigError(f"{option} {path}: {str(parent)!r} is a file, not a directory", option)
    if target.exists() and not os.access(target, os.W_OK):
        raise ConfigError(f"{option} {path}: the file is not writable", option)
    if not target.exists() and not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"{option} {path}: the directory {str(parent)!r} is not writable", option)


def check_output_dir(path: str, option: str) -> None:
    """Refuse, before anything runs, an output directory that cannot be made or written."""
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise ConfigError(f"{option} {path}: is a file, not a directory", option)
    ancestor = existing_ancestor(target)
    if not ancestor.is_dir():
        raise ConfigError(f"{option} {path}: {str(ancestor)!r} is a file, not a directory", option)
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise ConfigError(f"{option} {path}: the directory {str(ancestor)!r} is not writable", option)


def _write_output(path: str, text: str) -> None:
    try:
        Path(path).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"--output {path}: cannot write: {exc.strerror}", "output") from None


def _report_failures(console, failures) -> None:  # type: ignore[no-untyped-def]
    """How many tasks failed and why, most common reason first."""
    if not failures:
        return
    tasks = f"{len(failures)} task{'s' * (len(failures) != 1)}"
    console.print(f"{tasks} failed (recorded in the store; a rerun retries them):")
    for reason, count in Counter(f.reason for f in failures).most_common():
        console.print(f"  {count} x {reason}", markup=False, highlight=False)


#: The options several commands share, declared once; :func:`_options` attaches them.
_OPTIONS = {
    "quick": click.option("--quick", is_flag=True, help="Shrink the experiments to a smoke test."),
    "store": click.option("--store", "store_path", type=click.Path(dir_okay=False), default=None,
                          help="SQLite results file (default: results/swiptopt.sqlite)."),
    "workers": click.option("--workers", type=int, default=None, help="Local worker processes (default: all cores)."),
    "scheduler": click.option("--scheduler", default=None,
                              help="Dask scheduler address, or local:N for a local cluster."),
    "format": click.option("--format", "fmt", type=click.Choice(["terminal", "markdown", "csv", "latex"]),
                           default="terminal", help="How to print the tables."),
    "output": click.option("--output", type=click.Path(dir_okay=False), default=None,
                           help="Also write the tables to this file."),
    "retrain": click.option("--retrain", is_flag=True,
                            help="Train every deep-RL model here instead of reusing the models shipped with "
                                 "swiptopt (models in the store's own models/ are still reused)."),
    "keep_state": click.option("--keep-state", is_flag=True,
                               help="Keep the state of each lineage's longest deep-RL training at its end in the "
                                    "store's models/ (hundreds of MB for SAC and DQN: their replay buffers), so that "
                                    "a longer budget added later goes on from it instead of from the start."),
}
#: What compare and run take: every option of a run and of its printed tables.
_RUN_OPTIONS = ("quick", "store", "workers", "scheduler", "format", "output", "retrain", "keep_state")


def _options(*names: str):  # type: ignore[no-untyped-def]
    """Attach the shared options ``names`` (:data:`_OPTIONS`), in that order."""

    def attach(fn):  # type: ignore[no-untyped-def]
        for name in reversed(names):
            fn = _OPTIONS[name](fn)
        return fn

    return attach


_with_run_options = _options(*_RUN_OPTIONS)


_allow_plugins_option = click.option(
    "--allow-plugins", is_flag=True,
    help="Honour the experiment file's [plugins]: import the modules they name and run their code.",
)


def _scheduler_client(scheduler: str | None):  # type: ignore[no-untyped-def]
    """A client of a remote ``--scheduler``, connected before the store is opened, so an
    unreachable one leaves no store behind (a ``local:N`` cluster starts with each run)."""
    from swiptopt.benchmark.runner import dask_client

    if scheduler is None or scheduler.startswith("local:"):
        return contextlib.nullcontext(None)
    return dask_client(scheduler)


def _pretrained(retrain: bool) -> tuple[str, ...]:
    """The directories of shipped models a run may reuse (none with ``--retrain``)."""
    from swiptopt.benchmark.runner import PRETRAINED_DIR

    return () if retrain or not PRETRAINED_DIR.is_dir() else (str(PRETRAINED_DIR),)


def _check_before_running(experiments, store, retrain: bool) -> None:  # type: ignore[no-untyped-def]
    """What every experiment of a run needs of the store, checked before any task runs: a
    usable models directory and, with ``--retrain``, no result from a shipped model."""
    from swiptopt.benchmark.runner import check_models_for, check_retrain

    for experiment in experiments:
        check_models_for(experiment, store, _pretrained(retrain))
        if retrain:
            check_retrain(experiment, store)


#: Seconds between two status lines of a run whose stderr is not a terminal (a log file, CI).
STATUS_INTERVAL_S = 60.0


def _training_label(task) -> str:  # type: ignore[no-untyped-def]
    """A training under way, as its status row names it."""
    from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT

    where = "across layouts" if task.training_layouts is not None else f"layout {task.scenario.get('layout_seed')}"
    return f"  training {task.algorithm} (seed {task.seed % SEEDS_PER_LAYOUT}, {where})"


@contextlib.contextmanager
def _run_status(console, name: str):  # type: ignore[no-untyped-def]
    """How far a run of the experiment ``name`` has got, on ``console`` (stderr), as
    ``(on_progress, on_training)`` for :func:`~swiptopt.benchmark.runner.execute`: in a
    terminal, rich's bars (the tasks, and one per deep-RL training under way, with its
    steps, or decisions, and the time it has left); elsewhere a plain line at most every
    :data:`STATUS_INTERVAL_S` seconds, and one at the end."""
    import time

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TaskID,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from swiptopt.benchmark.experiment import training_unit

    start, last = time.monotonic(), [-float("inf")]

    def line(progress: Progress, force: bool = False) -> None:
        """The plain status line, from the bars' own counts (the first bar is the tasks')."""
        now = time.monotonic()
        if console.is_terminal or (not force and now - last[0] < STATUS_INTERVAL_S):
            return
        last[0] = now
        elapsed = int(now - start)
        tasks, *trainings = progress.tasks
        parts = [f"{name}: {int(tasks.completed)}/{int(tasks.total or 0)} tasks, "
                 f"{elapsed // 3600}:{elapsed // 60 % 60:02d}:{elapsed % 60:02d}"]
        parts += [f"{t.description.strip()}: {int(t.completed):,}/{int(t.total or 0):,} {t.fields['unit']}"
                  for t in trainings]
        console.print("; ".join(parts), markup=False, highlight=False, soft_wrap=True)

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("eta"), TimeRemainingColumn(), console=console, transient=False,
                  disable=not console.is_terminal) as progress:
        bar = progress.add_task(f"[bold]{name}[/]", total=None)
        rows: dict[str, TaskID] = {}  # a training's task key -> its bar

        def on_progress(done: int, todo: int) -> None:
            progress.update(bar, completed=done, total=todo)
            line(progress, force=done in (0, todo))

        def on_training(task, steps: int, total: int, finished: bool) -> None:  # type: ignore[no-untyped-def]
            if finished:
                if task.key in rows:
                    progress.remove_task(rows.pop(task.key))
                return
            if task.key not in rows:
                rows[task.key] = progress.add_task(_training_label(task), total=total, completed=steps,
                                                   unit=training_unit(task.algorithm))
            else:
                progress.update(rows[task.key], completed=steps)
            line(progress)

        yield on_progress, on_training


def _run_and_report(experiments, quick, store_path, workers, scheduler, fmt, output,  # type: ignore[no-untyped-def]
                    caption=False, retrain=False, keep_state=False, expect_shipped=False) -> None:
    """Run the experiments one after the other into one store, print each one's tables as
    it finishes (``caption``: each under its name and world, also in
    the text formats), and write them all to ``output``. ``expect_shipped``: the run is
    meant to reuse the shipped models (``compare``), so say first if it will train any."""
    from rich.console import Console

    from swiptopt.benchmark import tables
    from swiptopt.benchmark.runner import check_run_options, execute
    from swiptopt.benchmark.store import DEFAULT_STORE, ResultStore

    if quick:
        experiments = [e.quick() for e in experiments]
    # every path and address is checked before the store opens and any task runs
    check_output_file(output, "--output")
    check_run_options(workers, scheduler)
    console = Console(stderr=True)
    texts, failures, reports = [], [], []
    with _scheduler_client(scheduler) as client, ResultStore(store_path or DEFAULT_STORE) as store:
        _check_before_running(experiments, store, retrain)
        if expect_shipped and not retrain:
            _say_what_trains(console, experiments, store, quick)
        for experiment in experiments:
            with _run_status(console, experiment.name) as (on_progress, on_training):
                report = execute(experiment, store, workers=workers, scheduler=scheduler, on_progress=on_progress,
                                 on_training=on_training, pretrained=_pretrained(retrain), client=client,
                                 keep_state=keep_state)
            failed = f", {report.failed} failed" if report.failed else ""
            console.print(
                f"{report.total} tasks: {report.cached} already stored, {report.ran} run{failed} in "
                f"{report.seconds:.1f} s -> {store.path}"
            )
            reports.append(tables.report(experiment, store))
            texts.append(_print_report(reports[-1], fmt, caption=caption))
            failures += report.failures
        texts += _print_curves(reports, fmt)
    if output:
        _write_output(output, "\n".join(texts))
    _report_failures(console, failures)
    if failures:
        raise click.exceptions.Exit(EXIT_TASKS_FAILED)


def _say_what_trains(console, experiments, store, quick=False) -> None:  # type: ignore[no-untyped-def]
    """One line before a run that was to reuse the shipped models but will train some: how
    many, of which algorithms, and why (the shipped ones are named for the package
    versions ``make`` installs; :func:`swiptopt.benchmark.runner.models_to_train`)."""
    from rl.deep import model_versions
    from swiptopt.benchmark.runner import models_to_train
    from swiptopt.fpmath import torch_cpu_path_overrides

    missing = [a for e in experiments for a in models_to_train(e, store, _pretrained(False))]
    if not missing:
        return
    names = ", ".join(f"{n} {name}" for name, n in sorted(Counter(missing).items()))
    versions = ", ".join(f"{package} {v}" for package, v in model_versions().items())
    paths = "".join(f", {name}={value}" for name, value in torch_cpu_path_overrides().items())
    console.print(f"{len(missing)} deep-RL models ({names}) are neither in the store's models/ nor shipped for "
                  f"this installation ({versions}{paths}; the shipped ones are named for the versions `make` "
                  "installs from constraints.txt and for torch's pinned CPU paths): they are trained now"
                  + ("" if quick else ", which takes hours on 2 cores"), markup=False, highlight=False)


def _print_curves(reports, fmt) -> list[str]:  # type: ignore[no-untyped-def]
    """The learning curves of the reports with budgets, as one table (Markdown in the
    terminal and Markdown formats); returns its text for --output (none without budgets)."""
    from swiptopt.benchmark import tables

    rows = [row for r in reports for row in r.curves]
    if not rows or fmt in ("csv", "latex"):
        return []
    text = tables.render_curves(rows)
    click.echo("")
    click.echo(text, nl=False)
    return [text]


def _print_report(r, fmt, caption: bool = False) -> str:  # type: ignore[no-untyped-def]
    """Print one experiment's report (:func:`swiptopt.benchmark.tables.report`); returns its
    text for --output (Markdown for the terminal format).

    The terminal titles name the experiment and its world. With ``caption`` (``compare``'s
    suites, or several experiments printed one after the other), the text formats start
    with a caption line that does so too (Markdown: a bold line; LaTeX: a comment; CSV: a
    line on stderr, so the data stays plain CSV)."""
    from rich.console import Console

    from swiptopt.benchmark import tables

    text = tables.render_report(r, fmt, caption=caption)
    if caption and fmt == "csv":
        click.echo(r.title, err=True)
    if fmt == "terminal":
        console = Console(width=max(160, Console().width))
        console.print(tables.to_rich(r.rows, r.heading))
        if r.pairs:
            console.print(tables.paired_to_rich(r.pairs, r.paired_heading))
    else:
        click.echo(text, nl=False)
        if r.note:
            click.echo(f"{r.experiment.name}: {r.note}", err=True)
    return text


def _builtin_list() -> list[tuple[str, str]]:
    from swiptopt.benchmark.experiment import builtin_experiments

    return [(name, e.description) for name, e in builtin_experiments().items()]


class _ListsExperiments(click.Command):
    """A command whose help ends with the built-in experiments, one line each."""

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Built-in experiments"):
            formatter.write_dl(_builtin_list())
        super().format_epilog(ctx, formatter)


#: ``compare --suite``: the suites by name, as built-in experiments, in the order they run.
SUITES = {"standard": ("compare",), "harbour": ("harbour",), "all": ("compare", "harbour")}
#: What the help calls each suite.
_SUITE_HEADINGS = {"compare": "The standard suite (built-in experiment 'compare')",
                   "harbour": "The harbour suite (built-in experiment 'harbour')"}


class _DescribesSuite(click.Command):
    """``compare``: its help ends with what each suite holds, read from the experiments."""

    def format_epilog(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        from swiptopt.benchmark.experiment import builtin_experiments

        for name, heading in _SUITE_HEADINGS.items():
            suite = builtin_experiments()[name]
            scenario = ", ".join(f"{k} = {v}" for k, v in suite.scenario.items())
            rows = [
                ("world", suite.world),
                ("scenario", scenario),
                ("algorithms", ", ".join(suite.algorithms)),
                ("layouts", f"{len(suite.layout_seeds())} node layouts (layout seeds "
                            f"{', '.join(map(str, suite.layout_seeds()))}), {suite.seeds} seed each "
                            "(deep RL: its training_seeds)"),
                ("episodes", f"{suite.episodes} greedy evaluation episodes per task"),
                ("baseline", suite.baseline or "none"),
            ]
            with formatter.section(heading):
                formatter.write_dl(rows)
        super().format_epilog(ctx, formatter)


@cli.command(cls=_DescribesSuite)
@click.option("--suite", type=click.Choice(list(SUITES)), default="all", show_default=True,
              help="standard: the paper's grid world; harbour: the continuous world around obstacles; all: both.")
@_with_run_options
def compare(suite, quick, store_path, workers, scheduler, fmt, output, retrain,  # type: ignore[no-untyped-def]
            keep_state) -> None:
    """Every algorithm on the standard suite (the paper's grid world) and on the harbour
    suite (the continuous world), a table each (the main job).

    Prints every metric with a 95 % confidence interval over layouts, then every algorithm
    against the suite's baseline, layout by layout. Finished tasks go to the store, so a
    second run only prints.
    """
    from swiptopt.benchmark.experiment import builtin_experiments

    builtins = builtin_experiments()
    _run_and_report([builtins[name] for name in SUITES[suite]], quick, store_path, workers, scheduler, fmt, output,
                    caption=True, retrain=retrain, keep_state=keep_state, expect_shipped=True)


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
@_allow_plugins_option
def run(spec, quick, store_path, workers, scheduler, fmt, output, retrain,  # type: ignore[no-untyped-def]
        keep_state, allow_plugins) -> None:
    """Run a built-in experiment (by NAME) or a TOML experiment file and print its table.

    A file's [plugins] run code from outside swiptopt: they are refused unless
    --allow-plugins is given (see docs/plugins.md)."""
    from swiptopt.benchmark.experiment import load_experiments

    experiments = load_experiments(spec, allow_plugins=allow_plugins)
    _run_and_report(experiments, quick, store_path, workers, scheduler, fmt, output, caption=len(experiments) > 1,
                    retrain=retrain, keep_state=keep_state)


@cli.command()
@click.argument("what", type=click.Choice(["paper", "learning-curve", "links", "fleet"]))
@_options("quick", "store", "workers", "scheduler")
@click.option("--outdir", type=click.Path(file_okay=False), default="figures", help="Where figures and data go.")
@click.option(
    "--link", type=click.Choice(["downlink_split", "uplink"]), default=None,
    help="Run every figure on this data link (default: the paper preset's, downlink_split); "
    "uplink experiments are named with an -uplink suffix.",
)
@_options("retrain")
def reproduce(what, quick, store_path, workers, scheduler, outdir, link, retrain) -> None:  # type: ignore[no-untyped-def]
    """Run every experiment of the paper's figures (``paper``) or the learning curves
    (``learning-curve``), or draw the link technologies (``links``), and write the figures
    and their data.

    The paper's data figures run with the reward weight Gamma = 1 (throughput only), its
    energy figures with Gamma = 0 and alpha = 0 (harvesting only), the paper's extremes
    (Section IV). ``learning-curve`` writes ``fig-learning-curve`` (return against budget,
    the planners as bands) and prints the curves' table. ``links`` writes ``fig-links``
    (SNR, rate and harvested power against distance for each technology; no task runs);
    ``fleet`` writes ``fig-fleet-routes`` (the routing planner's fleets of 1, 2 and 4 AUVs on
    the fleet suite's field, seen from above; no task runs)."""
    from rich.console import Console

    from swiptopt.benchmark import plots, tables
    from swiptopt.benchmark.experiment import paper_figures
    from swiptopt.benchmark.runner import check_run_options, execute
    from swiptopt.benchmark.store import DEFAULT_STORE, ResultStore

    check_output_dir(outdir, "--outdir")
    check_run_options(workers, scheduler)
    console = Console(stderr=True)
    failures = []
    if what == "links":
        console.print(", ".join(map(str, plots.links_figure(outdir))))
        return
    if what == "fleet":
        console.print(", ".join(map(str, plots.fleet_routes_figure(outdir))))
        return
    if what == "learning-curve":
        from swiptopt.benchmark.experiment import load_experiments

        experiments = [e.quick() if quick else e for e in load_experiments("learning-curve")]
        with _scheduler_client(scheduler) as client, ResultStore(store_path or DEFAULT_STORE) as store:
            _check_before_running(experiments, store, retrain)
            for experiment in experiments:
                report = execute(experiment, store, workers=workers, scheduler=scheduler,
                                 pretrained=_pretrained(retrain), client=client)
                failures += report.failures
                console.print(f"{experiment.name}: {report.ran} run, {report.cached} stored")
            figure = plots.learning_curve_figure(experiments, store, outdir)
            console.print(", ".join(map(str, figure.paths)) or f"no figure: {figure.skipped}")
            _print_curves([tables.report(e, store) for e in experiments], "markdown")
        _report_failures(console, failures)
        if failures:
            raise click.exceptions.Exit(EXIT_TASKS_FAILED)
        return
    with _scheduler_client(scheduler) as client, ResultStore(store_path or DEFAULT_STORE) as store:
        written = plots.coverage_figure(outdir, quick=quick)
        console.print(f"coverage probability -> {', '.join(map(str, written))}")
        for experiment in paper_figures(link):
            name = experiment.name
            if quick:
                experiment = experiment.quick()
            report = execute(experiment, store, workers=workers, scheduler=scheduler, client=client)
            failures += report.failures
            figure = plots.experiment_figure(experiment, store, outdir)
            drawn = ", ".join(map(str, figure.paths)) or f"no figure: {figure.skipped}"
            failed = f", {report.failed} failed" if report.failed else ""
            console.print(f"{name}: {report.ran} run{failed}, {report.cached} stored -> {drawn}")
    _report_failures(console, failures)
    if failures:
        raise click.exceptions.Exit(EXIT_TASKS_FAILED)


@cli.command()
@click.argument("store_path", metavar="STORE", type=click.Path(dir_okay=False))
@click.option("--experiment", "name", default=None, help="Only this experiment (default: every one in the store).")
@_options("format", "output")
def table(store_path, name, fmt, output) -> None:  # type: ignore[no-untyped-def]
    """Print the tables of the experiments recorded in a results store (from the stored
    data alone: no plugin is loaded; a plugin's rows are labelled by its name)."""
    from swiptopt.benchmark import tables
    from swiptopt.benchmark.store import ResultStore

    check_output_file(output, "--output")
    with ResultStore(store_path, readonly=True) as store:
        experiments = store.experiments(name)
        if not experiments:
            raise ConfigError(f"no run of {name!r} in {store_path}" if name else f"no runs in {store_path}",
                              "experiment")
        caption = len(experiments) > 1
        reports = [tables.report(experiment, store) for experiment in experiments]
        texts = [_print_report(r, fmt, caption=caption) for r in reports] + _print_curves(reports, fmt)
        text = "\n".join(texts)
    if output:
        _write_output(output, text)


@cli.command()
@click.argument("store_path", metavar="STORE", type=click.Path(dir_okay=False))
@click.option("--outdir", type=click.Path(file_okay=False), default="figures")
@click.option("--experiment", "names", multiple=True, metavar="NAME",
              help="Only this experiment's figures (repeatable; default: every experiment in the store). "
                   "The learning curves of the named experiments are drawn as fig-NAME.")
def plot(store_path, outdir, names) -> None:  # type: ignore[no-untyped-def]
    """Draw the figure of every experiment in a results store that defines one, and the
    learning curves (``fig-learning-curve``) of the experiments with budgets it holds.
    ``--experiment`` draws only the named experiments' figures, and their learning curves as
    ``fig-NAME`` (names joined by '+'), so that a store's curves can be drawn apart."""
    from swiptopt.benchmark import plots
    from swiptopt.benchmark.store import ResultStore

    check_output_dir(outdir, "--outdir")
    with ResultStore(store_path, readonly=True) as store:
        drawn = []
        latest = {e.name: e for e in store.experiments()}  # the latest run of each
        unknown = [n for n in names if n not in latest]
        if unknown:
            raise ConfigError(f"--experiment {unknown[0]!r}: {store_path} holds no run of it "
                              f"(it holds {', '.join(sorted(latest)) or 'none'})", "--experiment")
        if names:
            latest = {n: latest[n] for n in dict.fromkeys(names)}
        for experiment in latest.values():
            if not experiment.figure:
                continue
            figure = plots.experiment_figure(experiment, store, outdir)
            if figure.skipped:
                click.echo(f"{experiment.name}: no figure: {figure.skipped}", err=True)
            drawn += figure.paths
        curves = [e for e in latest.values() if e.budgets]
        if curves:
            stem = "fig-" + "+".join(e.name for e in curves) if names else "fig-learning-curve"
            drawn += plots.learning_curve_figure(curves, store, outdir, stem=stem).paths
    if not drawn:
        raise ConfigError(f"no figure to draw from {store_path}", "figure")
    click.echo("\n".join(map(str, drawn)))


@cli.group()
def models() -> None:
    """Trained deep-RL models: gather the ones a run used into a directory of their own."""


@models.command("export")
@click.argument("store_path", metavar="STORE", type=click.Path(dir_okay=False))
@click.option("--experiment", "names", multiple=True, metavar="NAME|FILE.toml",
              help="Only the models of these experiments' tasks (repeatable; default: every task's).")
@_options("quick")
@click.option("--to", "outdir", type=click.Path(file_okay=False), required=True,
              help="The directory to copy them to (its manifest.json records each file's SHA-256).")
@_allow_plugins_option
def models_export(store_path, names, quick, outdir, allow_plugins) -> None:  # type: ignore[no-untyped-def]
    """Copy the model files the tasks of a results store loaded or trained (each checked
    against the manifest that vouched for it) into a directory with its own manifest.

    This is how the models shipped with swiptopt are made: ``swiptopt compare --retrain
    --store build/s.sqlite`` trains them, then ``swiptopt models export build/s.sqlite
    --experiment compare --experiment harbour --to swiptopt/benchmark/pretrained`` gathers
    them."""
    import shutil

    from rl.deep import file_sha256, read_manifest, record_in_manifest
    from swiptopt.benchmark.experiment import load_experiments
    from swiptopt.benchmark.runner import PRETRAINED_DIR, models_dir_for
    from swiptopt.benchmark.store import ResultStore

    check_output_dir(outdir, "--to")
    target = Path(outdir)
    wanted = None
    if names:
        experiments = [e for name in names for e in load_experiments(name, allow_plugins=allow_plugins)]
        wanted = {t.key for e in experiments for t in (e.quick() if quick else e).tasks()}
    copied: dict[str, str] = {}
    with ResultStore(store_path, readonly=True) as store:
        results = store.get(wanted if wanted is not None else store.keys())
        for result in results.values():
            extra = result["extra"]
            name = extra.get("model_file")
            if not name or name in copied:
                continue
            source_dir = PRETRAINED_DIR if extra.get("model_shipped") else Path(models_dir_for(store_path))
            record = read_manifest(source_dir).get(name)
            source = source_dir / name
            if record is None or not source.is_file() or file_sha256(source) != record["sha256"]:
                raise ConfigError(f"{source} is missing or not the file its manifest records: cannot export it",
                                  "store")
            copied[name] = record["sha256"]
            if source.resolve() != (target / name).resolve():
                target.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source, target / name)
            record_in_manifest(target, name, record)
    if not copied:
        raise ConfigError(f"no task in {store_path} used a model" + (f" in {', '.join(names)}" if names else ""),
                          "store")
    click.echo(f"{len(copied)} model files -> {target}")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code."""
    try:
        code = cli.main(args=argv, prog_name="swiptopt", standalone_mode=False)
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
    # without standalone mode, click returns an Exit's code (e.g. EXIT_TASKS_FAILED)
    return code if isinstance(code, int) else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
