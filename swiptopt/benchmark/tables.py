"""Tables of results: mean, 95 % CI, min and max per algorithm and metric, ranks and gaps.

Each task's episodes are averaged first; the summary is then taken over tasks (layouts and
seeds), so the confidence interval reflects the variation between layouts, as in the
paper's Monte Carlo over layouts. A metric with no value in an episode (a target never
reached) is left out of that average and counted as missing, never as a number.

The gap to bound, ``(bound - return) / |bound|`` per task, is taken against the tightest
bound that *holds for the task's class of policy* among those the experiment has for its
scenario (the same sweep point and layout; docs/optimum.md has the proofs). A task is an
open-loop plan when its record says so (``policy_class``: the MILP's plan) and an adaptive
policy otherwise (every RL agent, and the planners that skip served stops or linger). The
bounds are the ones a solver's task recorded with the class each holds for
(``policy_bounds``: :func:`planners.optimal.policy_bounds`) and :func:`planners.upper_bound`;
the ``bound`` column names the one used:

- ``milp``: the MILP's bound with a deterministic channel, a bound on every policy;
- ``lp (expected)``: the linear relaxation of the expected-rate model with a stochastic
  channel, a bound on every non-anticipative policy, adaptive ones included;
- ``milp (expected)``: the MILP's bound on that model, a bound on open-loop plans only, and
  only where no walk can end early: the open-loop rows may use it, the adaptive ones never;
- ``upper``: every coverable node fully served with no travel, a bound on every policy.

Results stored before the records carried ``policy_bounds`` are read conservatively: a
``milp`` bound holds for every policy, a ``milp (expected)`` one for none (whether its
episodes could end early was not recorded), and its ``lp_bound_return`` is ``lp (expected)``.

The MILP's own row adds [best, bound]: the mean of its plans' values in its model and of
its bounds.

Spread across training seeds: where an algorithm ran several seeds per layout (deep RL's
``training_seeds``), its return is also averaged over the layouts seed by seed, and the
``return by seed`` column shows the lowest and highest of those per-seed means (CSV: the
metric ``return_by_seed``, with every statistic of the per-seed means). The main columns
summarise every task (layouts x seeds).

An experiment with a ``baseline`` algorithm also gets a paired table (:func:`paired`): for
each other algorithm and metric, the ratio of its mean to the baseline's over the layouts
both ran (the same scenario and layout; each side averaged over its seeds there, so an
algorithm with three training seeds is paired with a baseline that ran one), a 95 %
bootstrap confidence interval of that ratio (layouts resampled), and on how many of those
layouts it beat the baseline.
"""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np

from planners.bounds import ADAPTIVE, LP_EXPECTED_NAME, MILP_NAME, UPPER_NAME, PolicyBound
from swiptopt.benchmark.algorithms import labels
from swiptopt.benchmark.experiment import SEEDS_PER_LAYOUT, Experiment, budget_row
from swiptopt.benchmark.store import ResultStore
from swiptopt.evaluation import Summary
from swiptopt.metrics import EPISODE_METRICS

#: Extra columns beyond the episode metrics.
GAP_BOUND = "gap_to_bound"
GAP_OPTIMUM = "gap_to_optimum"
#: The per-seed means of the return (over layouts), where an algorithm ran several seeds.
SEED_SPREAD = "return_by_seed"
#: A solver's own numbers, in its row: its plans' values in its model and its bounds.
SOLVER_BEST = "best_return"
SOLVER_BOUND = "bound_return"
#: The bound column's word for planners.upper_bound.
UPPER = UPPER_NAME
#: A task's record of its bounds with their classes, and of its own class (docs/optimum.md).
POLICY_BOUNDS = "policy_bounds"
POLICY_CLASS = "policy_class"
#: Solver statuses that come with a plan and a bound.
SOLVED = ("optimal", "feasible")

#: The columns of the terminal / Markdown / LaTeX tables: (metric, heading, scale, digits).
DISPLAY = (
    ("return", "return", 1.0, 2),
    ("data_bits", "data (kbit)", 1e-3, 0),
    ("energy_delivered_j", "energy (mJ)", 1e3, 0),
    ("energy_efficiency_bit_per_j", "bit/J (all)", 1.0, 2),
    ("mobility_efficiency_bit_per_j", "bit/J (motion)", 1.0, 1),
    ("nodes_served", "served", 1.0, 1),
    ("jain_data", "Jain data", 1.0, 2),
    ("steps_to_data_target", "steps to 50% data", 1.0, 1),
    (GAP_BOUND, "gap to bound", 100.0, 0),
)

#: The fleet's own columns (docs/fleet.md), shown when some row has them.
FLEET_DISPLAY = (
    ("makespan_s", "makespan (s)", 1.0, 0),
    ("jain_auv_energy", "Jain AUV energy", 1.0, 2),
)


def _display(rows: list[Row]) -> tuple[tuple[str, str, float, int], ...]:
    """The columns of these rows: :data:`DISPLAY`, and the fleet's when some row has them."""
    fleet = any(r.summaries.get(m) is not None for r in rows for m, *_ in FLEET_DISPLAY)
    return DISPLAY + FLEET_DISPLAY if fleet else DISPLAY


@dataclass(frozen=True)
class Row:
    """One algorithm at one sweep point."""

    point: dict[str, Any]
    algorithm: str
    label: str
    summaries: dict[str, Summary]
    rank: int
    tasks: int
    bound: str = UPPER
    """Which bound the gap is measured against (module docstring); several, with their
    task counts, when the layouts differ."""
    notes: str = ""
    """A solver's statuses other than optimal or feasible, and safety time limits hit."""


def _task_mean(records: list[dict[str, Any]], metric: str) -> float | None:
    values = [r[metric] for r in records
              if r[metric] is not None and not (isinstance(r[metric], float) and math.isnan(r[metric]))]
    return float(np.mean(values)) if values else None


@dataclass(frozen=True, eq=False)
class Stored:
    """An experiment's results as read from a store, once: the task grid is expanded and the
    store read a single time, and every table of the experiment is built from this."""

    by_row: dict[tuple[int, str], dict[int, dict[str, Any]]]
    """The results by (sweep point index, row), each keyed by task seed (which names the
    layout and the seed)."""
    missing: int
    """Tasks without a result."""
    failures: dict[str, str]
    """Task key -> reason, for the tasks whose last try failed."""
    expected: dict[tuple[int, str], int]
    """The experiment's task count by (sweep point index, row)."""

    def complete(self, key: tuple[int, str]) -> bool:
        """Whether every task of the (sweep point index, row) has a result."""
        return len(self.by_row.get(key, {})) == self.expected.get(key, 0)

    def get(self, key: tuple[int, str], default: Any = None) -> Any:
        return self.by_row.get(key, default)

    def items(self) -> Any:
        return self.by_row.items()


def load_results(experiment: Experiment, store: ResultStore) -> Stored:
    """The experiment's stored results and failures (:class:`Stored`)."""
    tasks = experiment.tasks()
    keys = {t.key for t in tasks}
    results = store.get(keys)
    points = experiment.points()
    out: dict[tuple[int, str], dict[int, dict[str, Any]]] = {}
    expected: dict[tuple[int, str], int] = {}
    for t in tasks:
        where = (points.index(t.point), t.row)
        expected[where] = expected.get(where, 0) + 1
        if t.key in results:
            out.setdefault(where, {})[t.seed] = results[t.key]
    return Stored(out, len(tasks) - sum(len(v) for v in out.values()), store.failures(keys), expected)


def _stored(experiment: Experiment, store: ResultStore | Stored) -> Stored:
    return store if isinstance(store, Stored) else load_results(experiment, store)


def _recorded_bounds(extra: dict[str, Any]) -> list[PolicyBound]:
    """The bounds a task recorded, each with the class it holds for (module docstring for
    records from before ``policy_bounds``)."""
    if POLICY_BOUNDS in extra:
        found = [PolicyBound(float(b["value"]), str(b["name"]), str(b["holds_for"])) for b in extra[POLICY_BOUNDS]]
    else:
        label = extra.get("bound_label")
        found = []
        if label == MILP_NAME and extra.get(SOLVER_BOUND) is not None:
            found.append(PolicyBound(float(extra[SOLVER_BOUND]), MILP_NAME, ADAPTIVE))
        elif label and extra.get("lp_bound_return") is not None:
            found.append(PolicyBound(float(extra["lp_bound_return"]), LP_EXPECTED_NAME, ADAPTIVE))
    return [b for b in found if math.isfinite(b.value)]


def _references(stored: dict[tuple[int, str], dict[int, dict[str, Any]]], p: int) -> dict[int, list[PolicyBound]]:
    """Every bound recorded at sweep point ``p``, per layout, with the class it holds for."""
    out: dict[int, list[PolicyBound]] = {}
    for (q, _), found in stored.items():
        if q != p:
            continue
        for seed, r in found.items():
            out.setdefault(seed // SEEDS_PER_LAYOUT, []).extend(_recorded_bounds(r["extra"]))
    return out


def _tightest(references: list[PolicyBound], extra: dict[str, Any]) -> PolicyBound | None:
    """The tightest bound for a task: the recorded ones that hold for its class, and its
    :func:`planners.upper_bound`."""
    policy_class = extra.get(POLICY_CLASS, ADAPTIVE)
    candidates = [b for b in references if b.holds(policy_class)]
    if extra.get("upper_bound_return") is not None:
        candidates.append(PolicyBound(float(extra["upper_bound_return"]), UPPER, ADAPTIVE))
    return min(candidates, key=lambda b: b.value, default=None)


def _bound_words(labels_used: list[str]) -> str:
    counts = Counter(labels_used)
    if len(counts) <= 1:
        return next(iter(counts), "n/a")
    return ", ".join(f"{label} {n}/{len(labels_used)}" for label, n in counts.most_common())


def _solver_notes(found: list[dict[str, Any]]) -> str:
    extras = [r["extra"] for r in found if "solver_status" in r["extra"]]
    unsolved = Counter(e["solver_status"] for e in extras if e["solver_status"] not in SOLVED)
    notes = [f"{status} {n}/{len(extras)}" for status, n in sorted(unsolved.items())]
    hit = sum(bool(e.get("solver_time_limit_hit")) for e in extras)
    if hit:
        notes.append(f"time limit hit {hit}/{len(extras)}")
    return ", ".join(notes)


def _seed_means(by_seed: dict[int, dict[str, Any]], metric: str) -> list[float]:
    """The mean of ``metric`` over layouts for each seed index (task seed mod 1000)."""
    per_seed: dict[int, list[float]] = {}
    for seed, r in by_seed.items():
        value = _task_mean(r["records"], metric)
        if value is not None:
            per_seed.setdefault(seed % SEEDS_PER_LAYOUT, []).append(value)
    return [float(np.mean(v)) for _, v in sorted(per_seed.items())]


def _layout_means(by_seed: dict[int, dict[str, Any]], metric: str) -> dict[int, float]:
    """The mean of ``metric`` over each layout's seeds, by layout."""
    per_layout: dict[int, list[float]] = {}
    for seed, r in by_seed.items():
        value = _task_mean(r["records"], metric)
        if value is not None:
            per_layout.setdefault(seed // SEEDS_PER_LAYOUT, []).append(value)
    return {layout: float(np.mean(v)) for layout, v in per_layout.items()}


def aggregate(experiment: Experiment, store: ResultStore | Stored) -> tuple[list[Row], int]:
    """Rows of the experiment's stored results, and how many of its tasks are missing
    (``store``: a results store, or the experiment's results already read from one)."""
    stored = _stored(experiment, store)
    missing = stored.missing
    names = labels()
    rows = []
    for p, point in enumerate(experiment.points()):
        references = _references(stored, p)
        point_rows = []
        for algorithm, _, _ in experiment.rows():
            by_seed = stored.get((p, algorithm), {})
            found = list(by_seed.values())
            if not found:
                continue
            fleet = tuple(m for m, *_ in FLEET_DISPLAY if any(r["records"] and m in r["records"][0] for r in found))
            per_metric: dict[str, list[Any]] = {m: [_task_mean(r["records"], m) for r in found]
                                                for m in (*EPISODE_METRICS, *fleet)}
            gaps, optimum_gaps, used = [], [], []
            for seed, r in by_seed.items():
                ret = _task_mean(r["records"], "return")
                tightest = _tightest(references.get(seed // SEEDS_PER_LAYOUT, []), r["extra"])
                if ret is not None and tightest is not None and tightest.value:
                    gaps.append((tightest.value - ret) / abs(tightest.value))
                    used.append(tightest.name)
                opt = r["extra"].get("optimum_return")
                if ret is not None and opt:
                    optimum_gaps.append((opt - ret) / abs(opt))
            summaries = {m: Summary.of(v) for m, v in per_metric.items()}
            seed_means = _seed_means(by_seed, "return")
            if len(seed_means) > 1:
                summaries[SEED_SPREAD] = Summary.of(seed_means)
            summaries[GAP_BOUND] = Summary.of(gaps)
            if optimum_gaps:
                summaries[GAP_OPTIMUM] = Summary.of(optimum_gaps)
            if any(SOLVER_BOUND in r["extra"] for r in found):
                for key in (SOLVER_BEST, SOLVER_BOUND):
                    summaries[key] = Summary.of([r["extra"].get(key) for r in found])
            point_rows.append((algorithm, summaries, len(found), _bound_words(used), _solver_notes(found)))
        order = sorted(range(len(point_rows)), key=lambda i: -point_rows[i][1]["return"].mean)
        ranks = {i: r + 1 for r, i in enumerate(order)}
        for i, (algorithm, summaries, n, bound, notes) in enumerate(point_rows):
            rows.append(Row(point, algorithm, row_label(algorithm, names), summaries, ranks[i], n, bound, notes))
    return rows, missing


#: Metrics of the paired comparison with the baseline: (metric, heading).
PAIRED = (
    ("return", "return"),
    ("data_bits", "data"),
    ("energy_delivered_j", "energy"),
    ("energy_efficiency_bit_per_j", "bit/J (all)"),
    ("mobility_efficiency_bit_per_j", "bit/J (motion)"),
)
BOOTSTRAP_RESAMPLES = 4000


@dataclass(frozen=True)
class Ratio:
    """An algorithm's mean over the baseline's, over tasks both have a value for.

    ``low``/``high`` bound a 95 % percentile-bootstrap interval (tasks resampled in pairs;
    NaN with fewer than 2 pairs, or when a resample's baseline mean is not positive);
    ``wins`` counts the tasks where the algorithm's value is higher.
    """

    ratio: float
    low: float
    high: float
    wins: int
    n: int

    @classmethod
    def of(cls, values: np.ndarray, baseline: np.ndarray, rng: np.random.Generator,
           resamples: int = BOOTSTRAP_RESAMPLES) -> Ratio:
        x, y = np.asarray(values, float), np.asarray(baseline, float)
        n = len(x)
        wins = int(np.sum(x > y))
        if n == 0 or y.sum() <= 0:
            return cls(math.nan, math.nan, math.nan, wins, n)
        ratio = float(x.sum() / y.sum())
        if n < 2:
            return cls(ratio, math.nan, math.nan, wins, n)
        pick = rng.integers(0, n, size=(resamples, n))
        den = y[pick].sum(axis=1)
        if np.any(den <= 0):
            return cls(ratio, math.nan, math.nan, wins, n)
        low, high = np.percentile(x[pick].sum(axis=1) / den, [2.5, 97.5])
        return cls(ratio, float(low), float(high), wins, n)


@dataclass(frozen=True)
class PairedRow:
    """One algorithm against the baseline at one sweep point."""

    point: dict[str, Any]
    algorithm: str
    label: str
    ratios: dict[str, Ratio]


def paired(experiment: Experiment, store: ResultStore | Stored, seed: int = 0) -> list[PairedRow]:
    """Every algorithm but the experiment's baseline, against the baseline, task by task.

    The bootstrap draws from a generator seeded with ``seed``, so a table prints the same
    interval every time.
    """
    if not experiment.baseline:
        return []
    stored = _stored(experiment, store)
    names = labels()
    rng = np.random.default_rng(seed)
    rows = []
    for p, point in enumerate(experiment.points()):
        base = stored.get((p, experiment.baseline), {})
        for algorithm, _, _ in experiment.rows():
            mine = stored.get((p, algorithm), {})
            if algorithm == experiment.baseline or not mine:
                continue
            ratios = {}
            for metric, _ in PAIRED:
                a, b = _layout_means(mine, metric), _layout_means(base, metric)
                pairs = [(a[layout], b[layout]) for layout in sorted(set(a) & set(b))]
                x, y = (np.array(v, float) for v in zip(*pairs)) if pairs else (np.zeros(0), np.zeros(0))
                ratios[metric] = Ratio.of(x, y, rng)
            rows.append(PairedRow(point, algorithm, row_label(algorithm, names), ratios))
    return rows


def row_label(row: str, names: dict[str, str]) -> str:
    """A row's label: the algorithm's, with its budget (``PPO @ 250,000``) for a learning
    curve's row (:func:`swiptopt.benchmark.experiment.budget_row`)."""
    algorithm, _, budget = row.partition("@")
    label = names.get(algorithm, algorithm)
    return f"{label} @ {int(budget):,}" if budget.isdigit() else label


def _ratio_cell(r: Ratio) -> str:
    if math.isnan(r.ratio):
        return f"n/a ({r.wins}/{r.n})"
    interval = "" if math.isnan(r.low) else f" [{r.low:.2f}–{r.high:.2f}]"
    return f"{r.ratio:.2f}×{interval} {r.wins}/{r.n}"


def _paired_table(rows: list[PairedRow]) -> tuple[list[str], list[list[str]]]:
    has_point = any(r.point for r in rows)
    heads = (["point"] if has_point else []) + ["algorithm"] + [h for _, h in PAIRED]
    cells = [
        ([_point_label(r.point)] if has_point else []) + [r.label] + [_ratio_cell(r.ratios[m]) for m, _ in PAIRED]
        for r in rows
    ]
    return heads, cells


def suite_title(experiment: Experiment) -> str:
    """The experiment's name and its world, as the tables' titles begin: ``compare (grid world)``."""
    return f"{experiment.name} ({experiment.world} world)"


def paired_title(experiment: Experiment) -> str:
    label = labels().get(experiment.baseline, experiment.baseline)
    return (
        f"{suite_title(experiment)}: mean / mean of {label} over the same layouts (seeds averaged), "
        "[95 % bootstrap CI], layouts won"
    )


def _cell(s: Summary | None, scale: float, digits: int) -> str:
    if s is None or s.n == 0:
        return "n/a"
    mean = s.mean * scale
    text = f"{mean:.{digits}f}"
    if not math.isnan(s.ci95):
        text += f" ± {s.ci95 * scale:.{digits}f}"
    if s.missing:
        text += f" ({s.missing} n/r)"
    return text


def _point_label(point: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in point.items())


def _has_seed_spread(rows: list[Row]) -> bool:
    return any(SEED_SPREAD in r.summaries for r in rows)


def _headings(rows: list[Row]) -> list[str]:
    has_point = any(r.point for r in rows)
    has_opt = any(GAP_OPTIMUM in r.summaries for r in rows)
    heads = (["point"] if has_point else []) + ["algorithm", "rank"] + [h for _, h, _, _ in _display(rows)] + ["bound"]
    return heads + (["gap to optimum"] if has_opt else []) + (["return by seed"] if _has_seed_spread(rows) else [])


def _seed_cell(row: Row) -> str:
    """``min–max (k seeds)`` of the per-seed mean returns, or '' for a single seed."""
    s = row.summaries.get(SEED_SPREAD)
    if s is None or s.n < 2:
        return ""
    return f"{s.min:.2f}–{s.max:.2f} ({s.n} seeds)"


def _solver_cell(row: Row) -> str:
    """A solver's [best, bound] (means over its tasks), or '' for other rows."""
    best, bound = row.summaries.get(SOLVER_BEST), row.summaries.get(SOLVER_BOUND)
    if best is None or bound is None or best.n == 0 or bound.n == 0:
        return ""
    return f" [{best.mean:.2f}, {bound.mean:.2f}]"


def _cells(row: Row, rows: list[Row]) -> list[str]:
    has_point = any(r.point for r in rows)
    has_opt = any(GAP_OPTIMUM in r.summaries for r in rows)
    out = ([_point_label(row.point)] if has_point else []) + [row.label, str(row.rank)]
    for metric, _, scale, digits in _display(rows):
        text = _cell(row.summaries.get(metric), scale, digits)
        if metric == GAP_BOUND:
            text += (" %" if text != "n/a" else "") + _solver_cell(row)
        out.append(text)
    out.append(row.bound + (f" ({row.notes})" if row.notes else ""))
    if has_opt:
        opt = _cell(row.summaries.get(GAP_OPTIMUM), 100.0, 0)
        out.append(opt + (" %" if opt != "n/a" else ""))
    if _has_seed_spread(rows):
        out.append(_seed_cell(row))
    return out


def _text_columns(rows: list[Row]) -> int:
    """How many leading columns hold text (the point, the algorithm, the rank)."""
    return 3 if any(r.point for r in rows) else 2


def _markdown(heads: list[str], cells: list[list[str]]) -> str:
    lines = ["| " + " | ".join(heads) + " |", "|" + "|".join("---" for _ in heads) + "|"]
    lines += ["| " + " | ".join(c) + " |" for c in cells]
    return "\n".join(lines) + "\n"


#: How each character LaTeX treats specially is written as text (and the few symbols the
#: tables use, as math). Control characters become spaces; everything else passes through
#: (LaTeX reads UTF-8).
_LATEX = {
    "\\": r"\textbackslash{}",
    "{": r"\{",
    "}": r"\}",
    "$": r"\$",
    "&": r"\&",
    "#": r"\#",
    "%": r"\%",
    "_": r"\_",
    "^": r"\textasciicircum{}",
    "~": r"\textasciitilde{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    "±": r"$\pm$",
    "×": r"$\times$",
    "–": "--",
}


def latex_escape(text: str) -> str:
    """``text`` as LaTeX that typesets it verbatim: every special character escaped, so a
    swept value such as ``\\input{/etc/hostname}`` or ``a & b`` is printed, never run."""
    return "".join(_LATEX.get(c, c if c.isprintable() else " ") for c in text)


def _latex(heads: list[str], cells: list[list[str]], numeric: int) -> str:
    lines = [r"\begin{tabular}{" + "l" * (len(heads) - numeric) + "r" * numeric + "}", r"\hline"]
    lines.append(" & ".join(latex_escape(h) for h in heads) + r" \\ \hline")
    lines += [" & ".join(latex_escape(c) for c in row) + r" \\" for row in cells]
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def to_markdown(rows: list[Row]) -> str:
    return _markdown(_headings(rows), [_cells(r, rows) for r in rows])


def to_latex(rows: list[Row]) -> str:
    heads = _headings(rows)
    return _latex(heads, [_cells(r, rows) for r in rows], len(heads) - _text_columns(rows))


def paired_to_csv(rows: list[PairedRow]) -> str:
    """Every ratio of the paired table: ratio, CI bounds, wins and pairs."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    keys = sorted({k for r in rows for k in r.point})
    writer.writerow(keys + ["algorithm", "metric", "ratio", "ci95_low", "ci95_high", "wins", "n"])
    for r in rows:
        for metric, q in r.ratios.items():
            writer.writerow([r.point.get(k) for k in keys] + [r.algorithm, metric, q.ratio, q.low, q.high, q.wins, q.n])
    return buf.getvalue()


def render_paired(rows: list[PairedRow], fmt: str) -> str:
    """The paired table as Markdown, CSV or LaTeX text."""
    if fmt == "csv":
        return paired_to_csv(rows)
    if fmt == "latex":
        return _latex(*_paired_table(rows), len(PAIRED))
    return _markdown(*_paired_table(rows))


def paired_to_rich(rows: list[PairedRow], title: str):  # type: ignore[no-untyped-def]
    from rich.table import Table

    heads, cells = _paired_table(rows)
    table = Table(title=title, title_justify="left")
    for i, head in enumerate(heads):
        table.add_column(head, justify="right" if i >= len(heads) - len(PAIRED) else "left")
    for c in cells:
        table.add_row(*c)
    return table


def to_csv(rows: list[Row]) -> str:
    """Every metric of every row: mean, ci95, min, max, n, missing, and the row's bound (what
    its gap to bound is measured against) and solver notes."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    keys = sorted({k for r in rows for k in r.point})
    writer.writerow(keys + ["algorithm", "rank", "metric", "mean", "ci95", "min", "max", "n", "missing", "bound",
                            "notes"])
    for r in rows:
        for metric, s in r.summaries.items():
            writer.writerow([r.point.get(k) for k in keys]
                            + [r.algorithm, r.rank, metric, s.mean, s.ci95, s.min, s.max, s.n, s.missing, r.bound,
                               r.notes])
    return buf.getvalue()


def to_rich(rows: list[Row], title: str):  # type: ignore[no-untyped-def]
    from rich.table import Table

    table = Table(title=title, title_justify="left")
    for i, head in enumerate(_headings(rows)):
        table.add_column(head, justify="left" if i < 2 else "right")
    for r in rows:
        table.add_row(*_cells(r, rows))
    return table


FORMATS = ("terminal", "markdown", "csv", "latex")


def render(rows: list[Row], fmt: str) -> str:
    """The rows as Markdown, CSV or LaTeX text."""
    return {"markdown": to_markdown, "csv": to_csv, "latex": to_latex}[fmt](rows)


# ------------------------------------------------------------------ learning curves


@dataclass(frozen=True)
class CurveRow:
    """One algorithm's learning curve in one experiment (``budgets``): its mean return at
    each budget, whether the curve is flat at its end, and its last budget against the best
    planner of the experiment on the same layouts. A budget some of whose tasks have no
    result yet (a run still going, or stopped) is *incomplete*: its mean is shown with its
    task count, and no verdict that needs it is drawn."""

    experiment: str
    algorithm: str
    label: str
    budgets: tuple[int, ...]
    returns: tuple[Summary, ...]
    flat: bool | None
    """The last two budgets' means lie within each other's 95 % CI; None while either is
    incomplete."""
    near_plateau: int | None
    """The smallest budget whose mean return is within 10 % of the last budget's; None while
    any budget is incomplete."""
    reference: str
    """The best planner's label (the experiment's non-budgeted algorithm of highest mean return)."""
    reference_return: Summary | None
    ratio: Ratio | None
    """The last budget's mean over the reference's, paired by layout (seeds averaged); None
    while the last budget or the reference is incomplete."""
    tasks: tuple[tuple[int, int], ...] = ()
    """Per budget, (tasks with a result, tasks of the budget)."""
    unit: str = "steps"
    """What the budgets count (:meth:`~swiptopt.benchmark.experiment.Experiment.budget_unit`)."""

    @property
    def complete(self) -> tuple[bool, ...]:
        """Per budget, whether every task has a result."""
        return tuple(found == total for found, total in self.tasks)


def curve_rows(experiment: Experiment, store: ResultStore | Stored, seed: int = 0) -> list[CurveRow]:
    """The learning curves of an experiment with ``budgets`` (empty without)."""
    if not experiment.budgets:
        return []
    stored = _stored(experiment, store)
    names = labels()
    rng = np.random.default_rng(seed)
    rows, _ = aggregate(experiment, stored)
    planners = [r for r in rows if "@" not in r.algorithm and r.algorithm not in experiment.budgets]
    best = max(planners, key=lambda r: r.summaries["return"].mean, default=None)
    out = []
    for name, budgets in experiment.budgets.items():
        keys = [(0, budget_row(name, b)) for b in budgets]
        summaries = [Summary.of([_task_mean(r["records"], "return") for r in stored.get(k, {}).values()])
                     for k in keys]
        if not summaries or all(s.n == 0 for s in summaries):
            continue
        tasks = tuple((len(stored.get(k, {})), stored.expected.get(k, 0)) for k in keys)
        done = [stored.complete(k) for k in keys]
        last, before = summaries[-1], summaries[-2] if len(summaries) > 1 else None
        flat = None
        if done[-1] and (before is None or done[-2]):
            flat = before is not None and abs(last.mean - before.mean) <= min(last.ci95, before.ci95)
        near = None
        if all(done):
            target = 0.9 * last.mean if last.mean > 0 else last.mean
            near = next((b for b, s in zip(budgets, summaries) if s.n and s.mean >= target), budgets[-1])
        ratio = None
        if best is not None and done[-1] and stored.complete((0, best.algorithm)):
            mine = _layout_means(stored.get(keys[-1], {}), "return")
            base = _layout_means(stored.get((0, best.algorithm), {}), "return")
            common = sorted(set(mine) & set(base))
            ratio = Ratio.of(np.array([mine[k] for k in common]), np.array([base[k] for k in common]), rng)
        out.append(CurveRow(experiment.name, name, names.get(name, name), tuple(budgets), tuple(summaries), flat,
                            near, best.label if best else "", best.summaries["return"] if best else None, ratio,
                            tasks, experiment.budget_unit(name)))
    return out


def _budget_head(rows: list[CurveRow]) -> str:
    """The budget column's header: what the budgets count, each algorithm's where the rows
    differ (``decisions: mean ± 95 % CI``, or ``mean ± 95 % CI; budgets in decisions for
    A, in steps for B``)."""
    units = list(dict.fromkeys(r.unit for r in rows)) or ["steps"]
    if len(units) == 1:
        return f"{units[0]}: mean ± 95 % CI"
    each = [f"in {u} for {' and '.join(dict.fromkeys(r.label for r in rows if r.unit == u))}" for u in units]
    return "mean ± 95 % CI; budgets " + ", ".join(each)


def curves_to_markdown(rows: list[CurveRow]) -> str:
    """The learning curves as a Markdown table: return at each budget, whether flat, the
    budget within 10 % of the last, and the last budget against the best planner. An
    incomplete budget's cell says how many of its tasks have a result, and a verdict that
    needs an incomplete budget reads ``incomplete``. The header names what the budgets count
    (steps, decisions or episodes), each algorithm's where the rows differ."""
    heads = ["experiment", "algorithm", f"return at each budget ({_budget_head(rows)})", "flat at the end",
             "within 10 % from", "last / best planner"]
    cells = []
    for r in rows:
        parts = []
        for b, s, (found, total) in zip(r.budgets, r.returns, r.tasks):
            cell = _cell(s, 1.0, 2) if found else "not run"
            parts.append(f"{b:,}: {cell}" + (f" ({found} of {total} tasks)" if 0 < found < total else ""))
        ratio = _ratio_cell(r.ratio) + f" ({r.reference})" if r.ratio is not None else (
            "n/a" if r.reference_return is None else "incomplete")
        flat = "incomplete" if r.flat is None else ("yes" if r.flat else "no")
        near = "incomplete" if r.near_plateau is None else f"{r.near_plateau:,}"
        cells.append([r.experiment, r.label, "; ".join(parts), flat, near, ratio])
    return _markdown(heads, cells)


# ------------------------------------------------------------------ the report


@dataclass(frozen=True, eq=False)
class Report:
    """Everything printed of one experiment, as data: built once from one read of the store
    (:func:`report`), rendered per format (:func:`render_report`; the CLI renders the
    terminal's tables from the same rows)."""

    experiment: Experiment
    title: str
    """The experiment and its world (:func:`suite_title`)."""
    note: str
    """Failed and missing tasks (``k tasks failed: reason; m tasks missing``), or ''."""
    rows: list[Row]
    pairs: list[PairedRow]
    """Against the baseline (empty without one)."""
    curves: list[CurveRow]
    """The learning curves (empty without budgets)."""

    @property
    def heading(self) -> str:
        """The main table's title."""
        return f"{self.title}: mean ± 95 % CI over layouts" + (f" ({self.note})" if self.note else "")

    @property
    def paired_heading(self) -> str:
        return paired_title(self.experiment) if self.pairs else ""


def missing_note(stored: Stored) -> str:
    """``k tasks failed: reason; m tasks missing`` for the tasks without a result, or ''."""
    parts = []
    if stored.failures:
        reasons = Counter(stored.failures.values()).most_common()
        others = f" (and {len(reasons) - 1} other reasons)" if len(reasons) > 1 else ""
        n = len(stored.failures)
        parts.append(f"{n} task{'s' * (n != 1)} failed: {reasons[0][0]}{others}")
    if stored.missing > len(stored.failures):
        parts.append(f"{stored.missing - len(stored.failures)} tasks missing")
    return "; ".join(parts)


def report(experiment: Experiment, store: ResultStore, seed: int = 0) -> Report:
    """The experiment's :class:`Report` from ``store`` (read once); ``seed`` seeds the
    bootstrap of the paired table and the curves' ratios."""
    stored = load_results(experiment, store)
    rows, _ = aggregate(experiment, stored)
    return Report(experiment, suite_title(experiment), missing_note(stored), rows, paired(experiment, stored, seed),
                  curve_rows(experiment, stored, seed))


def render_report(r: Report, fmt: str, *, caption: bool = False) -> str:
    """The report's tables as text: the main table, then the paired one after a blank line,
    in ``fmt`` (Markdown, CSV or LaTeX; the terminal's text is Markdown). With ``caption``,
    Markdown starts with the title in bold and LaTeX with it as a comment (CSV stays plain
    data)."""
    fmt = "markdown" if fmt == "terminal" else fmt
    head = ""
    if caption and fmt == "markdown":
        head = f"**{r.title}**\n\n"
    elif caption and fmt == "latex":
        head = f"% {r.title}\n"
    text = head + render(r.rows, fmt)
    if r.pairs:
        text += "\n" + render_paired(r.pairs, fmt)
    return text


CURVES_TITLE = "learning curves: return at each budget, flat at the end, last budget / best planner"


def render_curves(rows: list[CurveRow]) -> str:
    """The learning curves of one or more reports as one Markdown table under its title."""
    return f"**{CURVES_TITLE}**\n\n" + curves_to_markdown(rows)
