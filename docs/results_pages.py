"""Results pages generated from the committed ``summary.csv`` files (never pasted by hand).

:func:`write_results_pages` writes one MyST page per results folder of
``benchmarks/results/`` that has a ``summary.csv`` (its preset's one line, its tables, its
figures), a page of the RL baselines (``benchmarks/results/rl``), and an index listing each page
with its one line, into ``docs/results/`` (git-ignored: rebuilt by every documentation build).
Controllers are named by their CLI names (:func:`benchmarks.report.cli_name`), with one legend
line per table. The README's headline table comes from :func:`headline_table` of the same
files.
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

RL = "rl"
"""Sub-folder of ``benchmarks/results`` with the RL baselines (``rl_eval.csv``, figures)."""

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
    from benchmarks.report import cli_name, controller_legend

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
            f"`{cli_name(r['controller'])}`{r.get('_suffix', '')}", str(int(get("episodes"))),
            _interval(get("success_rate"), get("success_ci_low"), get("success_ci_high")),
            *([_interval(get("return_mean"), get("return_ci_low"), get("return_ci_high"), 1),
               r.get("n_init", "")] if outside else
              [_interval(get("cost_mean"), get("cost_ci_low"), get("cost_ci_high"))]),
            _fmt(get("time_to_success_mean_s")),
            *([] if outside else [_fmt(get("final_position_error_max"), 4)]),
            r.get("violations_total", ""),
        ])
    return _table(header, body) + controller_legend(r["controller"] for r in rows)


def preset_line(folder: Path) -> str:
    """What the run of ``folder`` answers, in one line: the description of its preset
    (:data:`benchmarks.presets.PRESETS`; the folder's name, else the preset its ``report.md``
    names), else its report's title; empty if neither is known."""
    from benchmarks.presets import PRESETS

    report = folder / "report.md"
    title = report.read_text().splitlines()[0] if report.is_file() else ""
    named = re.fullmatch(r"# Benchmark report: `([^`]+)`", title)
    name = folder.name if folder.name in PRESETS else named.group(1) if named else None
    if name in PRESETS:
        text = PRESETS[name].description
        return f"{text}." if name == folder.name else f"preset `{name}`: {text}."
    return title.removeprefix("# ").strip()


def figures(folder: Path, page_dir: str = "../..") -> list[str]:
    """Markdown images of the figures (``*.png``) of ``folder``, relative to a page in
    ``docs/results`` (none: no lines)."""
    return [line for png in sorted(folder.glob("*.png"))
            for line in (f"![{png.stem}]({page_dir}/benchmarks/results/{folder.name}/"
                         f"{png.name})", "")]


def folder_page(folder: Path) -> str:
    """The MyST page of one results folder: its one line, its tables, its figures."""
    rows = summary_rows(folder / "summary.csv")
    lines = [f"# `{folder.name}`", ""]
    if line := preset_line(folder):
        lines += [line, ""]
    report = folder / "report.md"
    if report.is_file():
        lines += [f"The full report with its command: "
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
    if pngs := figures(folder):
        lines += ["## Figures", "", *pngs]
    return "\n".join(lines)


def _tolerance(env_id: str) -> tuple[str, float]:
    """The goal tolerance of ``env_id``'s task in words (each checked state component's bound
    and the hold time) and the norm of the checked bounds (the scale of
    ``info["distance_to_goal"]``)."""
    import gymnasium as gym
    import numpy as np

    import gp_envs

    env = gym.make(env_id)
    try:
        model = gp_envs.nominal_model(env)
    finally:
        env.close()
    task = model.task
    checked = np.isfinite(task.goal_tolerance)
    parts = [f"{name} within {tol:g}" for name, tol, ok in
             zip(model.state_names, task.goal_tolerance, checked, strict=True) if ok]
    return (f"{', '.join(parts)} of the goal, held {task.hold_time:g} s",
            float(np.linalg.norm(task.goal_tolerance[checked])))


def _training_reward(model_dir: Path) -> str:
    """What the shipped policy in ``model_dir`` was trained on, from its ``metadata.json``: the
    task's reward (minus the quadratic cost) and the training wrappers that reshaped it."""
    meta_file = model_dir / "metadata.json"
    meta = json.loads(meta_file.read_text()) if meta_file.is_file() else {}
    wrappers = [w["name"] for w in meta.get("training_wrappers") or []
                if "Reward" in w.get("name", "")]
    return "minus the quadratic cost" + (f" (reshaped by {', '.join(wrappers)})"
                                         if wrappers else "")


def rl_page(folder: Path) -> str:
    """The MyST page of the RL baselines: per shipped policy (``rl_eval.csv``) its success and
    cost over its evaluation episodes, and where it fails the task's goal tolerance, why (the
    training reward, the final distance against the tolerance); then the folder's figures."""
    from benchmarks.report import cli_name, controller_legend

    with (folder / "rl_eval.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    lines = ["# `rl`", "",
             "The shipped RL baselines (stable-baselines3 policies, `sac`, `ppo`, `tqc`) on the "
             "plain envs, each evaluated deterministically on reset seeds 0..19: can a "
             "policy trained from the reward alone do the task the MPC does?", "",
             "Generated from `benchmarks/results/rl/rl_eval.csv` (`python -m "
             "benchmarks.rl.evaluate`); the spread over training seeds is in "
             "`benchmarks/results/rl/summary.md`. Cost: minus the env's return. Final distance: "
             "`info[\"distance_to_goal\"]` at the last step, mean over the episodes.", ""]
    body = []
    for r in rows:
        success = _float(r["success_rate"])
        cost = _interval(-_float(r["mean_return"]), -_float(r["return_ci_high"]),
                         -_float(r["return_ci_low"]))
        distance = _float(r["mean_final_distance"])
        note = ""
        if success < 1:
            tolerance, scale = _tolerance(r["env_id"])
            near = ("stays near the goal without holding it within tolerance"
                    if distance <= 5 * scale else "ends far from the goal")
            note = (f"fails the task's tolerance ({tolerance}) in "
                    f"{round((1 - success) * _float(r['episodes']))} of {r['episodes']} "
                    f"episodes: trained on {_training_reward(folder.parent.parent / r['model'])}"
                    f", which never asks for the tolerance, it {near} (final distance "
                    f"{distance:.3f}, within tolerance at some step in "
                    f"{_float(r['success_any_rate']):.0%} of the episodes)")
        body.append([r["env"], f"`{r['scenario']}`", f"`{cli_name(r['algo'])}`", r["seed"],
                     r["training_steps"],
                     _interval(success, _float(r["success_ci_low"]),
                               _float(r["success_ci_high"])),
                     cost, _fmt(distance, 3), note])
    lines += _table(["env", "scenario", "controller", "training seed", "env steps trained",
                     "success", "cost", "final distance", "why it fails"], body)
    lines += controller_legend(r["algo"] for r in rows)
    lines += ["", *(["## Figures", "", *pngs] if (pngs := figures(folder)) else [])]
    return "\n".join(lines)


def write_results_pages(results: Path, out: Path) -> list[Path]:
    """Write a page per results folder with a ``summary.csv`` (the archive listed only), the RL
    baselines' page (:func:`rl_page`, if ``results/rl/rl_eval.csv`` exists) and an index
    listing each page with its one line into ``out``, removing the pages of folders that are
    gone (moved to the archive, renamed); returns the pages written."""
    out.mkdir(parents=True, exist_ok=True)
    folders = sorted(p.parent for p in results.glob("*/summary.csv"))
    rl = results / RL
    has_rl = (rl / "rl_eval.csv").is_file()
    current = ({f"{folder.name}.md" for folder in folders} | {"index.md"}
               | ({f"{RL}.md"} if has_rl else set()))
    for stale in out.glob("*.md"):
        if stale.name not in current:
            stale.unlink()
    written = []
    entries = []
    for folder in folders:
        page = out / f"{folder.name}.md"
        page.write_text(folder_page(folder))
        written.append(page)
        entries.append((folder.name, preset_line(folder)))
    if has_rl:
        page = out / f"{RL}.md"
        page.write_text(rl_page(rl))
        written.append(page)
        entries.append((RL, "The shipped RL baselines on the plain envs, and why they fail "
                        "the task's tolerance."))
    entries.sort()
    archived = sorted(p.parent.name for p in (results / ARCHIVE).glob("*/summary.csv"))
    index = ["# Results", "", INDEX_INTRO, "", "```{toctree}", ":maxdepth: 1", ":hidden:", ""]
    index += [name for name, _ in entries] + ["```", ""]
    index += [f"- [`{name}`]({name}.md)" + (f": {line}" if line else "")
              for name, line in entries] + [""]
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
        body.append({**r, "_suffix": f", {r['env']}"})
    return "\n".join(episode_table(body))
