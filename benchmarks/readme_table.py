"""Print the README's results table from a report directory's ``summary.csv``.

Usage::

    python -m benchmarks.readme_table benchmarks/results/quick
    python -m benchmarks.readme_table benchmarks/results/full --experiment sample-efficiency

The table is generated from the CSV the report was built from, never typed in. Controllers are
named by their CLI names (an older alias by the name it stands for), with one legend line under
the table giving each one's label and description.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Sequence
from pathlib import Path

COLUMNS = (
    ("env", "env"), ("scenario", "scenario"), ("controller", "controller"),
    ("episodes", "episodes"), ("success_rate", "success rate [95% CI]"),
    ("cost_mean", "mean cost [95% CI]"),
    ("final_distance_mean", "final distance"), ("episodes_with_violation", "episodes w/ violation"),
    ("data_steps_mean", "env steps of data"), ("act_median_ms", "act median (ms)"),
)
OUTSIDE_COLUMNS = (
    ("env", "env"), ("scenario", "scenario"), ("n_init", "initial samples"),
    ("controller", "controller"), ("episodes", "episodes"),
    ("success_rate", "success rate [95% CI]"),
    ("return_mean", "env's return [95% CI]"), ("data_steps_mean", "env steps of data"),
    ("act_median_ms", "act median (ms)"),
)
"""The columns of an experiment on outside simulators (whose reward is their own: the return,
not the cost)."""
DIGITS = {"success_rate": 2, "cost_mean": 1, "final_distance_mean": 3, "data_steps_mean": 0,
          "act_median_ms": 1, "return_mean": 1}


INTERVALS = {"success_rate": ("success_ci_low", "success_ci_high"),
             "cost_mean": ("cost_ci_low", "cost_ci_high"),
             "return_mean": ("return_ci_low", "return_ci_high")}
"""Columns shown with their 95% interval (Wilson for rates, bootstrap of the mean for costs)."""


def _cell(key: str, value: str, row: dict[str, str] | None = None) -> str:
    if key not in DIGITS:
        return value
    try:
        x = float(value)
    except ValueError:
        return value or "-"
    if not math.isfinite(x):
        return "-"
    text = f"{x:.{DIGITS[key]}f}"
    if row is not None and key in INTERVALS and all(k in row for k in INTERVALS[key]):
        try:
            low, high = (float(row[k]) for k in INTERVALS[key])
        except ValueError:
            return text
        if math.isfinite(low) and math.isfinite(high):
            text += f" [{low:.{DIGITS[key]}f}, {high:.{DIGITS[key]}f}]"
    return text


def readme_table(report_dir: Path, experiment: str | None = None) -> str:
    """The Markdown table of one experiment of ``report_dir/summary.csv`` (rows of trials not
    run yet left out; a *cell* and an *initial samples* column where the experiment varies them).

    Args:
        report_dir: a results directory written by ``python -m benchmarks``.
        experiment: experiment name (default: the first one in the CSV).

    Raises:
        FileNotFoundError: no ``summary.csv`` in ``report_dir``.
        ValueError: unknown experiment (the message lists the ones present).
    """
    path = Path(report_dir) / "summary.csv"
    if not path.is_file():
        raise FileNotFoundError(f"no summary.csv in {report_dir}: run python -m benchmarks first")
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    experiments = list(dict.fromkeys(r["experiment"] for r in rows))
    if not experiments:
        raise ValueError(f"{path} has no rows")
    experiment = experiment or experiments[0]
    if experiment not in experiments:
        raise ValueError(f"unknown experiment {experiment!r}; present: {', '.join(experiments)}")
    rows = [r for r in rows if r["experiment"] == experiment and r.get("status") != "missing"]
    from benchmarks.outside_envs import OUTSIDE_ENVS

    if rows and all(r["env"] in OUTSIDE_ENVS for r in rows):
        return _table(_headline(rows), list(OUTSIDE_COLUMNS))
    columns = list(COLUMNS)
    # the robustness cells and initial-sample counts, where an experiment varies them
    if any(r.get("cell", "fixed truth") != "fixed truth" for r in rows):
        columns.insert(2, ("cell", "cell"))
    if len({r.get("n_init") for r in rows}) > 1:
        columns.insert(columns.index(("controller", "controller")), ("n_init", "initial samples"))
    return _table(rows, columns)


def _headline(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    """The rows that ran, each learning recipe at its largest initial-sample count per (env,
    scenario) only (the references have none)."""
    ran = [r for r in rows if r.get("status") != "not available"]
    largest: dict[tuple[str, str, str], int] = {}
    for r in ran:
        key = (r["env"], r["scenario"], r["controller"])
        largest[key] = max(largest.get(key, 0), int(float(r.get("n_init") or 0)))
    return [r for r in ran if int(float(r.get("n_init") or 0))
            == largest[(r["env"], r["scenario"], r["controller"])]]


def _table(rows: list[dict[str, str]], columns: list[tuple[str, str]]) -> str:
    lines = ["| " + " | ".join(h for _, h in columns) + " |",
             "|" + "|".join("---" if k in ("env", "scenario", "controller", "cell") else "---:"
                            for k, _ in columns) + "|"]
    for r in rows:
        cells = [_controller(r) if k == "controller" else _cell(k, r[k], r) for k, _ in columns]
        if r["status"] == "not available":
            n = columns.index(("episodes", "episodes"))
            cells = [*cells[:n], "not available", *["-"] * (len(columns) - n - 1)]
        lines.append("| " + " | ".join(cells) + " |")
    if all("controller" in r for r in rows):
        from benchmarks.report.common import controller_legend

        lines += controller_legend(r["controller"] for r in rows)
    return "\n".join(lines)


def _controller(row: dict[str, str]) -> str:
    """The row's controller by its CLI name (a CSV without a ``controller`` column: its
    label)."""
    if "controller" not in row:
        return row.get("label", "")
    from benchmarks.report.common import cli_name

    return f"`{cli_name(row['controller'])}`"


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; prints the table to stdout."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("report_dir", type=Path, help="results directory (with summary.csv)")
    p.add_argument("--experiment", help="experiment name (default: the first in the CSV)")
    args = p.parse_args(argv)
    try:
        print(readme_table(args.report_dir, args.experiment))
    except (FileNotFoundError, ValueError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
