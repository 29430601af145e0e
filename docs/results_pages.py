"""Results pages generated from the committed ``summary.csv`` files (never pasted by hand).

:func:`write_results_pages` writes one MyST page per results folder of
``benchmarks/results/`` that has a ``summary.csv``, and an index, into ``docs/results/``
(git-ignored: rebuilt by every documentation build). The README's headline table comes from
:func:`headline_table` of the same files.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Sequence
from pathlib import Path

ARCHIVE = "archive"
"""Sub-folder of ``benchmarks/results`` with superseded runs (listed, not rendered)."""

INDEX_INTRO = """Every table on these pages is generated from the committed `summary.csv` of a
results folder in `benchmarks/results/` when the documentation is built: success rates with
Wilson 95% intervals, mean costs with bootstrap (BCa) 95% intervals over seeds. Each folder's
`report.md` has the command that produced it, the machine, the code version and the figures."""


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def _fmt(value: float, digits: int = 2) -> str:
    return "" if math.isnan(value) else f"{value:.{digits}f}"


def _interval(mean: float, low: float, high: float, digits: int = 2) -> str:
    if math.isnan(mean):
        return ""
    if math.isnan(low) or math.isnan(high):
        return _fmt(mean, digits)
    return f"{mean:.{digits}f} [{low:.{digits}f}, {high:.{digits}f}]"


def _table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |"
              for row in rows]
    return lines


def summary_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a ``summary.csv`` with at least one episode run."""
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return [r for r in rows if "episodes" not in r or _float(r["episodes"]) > 0]


def episode_table(rows: Sequence[dict[str, str]]) -> list[str]:
    """A Markdown table of episode summary rows: controller, episodes, success [95% CI], cost
    [95% CI], time to success, worst final position error, violations; for an outside
    simulator's rows (:mod:`benchmarks.outside_envs`, whose reward is its own), its return
    [95% CI] and initial samples instead of the cost and the position error."""
    from benchmarks.outside_envs import OUTSIDE_ENVS

    outside = any(r.get("env") in OUTSIDE_ENVS for r in rows)
    header = ["controller", "episodes", "success",
              *(["return", "initial samples"] if outside else ["cost"]),
              "time to success (s)",
              *([] if outside else ["max final position error (m)"]), "violations"]
    body = []
    for r in rows:
        def get(name: str, row: dict[str, str] = r) -> float:
            return _float(row.get(name, "nan"))

        body.append([
            f"`{r['controller']}`", str(int(get("episodes"))),
            _interval(get("success_rate"), get("success_ci_low"), get("success_ci_high")),
            *([_interval(get("return_mean"), get("return_ci_low"), get("return_ci_high"), 1),
               r.get("n_init", "")] if outside else
              [_interval(get("cost_mean"), get("cost_ci_low"), get("cost_ci_high"))]),
            _fmt(get("time_to_success_mean_s")),
            *([] if outside else [_fmt(get("final_position_error_max"), 4)]),
            r.get("violations_total", ""),
        ])
    return _table(header, body)


def folder_page(folder: Path) -> str:
    """The MyST page of one results folder."""
    rows = summary_rows(folder / "summary.csv")
    lines = [f"# `{folder.name}`", ""]
    report = folder / "report.md"
    if report.is_file():
        lines += [f"The full report with its command and figures: "
                  f"`benchmarks/results/{folder.name}/report.md`.", ""]
    if rows and "success_rate" in rows[0]:
        groups: dict[tuple[str, ...], list[dict[str, str]]] = {}
        for r in rows:
            key = (r.get("experiment", ""), r["env"], r["scenario"], r.get("cell", ""),
                   r.get("n_init", ""))
            groups.setdefault(key, []).append(r)
        for (experiment, env, scenario, cell, n_init), group in groups.items():
            title = f"{env} `{scenario}`"
            if cell:
                title += f", {cell}"
            if n_init:
                title += f", {n_init} initial samples"
            lines += [f"## {experiment}: {title}" if experiment else f"## {title}", ""]
            lines += [*episode_table(group), ""]
    elif rows:
        columns = list(rows[0])
        lines += [*_table(columns, ([r[c] for c in columns] for r in rows)), ""]
    return "\n".join(lines)


def write_results_pages(results: Path, out: Path) -> list[Path]:
    """Write a page per results folder with a ``summary.csv`` (the archive listed only) and an
    index into ``out``, removing the pages of folders that are gone (moved to the archive,
    renamed); returns the pages written."""
    out.mkdir(parents=True, exist_ok=True)
    folders = sorted(p.parent for p in results.glob("*/summary.csv"))
    current = {f"{folder.name}.md" for folder in folders} | {"index.md"}
    for stale in out.glob("*.md"):
        if stale.name not in current:
            stale.unlink()
    written = []
    for folder in folders:
        page = out / f"{folder.name}.md"
        page.write_text(folder_page(folder))
        written.append(page)
    archived = sorted(p.parent.name for p in (results / ARCHIVE).glob("*/summary.csv"))
    index = ["# Results", "", INDEX_INTRO, "", "```{toctree}", ":maxdepth: 1", ""]
    index += [f.name for f in folders] + ["```", ""]
    if archived:
        index += ["Superseded runs, kept for the record in `benchmarks/results/archive/`: "
                  + ", ".join(f"`{name}`" for name in archived) + ".", ""]
    (out / "index.md").write_text("\n".join(index))
    return [*written, out / "index.md"]


def headline_table(results: Path, preset: str = "recommended") -> str:
    """The README's results table: every episode row of ``preset``'s ``summary.csv``."""
    rows = summary_rows(results / preset / "summary.csv")
    body = []
    for r in rows:
        body.append({**r, "controller": f"{r['controller']}, {r['env']}"})
    return "\n".join(episode_table(body))
