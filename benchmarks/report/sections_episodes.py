"""Report sections on the episodes: the summary table, the paper's tables, trajectories,
paths, step times, sample efficiency and the robustness envelope."""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from benchmarks.controllers import CONTROLLERS, MODELS_DIR, RL_ALGORITHMS
from benchmarks.presets import MPC_BASES, Experiment
from benchmarks.report import figures
from benchmarks.report.common import (
    Context,
    _env_model,
    _env_title,
    _first_ok,
    _fmt,
    _interval,
    _name,
    _style,
    _time_varying,
    controller_legend,
    markdown_table,
)
from benchmarks.report.figures import paths_figure, step_times_figure, trajectories_figure
from benchmarks.report.load import Trial
from benchmarks.report.stats import _finite_number
from benchmarks.trial import EPISODE_KINDS, STATUS_OK, STATUS_UNAVAILABLE
from gp_agents.mpc.diagnostics import DEGRADED_FRACTION


def _rti_paths_table(rows: list[dict[str, Any]]) -> list[str]:
    """The real-time iterations' paths per cell (rows with RTI steps only; none: no lines)."""
    rti = [r for r in rows if _finite_number(r.get("rti_steps")) and r["rti_steps"] > 0]
    if not rti:
        return []
    body = [[f"{r['env']} `{r['scenario']}`, {r['cell']}", _name(r["controller"]), r["episodes"],
             r["rti_steps"], r["rti_recovered"], r["rti_rejected"],
             f"{100 * r['rti_rejected_fraction']:.1f}%"] for r in rti]
    return ["", "Real-time iteration paths per cell (summed over the episodes): RTI steps taken, "
            "steps *recovered* by further SQP iterations within the iteration budget "
            "(`RTI.recovery_iterations`), steps *rejected* (replaced by a converged solve):",
            "", *markdown_table(["cell", "controller", "episodes", "RTI steps", "recovered",
                                 "rejected", "rejected %"], body,
                                ["---", "---"] + ["---:"] * 5)]


def section_summary(ctx: Context, exp: Experiment) -> list[str]:
    """Per-controller table of the experiment's episodes."""
    rows = ctx.summaries[exp.name]
    header = ["env", "controller", "episodes", "success [95% CI]", "cost mean [95% CI]",
              "time to success (s)", "final dist.", "final pos. err. (m)", "violations",
              "data steps", "act median / p95 / max (ms)", "solver fails / fallbacks", "status"]
    body = []
    for r in rows:
        cell = "" if r["cell"] == "fixed truth" else f", {r['cell']}"
        body.append([
            f"{r['env']} `{r['scenario']}`{cell}", _name(r["controller"]), r["episodes"],
            f"{_fmt(r['success_rate'])} {_interval(r['success_ci_low'], r['success_ci_high'])}",
            f"{_fmt(r['cost_mean'])} {_interval(r['cost_ci_low'], r['cost_ci_high'])}",
            r["time_to_success_mean_s"],
            r["final_distance_mean"], r["final_position_error_mean"],
            f"{r['violations_total']} in {r['episodes_with_violation']} ep.",
            _fmt(r["data_steps_mean"], 0),
            f"{_fmt(r['act_median_ms'], 1)} / {_fmt(r['act_p95_ms'], 1)} / "
            f"{_fmt(r['act_max_ms'], 0)}",
            f"{_fmt(r['solver_failures'])} / {_fmt(r['fallbacks'])}", r["status"]])
    lines = ["", "Per controller (means over episodes, with 95% intervals over seeds: Wilson for "
             "the success rate, bootstrap (BCa) of the mean for the cost; *success*: "
             "`info['success']` at the episode end (episodic plans: at the goal at the plan's "
             "final time); *final dist.*: `info['distance_to_goal']`; *violations*: steps with "
             "`info['constraint_violation']`; *data steps*: env steps of data used):", ""]
    lines += markdown_table(header, body, ["---", "---"] + ["---:"] * 10 + ["---"])
    lines += controller_legend(r["controller"] for r in rows)
    lines += _rti_paths_table(rows)
    unavailable = [t for t in ctx.of(exp) if t.status == STATUS_UNAVAILABLE]
    reasons = sorted({f"{t.spec.controller} on {t.spec.env} `{t.spec.scenario}`: "
                      f"{t.record['message']}" for t in unavailable if t.record})
    if reasons:
        lines += ["", "Not available (recorded, not run):", ""] + [f"- {r}" for r in reasons]
    degraded = [t for t in ctx.of(exp) if t.status == STATUS_OK and t.metrics.get("degraded")]
    if degraded:
        lines += ["", f"{len(degraded)} trial(s) degraded: the MPC took a fallback path (RTI "
                  f"step rejected, solve failed or capped, older plan kept) in more than "
                  f"{DEGRADED_FRACTION:.0%} of an episode's replans (`degraded` in "
                  f"`metrics.csv`; the agent warned with `ControllerDegradedWarning`):", ""]
        lines += [f"- `{t.spec.key}`: RTI steps rejected {t.metrics.get('rti_rejected')}, "
                  f"solver failures {t.metrics.get('solver_failures')}"
                  for t in degraded[:10]]
        if len(degraded) > 10:
            lines.append(f"- ... and {len(degraded) - 10} more")
    errors = [t for t in ctx.of(exp) if t.status == "error"]
    if errors:
        lines += ["", f"{len(errors)} trial(s) failed with an exception (see `metrics.csv`):", ""]
        lines += [f"- `{t.spec.key}`: {t.record['message'].strip().splitlines()[-1]}"
                  for t in errors[:10] if t.record]
    missing = [t for t in ctx.of(exp) if t.status == "missing"]
    if missing:
        lines += ["", f"**{len(missing)} of {len(exp.specs)} trials have not run yet** "
                  "(rerun the command to complete them)."]
    return lines


def section_paper_tables(ctx: Context, exp: Experiment) -> list[str]:
    """The paper's tables: cost and success per model, episodic vs MPC, per scenario.

    Episodic plans are scored at the plan's final time (the paper's reading: an open-loop plan
    of an unstable system cannot hold the goal for long), with the env's held criterion beside
    it; receding-horizon MPC by the held criterion. Each cell gives the final distance too.
    """
    by = {(r["env"], r["scenario"], r["controller"]): r for r in ctx.summaries[exp.name]}
    lines: list[str] = []
    for number, scenario in ((1, "gp"), (2, "online")):
        lines += ["", f"**Table {number}** (scenario `{scenario}`): cumulative cost, mean over "
                  "seeds; success rate (episodic: at the plan's final time / held for the "
                  "task's hold time; MPC: held); mean final distance to the goal", ""]
        body = []
        for env in ("cartpole", "quadrotor"):
            for base in MPC_BASES:
                cells = []
                for mode in ("episodic", "mpc"):
                    r = by.get((env, scenario, f"{base}-{mode}"))
                    if r is None or not r["episodes"]:
                        cells += ["not run" if r is None else r["status"], "", ""]
                        continue
                    success = _fmt(r["success_rate"])
                    if mode == "episodic":
                        success += f" / {_fmt(r['success_held_rate'])}"
                    cells += [_fmt(r["cost_mean"]), success, _fmt(r["final_distance_mean"], 3)]
                body.append([env, f"{_name(f'{base}-episodic')}, {_name(f'{base}-mpc')}",
                             *cells])
        lines += markdown_table(
            ["env", "controllers", "episodic cost", "episodic success (final / held)",
             "episodic final distance", "MPC cost", "MPC success", "MPC final distance"],
            body, ["---", "---", "---:", "---:", "---:", "---:", "---:", "---:"])
        lines += controller_legend(f"{base}-{mode}" for base in MPC_BASES
                                   for mode in ("episodic", "mpc"))
    defects = [(r["env"], r["scenario"], r["plan_plant_defect_max"])
               for r in ctx.summaries[exp.name]
               if r["controller"] == "oracle-episodic" and r["episodes"]]
    if defects:
        worst = ", ".join(f"{e} `{sc}` {d:.1e}" for e, sc, d in defects)
        lines += ["", "One-period defect of the oracle's episodic plan against the plant (the "
                  "plan's state at each period's end minus the plant's RK4 step from its state "
                  f"at the period's start under the plan's action, largest over periods and "
                  f"seeds, max-norm): {worst}."]
    return lines


def section_trajectories(ctx: Context, exp: Experiment) -> list[str]:
    """States and controls vs time, one line per controller, lowest seed; one figure per env."""
    by_env: dict[tuple[str, str], dict[str, list[Trial]]] = defaultdict(lambda: defaultdict(list))
    for t in ctx.of(exp):
        if t.spec.kind in EPISODE_KINDS:
            by_env[(t.spec.env, t.spec.scenario)][t.spec.controller].append(t)
    lines: list[str] = []
    for (env, scenario), controllers in by_env.items():
        chosen = {c: _first_ok(ts) for c, ts in controllers.items()}
        chosen = {c: t for c, t in chosen.items() if t is not None}
        if not chosen:
            continue
        fig = trajectories_figure(env, scenario, chosen)
        name = figures._save(fig, ctx.out_dir, f"{exp.name}_trajectories_{env}_{scenario}.png")
        lines += ["", f"![{env} {scenario} trajectories]({name})"]
    return lines


def section_paths(ctx: Context, exp: Experiment) -> list[str]:
    """x-y paths of every episode of each env whose task has obstacles, with the obstacles and
    the goal, one panel per controller; one figure per env and scenario."""
    by_env: dict[tuple[str, str], dict[str, list[Trial]]] = defaultdict(lambda: defaultdict(list))
    for t in ctx.of(exp):
        if t.spec.kind in EPISODE_KINDS and t.ok and _env_model(t.spec.env,
                                                            t.spec.scenario).task.obstacles:
            by_env[(t.spec.env, t.spec.scenario)][t.spec.controller].append(t)
    lines: list[str] = []
    for (env, scenario), groups in by_env.items():
        several = sum(e == env for e, _ in by_env) > 1
        fig = paths_figure(env, scenario, groups)
        name = figures._save(fig, ctx.out_dir, f"{exp.name}_{env}_{scenario}_paths.png" if several
                             else f"{exp.name}_{env}_paths.png")
        lines += ["", f"![{env} {scenario} paths]({name})"]
    return lines


def section_step_times(ctx: Context, exp: Experiment) -> list[str]:
    """Box plot of the per-step ``act`` time of each controller, one panel per env, with the
    env's control period (a step above it would not keep up in real time)."""
    groups: dict[str, dict[str, list[np.ndarray]]] = defaultdict(lambda: defaultdict(list))
    scenarios: dict[str, str] = {}
    for t in ctx.of(exp):
        if t.spec.kind in EPISODE_KINDS and t.ok:
            groups[t.spec.env][t.spec.controller].append(t.arrays["act_time"])
            scenarios.setdefault(t.spec.env, t.spec.scenario)
    if not groups:
        return []
    fig = step_times_figure(groups, scenarios)
    rows = []
    for env, per in groups.items():
        for c, arrays in per.items():
            d = 1e3 * np.concatenate(arrays)
            rows.append([env, _name(c), len(d), float(np.median(d)),
                         float(np.percentile(d, 95)), float(d.max())])
    name = figures._save(fig, ctx.out_dir, f"{exp.name}_step_times.png")
    lines = ["", f"![step times]({name})", ""]
    lines += markdown_table(["env", "controller", "steps", "median (ms)", "p95 (ms)", "max (ms)"],
                            rows, ["---", "---", "---:", "---:", "---:", "---:"])
    lines += controller_legend(c for per in groups.values() for c in per)
    return lines


def _learning_curve(env: str, algo: str) -> list[dict[str, float]]:
    path = MODELS_DIR / env / algo / "learning_curve.csv"
    if not path.is_file():
        return []
    with open(path) as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def section_sample_efficiency(ctx: Context, exp: Experiment) -> list[str]:
    """Success and return against env steps of interaction; one figure per env. RL: its
    training-time learning curves. MPC: the interaction before success (initial data plus the
    time the final stretch held at the goal began, in env steps) where the cell succeeded,
    else the env steps of data it used (initial data plus the whole episode)."""
    by = defaultdict(list)
    for r in ctx.summaries[exp.name]:
        by[(r["env"], r["scenario"])].append(r)
    lines: list[str] = []
    for (env, scenario), rows in by.items():
        dt = float(_env_model(env, scenario).dt)
        fig, (ax_s, ax_r) = plt.subplots(1, 2, figsize=(11, 4))
        table = []
        for algo in RL_ALGORITHMS:
            curve = [p for p in _learning_curve(env, algo) if p["timesteps"] > 0]  # log axis
            rl_row = next((r for r in rows if r["controller"] == algo), None)
            if curve and rl_row is not None and rl_row["episodes"]:
                st = _style(algo)
                steps = [p["timesteps"] for p in curve]
                curve_style = {"color": st.color, "ls": st.linestyle, "lw": 1, "alpha": 0.8}
                ax_s.plot(steps, [p["success_rate"] for p in curve], **curve_style,
                          label=f"{algo} learning curve (training evals)")
                ax_r.plot(steps, [p["mean_return"] for p in curve], **curve_style,
                          label=f"{algo} learning curve (training evals)")
        for r in rows:
            if not r["episodes"]:
                table.append([_name(r["controller"]), "", "", "", "", r["status"]])
                continue
            point = _style(r["controller"]).point()
            interaction = r.get("interaction_mean_s", math.nan)
            before = (interaction / dt if r["controller"] not in RL_ALGORITHMS
                      and math.isfinite(interaction) else math.nan)
            x = before if math.isfinite(before) else r["data_steps_mean"]
            ax_s.plot([x], [r["success_rate"]], label=r["controller"], **point)
            ax_r.plot([x], [-r["cost_mean"]], label=r["controller"], **point)
            table.append([_name(r["controller"]), _fmt(before, 0), _fmt(r["data_steps_mean"], 0),
                          r["success_rate"], -r["cost_mean"], f"{r['episodes']} episodes"])
        for ax, ylabel in ((ax_s, "success rate"), (ax_r, "return (= minus cost)")):
            ax.set_xscale("log")
            ax.set_xlabel("env steps of interaction (MPC: before success; RL: training)")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
        ax_r.set_yscale("symlog", linthresh=10)
        ax_s.legend(fontsize=7, loc="best")
        fig.suptitle(f"{_env_title(env, scenario)}: sample efficiency", fontsize=10)
        fig.tight_layout()
        name = figures._save(fig, ctx.out_dir, f"{exp.name}_sample_efficiency_{env}_{scenario}.png")
        lines += ["", f"![{env} sample efficiency]({name})", ""]
        lines += markdown_table(["controller", "env steps of interaction before success",
                                 "env steps of data used", "success rate", "mean return",
                                 "evaluated"], table,
                                ["---", "---:", "---:", "---:", "---:", "---"])
        lines += controller_legend(r["controller"] for r in rows)
    return lines


def section_robustness(ctx: Context, exp: Experiment) -> list[str]:
    """Success per cell of the envelope, each learning MPC's as a share of the oracle's."""
    rows = ctx.summaries[exp.name]
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    cells: dict[tuple[str, str, str, int], dict[str, dict[str, Any]]] = defaultdict(dict)
    for r in rows:
        cells[(r["env"], r["scenario"], r["cell"], r["n_init"])][r["controller"]] = r
    learners = [c for c in controllers if CONTROLLERS[c].learner is not None]
    header = ["env", "scenario", "cell", "initial samples", *[_name(c) for c in controllers],
              *[f"{_name(c)} / oracle" for c in learners if "oracle-mpc" in controllers],
              "episodes with a violation", "max final pos. err. (m)", "recovered / max (s)"]
    body = []
    for (env, scenario, cell, n_init), by in cells.items():
        line: list[Any] = [env, f"`{scenario}`", cell, n_init]
        for c in controllers:
            r = by.get(c)
            line.append("" if r is None or not r["episodes"] else
                        f"{r['success_rate'] * r['episodes']:.0f}/{r['episodes']} "
                        f"{_interval(r['success_ci_low'], r['success_ci_high'])}")
        oracle = by.get("oracle-mpc")
        for c in learners:
            if "oracle-mpc" not in controllers:
                break
            r = by.get(c)
            line.append(_fmt(r["success_rate"] / oracle["success_rate"])
                        if r and oracle and oracle["success_rate"] else "")
        present = [by[c] for c in controllers if c in by and by[c]["episodes"]]
        line.append(", ".join(f"{_name(r['controller'])} {r['episodes_with_violation']}"
                              for r in present if r["episodes_with_violation"]) or "0")
        line.append(", ".join(f"{_name(r['controller'])} {_fmt(r['final_position_error_max'], 3)}"
                              for r in present if np.isfinite(r["final_position_error_max"]))
                    or "n/a")
        line.append(", ".join(f"{_name(r['controller'])} {r['recovered']}/{r['episodes']}, "
                              f"{_fmt(r['recovery_max_s'])}"
                              for r in present if _time_varying(r)) or "n/a")
        body.append(line)
    lines = ["", "Success per cell (episodes that hold the goal at the end / episodes, with "
             "Wilson 95% intervals), the learning MPCs' success rate as a share of the "
             "oracle's in the same cell, episodes with a constraint violation (obstacle contact, "
             "or leaving the state box: a crash), the largest final position error, "
             "and in the time-varying scenarios how many episodes get back within "
             "1 cm of the goal after the change and stay there, with the longest time it "
             "took. Initial data: *same* = from the system then controlled, *diff* = from an "
             "independent draw of the same spread.", ""]
    lines += markdown_table(header, body, ["---"] * 3 + ["---:"] * (len(header) - 3))
    lines += controller_legend(controllers)
    return lines
