"""What the paired studies share: run a list of trials into a folder (resumable), keep their
metrics as ``metrics.csv`` there, read a committed run's metrics, and write the study's tables
beside them (``sqp_scheme``, ``grey_box``, ``plan_guard``)."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from benchmarks.runner import run_trials
from benchmarks.trial import TrialSpec

__all__ = ["read_metrics", "run_and_record", "success_text", "write_tables"]


def success_text(k: int, n: int) -> str:
    """``k`` successes of ``n`` with their 95% Wilson interval: ``"9/10 [0.60, 0.98]"``."""
    from benchmarks.report.stats import wilson_ci

    lo, hi = wilson_ci(k, n)
    return f"{k}/{n} [{lo:.2f}, {hi:.2f}]"


def read_metrics(path: Path) -> dict[str, dict[str, str]]:
    """The rows of a ``metrics.csv`` by trial key (values as written)."""
    with path.open() as f:
        return {r["key"]: r for r in csv.DictReader(f)}


def run_and_record(specs: Sequence[TrialSpec], out: Path, workers: int = 1
                   ) -> dict[str, dict[str, str]]:
    """Run ``specs`` into ``out`` (finished trials are kept), write their metrics to
    ``out/metrics.csv`` (the benchmark's columns, as ``gp-bench`` writes them) and return them
    by trial key, as :func:`read_metrics` would."""
    from benchmarks.report.load import METRIC_COLUMNS, load_trials, metric_rows

    run_trials(list(specs), out, workers=workers)
    rows = metric_rows(load_trials(out, specs).values())
    if rows:
        with (out / "metrics.csv").open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(METRIC_COLUMNS), extrasaction="ignore")
            writer.writeheader()
            writer.writerows(rows)
    return read_metrics(out / "metrics.csv") if rows else {}


def write_tables(out: Path, title: str, command: str, tables: str) -> str:
    """Write ``out/tables.md`` (a title, the command that makes it, the tables); returns it."""
    text = f"# {title}\n\n`{command}`\n\n{tables}"
    out.mkdir(parents=True, exist_ok=True)
    (out / "tables.md").write_text(text)
    return text
