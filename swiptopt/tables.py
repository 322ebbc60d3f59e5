"""Tables of results: mean, 95 % CI, min and max per algorithm and metric, ranks and gaps.

Each task's episodes are averaged first; the summary is then taken over tasks (layouts and
seeds), so the confidence interval reflects the variation between layouts, as in the
paper's Monte Carlo over layouts. A metric with no value in an episode (a target never
reached) is left out of that average and counted as missing, never as a number.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from swiptopt.algorithms import labels
from swiptopt.evaluation import Summary
from swiptopt.experiment import Experiment
from swiptopt.metrics import EPISODE_METRICS
from swiptopt.store import ResultStore

#: Extra columns beyond the episode metrics.
GAP_BOUND = "gap_to_bound"
GAP_OPTIMUM = "gap_to_optimum"

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


@dataclass(frozen=True)
class Row:
    """One algorithm at one sweep point."""

    point: dict[str, Any]
    algorithm: str
    label: str
    summaries: dict[str, Summary]
    rank: int
    tasks: int


def _task_mean(records: list[dict[str, Any]], metric: str) -> float | None:
    values = [r[metric] for r in records if r[metric] is not None and not (isinstance(r[metric], float) and math.isnan(r[metric]))]
    return float(np.mean(values)) if values else None


def aggregate(experiment: Experiment, store: ResultStore) -> tuple[list[Row], int]:
    """Rows of the experiment's stored results, and how many of its tasks are missing."""
    tasks = experiment.tasks()
    results = store.get({t.key for t in tasks})
    names = labels()
    rows = []
    missing = 0
    for point in experiment.points():
        point_rows = []
        for algorithm in experiment.algorithms:
            chosen = [t for t in tasks if t.point == point and t.algorithm == algorithm]
            found = [results[t.key] for t in chosen if t.key in results]
            missing += len(chosen) - len(found)
            if not found:
                continue
            per_metric: dict[str, list[Any]] = {m: [_task_mean(r["records"], m) for r in found] for m in EPISODE_METRICS}
            gaps, optimum_gaps = [], []
            for r in found:
                ret = _task_mean(r["records"], "return")
                bound = r["extra"].get("upper_bound_return")
                if ret is not None and bound:
                    gaps.append((bound - ret) / abs(bound))
                opt = r["extra"].get("optimum_return")
                if ret is not None and opt:
                    optimum_gaps.append((opt - ret) / abs(opt))
            summaries = {m: Summary.of(v) for m, v in per_metric.items()}
            summaries[GAP_BOUND] = Summary.of(gaps)
            if optimum_gaps:
                summaries[GAP_OPTIMUM] = Summary.of(optimum_gaps)
            point_rows.append((algorithm, summaries, len(found)))
        order = sorted(range(len(point_rows)), key=lambda i: -point_rows[i][1]["return"].mean)
        ranks = {i: r + 1 for r, i in enumerate(order)}
        for i, (algorithm, summaries, n) in enumerate(point_rows):
            rows.append(Row(point, algorithm, names.get(algorithm, algorithm), summaries, ranks[i], n))
    return rows, missing


def _cell(s: Summary | None, scale: float, digits: int, plus: str = "±") -> str:
    if s is None or s.n == 0:
        return "n/a"
    mean = s.mean * scale
    text = f"{mean:.{digits}f}"
    if not math.isnan(s.ci95):
        text += f" {plus} {s.ci95 * scale:.{digits}f}"
    if s.missing:
        text += f" ({s.missing} n/r)"
    return text


def _point_label(point: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in point.items())


def _headings(rows: list[Row]) -> list[str]:
    has_point = any(r.point for r in rows)
    has_opt = any(GAP_OPTIMUM in r.summaries for r in rows)
    heads = (["point"] if has_point else []) + ["algorithm", "rank"] + [h for _, h, _, _ in DISPLAY]
    return heads + (["gap to optimum"] if has_opt else [])


def _cells(row: Row, rows: list[Row], plus: str = "±") -> list[str]:
    has_point = any(r.point for r in rows)
    has_opt = any(GAP_OPTIMUM in r.summaries for r in rows)
    out = ([_point_label(row.point)] if has_point else []) + [row.label, str(row.rank)]
    for metric, _, scale, digits in DISPLAY:
        text = _cell(row.summaries.get(metric), scale, digits, plus)
        out.append(text + (" %" if metric == GAP_BOUND and text != "n/a" else ""))
    if has_opt:
        opt = _cell(row.summaries.get(GAP_OPTIMUM), 100.0, 0, plus)
        out.append(opt + (" %" if opt != "n/a" else ""))
    return out


def to_markdown(rows: list[Row]) -> str:
    heads = _headings(rows)
    lines = ["| " + " | ".join(heads) + " |", "|" + "|".join("---" for _ in heads) + "|"]
    lines += ["| " + " | ".join(_cells(r, rows)) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def to_latex(rows: list[Row]) -> str:
    heads = _headings(rows)
    esc = lambda s: s.replace("%", r"\%").replace("_", r"\_")  # noqa: E731
    lines = [r"\begin{tabular}{" + "l" * (len(heads) - len(DISPLAY)) + "r" * len(DISPLAY) + "}", r"\hline"]
    lines.append(" & ".join(esc(h) for h in heads) + r" \\ \hline")
    lines += [" & ".join(esc(c) for c in _cells(r, rows, r"$\pm$")) + r" \\" for r in rows]
    lines += [r"\hline", r"\end{tabular}"]
    return "\n".join(lines) + "\n"


def to_csv(rows: list[Row]) -> str:
    """Every metric of every row: mean, ci95, min, max, n, missing."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    keys = sorted({k for r in rows for k in r.point})
    writer.writerow(keys + ["algorithm", "rank", "metric", "mean", "ci95", "min", "max", "n", "missing"])
    for r in rows:
        for metric, s in r.summaries.items():
            writer.writerow([r.point.get(k) for k in keys] + [r.algorithm, r.rank, metric, s.mean, s.ci95, s.min, s.max, s.n, s.missing])
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
