"""Tables, plots and the Markdown report of a results directory.

:func:`write_report` reads the trial files of a preset (``<out>/runs/*.npz``, see
:mod:`benchmarks.runner`) and writes next to them:

- ``metrics.csv``: one row per episode trial (the tidy table of metrics);
- ``summary.csv``: per experiment, env, scenario and controller: success rate, cost, errors,
  violations, data used, step times;
- ``compute.csv`` and ``peers.csv`` when the preset has those measurements;
- PNG figures, and ``report.md`` embedding them with the command and package versions.

Every number in the report comes from the trial files; nothing is typed in.
"""

from __future__ import annotations

import csv
import datetime as _dt
import functools
import importlib.metadata
import math
import os
import platform
import subprocess
from collections import defaultdict
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import (
    FixedFormatter,
    FixedLocator,
    FormatStrFormatter,
    LogLocator,
    NullFormatter,
    NullLocator,
)

import gp_envs
from benchmarks.compute import STEP_SCALING
from benchmarks.controllers import (
    CONTROLLERS,
    ENVS,
    MODELS_DIR,
    RL_ALGORITHMS,
    learned_term,
    make_env,
    scenario_changes,
)
from benchmarks.presets import MPC_BASES, Experiment, Preset
from benchmarks.runner import load_arrays, load_record, trial_path
from benchmarks.styles import EPISODIC, RTI, WARM_DUALS, Style, axis_label, style
from benchmarks.trial import EPISODE_KINDS, STATUS_OK, STATUS_UNAVAILABLE, Cell, TrialSpec
from gp_agents.mpc.diagnostics import DEGRADED_FRACTION

METRIC_COLUMNS = (
    "key", "env", "scenario", "cell", "controller", "family", "mode", "seed", "status",
    "success", "success_held", "at_goal_final", "time_to_success_s", "cost", "final_distance",
    "final_position_error", "recovery_s", "violations", "termination", "steps", "data_steps",
    "act_median_ms", "act_p95_ms", "act_max_ms", "solver_failures", "fallbacks", "solves",
    "capped_solves", "learner_changes", "rti_steps", "rti_recovered", "rti_recovery_iterations",
    "rti_rejected", "degraded", "plan_plant_defect",
    "build_s", "episode_s", "max_steps", "message", "n_init", "initial_data_steps",
    "at_goal_since_s", "interaction_s", "trials", "trials_to_success", "interaction_trials_s",
    "trial_successes", "trial_costs", "data_steps_trials", "return", "residual_off_steps",
)
TIME_COLUMNS = ("act_median_ms", "act_p95_ms", "act_max_ms", "build_s", "episode_s")
"""The columns of ``metrics.csv`` that are wall-clock times: the only ones a run's machine load
may change (the controllers are capped by iterations, never by time)."""
SUMMARY_COLUMNS = (
    "experiment", "env", "scenario", "cell", "n_init", "controller", "label", "status",
    "episodes",
    "success_rate",
    "success_ci_low", "success_ci_high", "cost_mean", "cost_ci_low", "cost_ci_high", "cost_std",
    "cost_median", "time_to_success_mean_s", "final_distance_mean",
    "final_position_error_mean", "final_position_error_max", "recovery_max_s", "recovered",
    "violations_total",
    "episodes_with_violation", "data_steps_mean", "act_median_ms", "act_p95_ms", "act_max_ms",
    "solver_failures", "fallbacks", "success_held_rate", "plan_plant_defect_max",
    "solve_median_ms", "outside_median_ms", "latency_median_ms", "preparation_median_ms",
    "accepted_latency_median_ms", "rti_steps", "rti_recovered", "rti_rejected",
    "rti_rejected_fraction",
    "interaction_mean_s", "interaction_ci_low", "interaction_ci_high",
    "trials_success_rate", "trials_success_ci_low", "trials_success_ci_high",
    "trials_to_success_mean", "interaction_trials_mean_s", "interaction_trials_ci_low",
    "interaction_trials_ci_high", "return_mean", "return_ci_low", "return_ci_high",
    "residual_off_steps_mean",
)
PACKAGES = ("gp-pseudospectral-mpc", "numpy", "scipy", "casadi", "gymnasium", "matplotlib",
            "torch", "stable-baselines3", "do-mpc", "dask", "distributed", "tqdm")


# ----------------------------------------------------------------------------- loading
@dataclass
class Trial:
    """A trial's spec, record (or None if never run) and lazily loaded arrays."""

    spec: TrialSpec
    path: Path
    record: dict[str, Any] | None
    _arrays: dict[str, np.ndarray] | None = field(default=None, repr=False)

    @property
    def status(self) -> str:
        """``ok``, ``error``, ``unavailable`` or ``missing`` (never run)."""
        return "missing" if self.record is None else str(self.record["status"])

    @property
    def ok(self) -> bool:
        """The trial finished successfully."""
        return self.status == STATUS_OK

    @property
    def metrics(self) -> dict[str, Any]:
        """The trial's metrics (empty unless ok)."""
        return self.record.get("metrics", {}) if self.record else {}

    @property
    def arrays(self) -> dict[str, np.ndarray]:
        """The trial's arrays (trajectory, diagnostics), loaded on first use."""
        if self._arrays is None:
            self._arrays = load_arrays(self.path) if self.ok else {}
        return self._arrays


def load_trials(out_dir: Path, specs: Iterable[TrialSpec]) -> dict[TrialSpec, Trial]:
    """The trials of ``specs`` as stored in ``out_dir`` (missing ones with ``record=None``)."""
    out = {}
    for spec in specs:
        path = trial_path(out_dir, spec)
        out[spec] = Trial(spec, path, load_record(path))
    return out


# ----------------------------------------------------------------------------- helpers
def _label(controller: str) -> str:
    recipe = CONTROLLERS.get(controller)
    return recipe.label if recipe else controller


def _style(controller: str) -> Style:
    """The controller's fixed style (:data:`benchmarks.styles.STYLES`; raises if it has none)."""
    return style(controller)


@functools.cache
def _env_model(env: str, scenario: str) -> Any:
    """The nominal :class:`gp_envs.ControlModel` of benchmark env ``env`` in ``scenario``
    (its ``dt``, names and task; the Dubins nominal parameters redrawn at each reset do not
    matter here)."""

    made = make_env(env, scenario)
    try:
        return gp_envs.nominal_model(made)
    finally:
        made.close()


@functools.cache
def _system(env: str) -> str | None:
    """The registered system whose physics benchmark env ``env`` plans with (the key of
    :func:`benchmarks.styles.unit`): the env's own, or for an outside env the system of its
    nominal model's physics module (None: a user's ODE, whose units are not known)."""
    from gp_envs.systems import SYSTEMS

    if ENVS[env].outside is None:
        return env
    module = getattr(_env_model(env, ENVS[env].default_scenario).ode, "__module__", "")
    name = module.rsplit(".", 1)[-1]
    return name if module.startswith("gp_envs.physics.") and name in SYSTEMS else None


def _control_period_line(ax: Any, dt: float) -> Any:
    """A horizontal line (returned) at the control period ``dt`` (s) on an axis of step times
    in ms: a step above it is not real-time feasible."""
    return ax.axhline(1e3 * dt, color="tab:red", ls=":", lw=1.4, zorder=6,
               label=f"control period ({1e3 * dt:g} ms)")


def _scheme_notes(controllers: Iterable[str]) -> list[str]:
    """``["dashed: episodic", "dash-dot: real-time iteration"]``, naming only the line styles
    of the schemes that ``controllers`` use (empty if all are solid)."""
    used = {_style(c).linestyle for c in controllers}
    return [text for ls, text in ((EPISODIC, "dashed: episodic"),
                                  (RTI, "dash-dot: real-time iteration"),
                                  (WARM_DUALS, "dotted: converged, warm-started multipliers"))
            if ls in used]


def _notes(*parts: str | list[str]) -> str:
    """``" (a; b)"`` of the non-empty notes, or empty."""
    flat = [p for part in parts for p in ([part] if isinstance(part, str) else part) if p]
    return f" ({'; '.join(flat)})" if flat else ""


def _max_finite(values: Iterable[float]) -> float:
    """Largest finite value (nan if there is none, e.g. a metric undefined for the env)."""
    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    return float(arr.max()) if arr.size else math.nan


def _fmt(value: Any, digits: int = 2) -> str:
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if not math.isfinite(value):
            return "n/a"
        if abs(value) >= 1000:
            return f"{value:.0f}"
        return f"{value:.{digits}f}"
    return str(value)


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[Any]],
                   align: Sequence[str] | None = None) -> list[str]:
    """Lines of a Markdown table; numbers formatted by :func:`_fmt`."""
    align = align or ["---"] * len(header)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(_fmt(v) for v in row) + " |")
    return lines


def _mean(values: Sequence[float]) -> float:
    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    return float(arr.mean()) if arr.size else float("nan")


def mean_ci(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """Bootstrap interval of the mean over seeds (scipy's BCa, 9,999 resamples, fixed random
    state so the report is a function of the trials); (nan, nan) below 5 finite values (a
    bootstrap of fewer says nothing), the value twice if they are all equal."""
    from scipy.stats import bootstrap

    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    if arr.size < 5:
        return math.nan, math.nan
    if np.ptp(arr) == 0:
        return float(arr[0]), float(arr[0])
    res = bootstrap((arr,), np.mean, confidence_level=confidence, n_resamples=9999,
                    method="BCa", random_state=0)
    low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if not (math.isfinite(low) and math.isfinite(high)):  # BCa degenerate: percentile
        low, high = (float(v) for v in np.percentile(
            bootstrap((arr,), np.mean, n_resamples=9999, method="percentile",
                      random_state=0).bootstrap_distribution, [2.5, 97.5]))
    return low, high


def wilson_ci(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a success rate (nan, nan for n = 0)."""
    from scipy.stats import norm

    if n == 0:
        return math.nan, math.nan
    z = float(norm.ppf(0.5 + confidence / 2))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def _interval(low: float, high: float, digits: int = 2) -> str:
    """``[low, high]``, or empty when undefined."""
    if not (isinstance(low, float | int) and math.isfinite(low) and math.isfinite(high)):
        return ""
    return f"[{_fmt(float(low), digits)}, {_fmt(float(high), digits)}]"


def _write_csv(path: Path, columns: Sequence[str], rows: Iterable[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: row.get(k, "") for k in columns})


def _env_title(env: str, scenario: str) -> str:
    return f"{ENVS[env].env_id or env} ({scenario})"


def _save(fig: Any, out_dir: Path, name: str) -> str:
    fig.savefig(out_dir / name, dpi=90, bbox_inches="tight")
    plt.close(fig)
    return name


# ----------------------------------------------------------------------------- tables
def metric_rows(trials: Iterable[Trial]) -> list[dict[str, Any]]:
    """One row per episode trial (tidy metrics; failed/unavailable trials with status only)."""
    rows = []
    for t in trials:
        if t.spec.kind not in EPISODE_KINDS or t.record is None:
            continue
        recipe = CONTROLLERS[t.spec.controller]
        row: dict[str, Any] = {
            "key": t.spec.key, "env": t.spec.env, "scenario": t.spec.scenario,
            "n_init": t.spec.n_init,
            "cell": t.spec.cell.describe(), "controller": t.spec.controller,
            "family": recipe.family,
            "mode": recipe.mode if recipe.family == "mpc" else "policy", "seed": t.spec.seed,
            "status": "not available" if t.status == STATUS_UNAVAILABLE else t.status,
            "max_steps": t.spec.max_steps if t.spec.max_steps is not None else "",
            "message": "" if t.ok else t.record.get("message", "").strip().splitlines()[-1:],
        }
        if isinstance(row["message"], list):
            row["message"] = row["message"][0] if row["message"] else ""
        row.update({k: v for k, v in t.metrics.items() if k in METRIC_COLUMNS})
        rows.append(row)
    return rows


def summarize(experiment: str, trials: Sequence[Trial]) -> list[dict[str, Any]]:
    """Per (env, scenario, cell, controller) aggregates over the episode trials of an
    experiment."""
    groups: dict[tuple[str, str, Cell, int, str], list[Trial]] = defaultdict(list)
    for t in trials:
        if t.spec.kind in EPISODE_KINDS:
            groups[(t.spec.env, t.spec.scenario, t.spec.cell, t.spec.n_init,
                    t.spec.controller)].append(t)
    rows = []
    for (env, scenario, cell, n_init, controller), group in groups.items():
        ok = [t for t in group if t.ok]
        statuses = {t.status for t in group}
        if ok:
            status = "ok" if len(ok) == len(group) else f"{len(ok)}/{len(group)} ok"
        elif STATUS_UNAVAILABLE in statuses:
            status = "not available"
        else:
            status = "/".join(sorted(statuses))
        m = [t.metrics for t in ok]
        costs = np.array([x["cost"] for x in m], float)
        act_all = (np.concatenate([t.arrays["act_time"] for t in ok]) if ok
                   else np.zeros(0))
        replans = [t.arrays["diag_replanned"].astype(bool) for t in ok
                   if "diag_replanned" in t.arrays]
        solve = (np.concatenate([t.arrays["diag_solve_time"][k] for t, k in zip(ok, replans,
                                                                                strict=False)])
                 if replans and len(replans) == len(ok) else np.zeros(0))
        outside = (np.concatenate([t.arrays["diag_act_time"][k] - t.arrays["diag_solve_time"][k]
                                   for t, k in zip(ok, replans, strict=False)])
                   if solve.size else np.zeros(0))
        # the split RTI's latency: act time minus the preparation done after the action
        latency, preparation = (
            (np.concatenate([(t.arrays["diag_act_time"] - t.arrays["diag_preparation_time"])[k]
                             for t, k in zip(ok, replans, strict=False)]),
             np.concatenate([t.arrays["diag_preparation_time"][k]
                             for t, k in zip(ok, replans, strict=False)]))
            if solve.size and all("diag_preparation_time" in t.arrays for t in ok)
            else (np.zeros(0), np.zeros(0)))
        # the same latency over the accepted RTI steps only: the QP's own cost, without the
        # converged solves that replace rejected steps
        accepted = (np.concatenate([t.arrays["diag_status"][k] == "RTI"
                                    for t, k in zip(ok, replans, strict=False)])
                    if latency.size and all("diag_status" in t.arrays for t in ok)
                    else np.zeros(0, bool))
        n_success = int(sum(bool(x["success"]) for x in m))
        success_ci = wilson_ci(n_success, len(m))
        cost_ci = mean_ci(costs)
        returns = [x.get("return", math.nan) for x in m]
        interaction = [x.get("interaction_s", math.nan) for x in m]
        multi = [x for x in m if "trials" in x]
        n_trials_success = int(sum(np.isfinite(x["trials_to_success"]) for x in multi))
        trials_ci = wilson_ci(n_trials_success, len(multi))
        interaction_trials = [x["interaction_trials_s"] for x in multi]
        rows.append({
            "experiment": experiment, "env": env, "scenario": scenario,
            "cell": cell.describe(), "n_init": n_init, "controller": controller,
            "label": _label(controller), "status": status,
            "episodes": len(ok),
            "success_rate": _mean([float(x["success"]) for x in m]),
            "success_ci_low": success_ci[0], "success_ci_high": success_ci[1],
            "cost_ci_low": cost_ci[0], "cost_ci_high": cost_ci[1],
            "success_held_rate": _mean([float(x.get("success_held", x["success"])) for x in m]),
            "plan_plant_defect_max": max([x.get("plan_plant_defect", math.nan) for x in m],
                                         default=math.nan),
            "cost_mean": _mean(costs), "cost_std": float(costs.std()) if costs.size else math.nan,
            # the env's own return (an outside env's reward is its own, not minus the cost)
            "return_mean": _mean(returns), "return_ci_low": mean_ci(returns)[0],
            "return_ci_high": mean_ci(returns)[1],
            "residual_off_steps_mean": _mean([x.get("residual_off_steps", math.nan)
                                              for x in m]),
            "cost_median": float(np.median(costs)) if costs.size else math.nan,
            "time_to_success_mean_s": _mean([x["time_to_success_s"] for x in m]),
            # over the episodes that succeeded (NaN for the others)
            "interaction_mean_s": _mean(interaction),
            "interaction_ci_low": mean_ci(interaction)[0],
            "interaction_ci_high": mean_ci(interaction)[1],
            "trials_success_rate": (n_trials_success / len(multi)) if multi else math.nan,
            "trials_success_ci_low": trials_ci[0], "trials_success_ci_high": trials_ci[1],
            "trials_to_success_mean": _mean([x["trials_to_success"] for x in multi]),
            "interaction_trials_mean_s": _mean(interaction_trials),
            "interaction_trials_ci_low": mean_ci(interaction_trials)[0],
            "interaction_trials_ci_high": mean_ci(interaction_trials)[1],
            "final_distance_mean": _mean([x["final_distance"] for x in m]),
            "final_position_error_mean": _mean([x["final_position_error"] for x in m]),
            "final_position_error_max": _max_finite(x["final_position_error"] for x in m),
            "recovery_max_s": _max_finite(x.get("recovery_s", math.nan) for x in m),
            "recovered": int(sum(np.isfinite(x.get("recovery_s", math.nan)) for x in m)),
            "violations_total": int(sum(x["violations"] for x in m)),
            "episodes_with_violation": int(sum(x["violations"] > 0 for x in m)),
            "data_steps_mean": _mean([x["data_steps"] for x in m]),
            "act_median_ms": 1e3 * float(np.median(act_all)) if act_all.size else math.nan,
            "act_p95_ms": 1e3 * float(np.percentile(act_all, 95)) if act_all.size else math.nan,
            "act_max_ms": 1e3 * float(act_all.max()) if act_all.size else math.nan,
            "solve_median_ms": 1e3 * float(np.median(solve)) if solve.size else math.nan,
            "outside_median_ms": 1e3 * float(np.median(outside)) if outside.size else math.nan,
            "latency_median_ms": (1e3 * float(np.median(latency)) if latency.size
                                  else math.nan),
            "preparation_median_ms": (1e3 * float(np.median(preparation)) if preparation.size
                                      else math.nan),
            "accepted_latency_median_ms": (1e3 * float(np.median(latency[accepted]))
                                           if accepted.any() else math.nan),
            "solver_failures": (int(sum(x["solver_failures"] for x in m))
                                if m and m[0]["family"] == "mpc" else math.nan),
            "fallbacks": (int(sum(x["fallbacks"] for x in m))
                          if m and m[0]["family"] == "mpc" else math.nan),
            **_rti_counts(m),
        })
    return rows


def _rti_counts(m: list[dict[str, Any]]) -> dict[str, Any]:
    """A cell's real-time-iteration paths summed over its episodes: steps taken, recovered
    by further SQP iterations, rejected (replaced by a converged solve) and the rejected
    fraction of the steps (NaN without RTI steps, or for records from before these counts)."""
    keys = ("rti_steps", "rti_recovered", "rti_rejected")
    if not m or any(not _finite_number(x.get(k)) for x in m for k in keys):
        return {**dict.fromkeys(keys, math.nan), "rti_rejected_fraction": math.nan}
    out = {k: int(sum(int(x[k]) for x in m)) for k in keys}
    out["rti_rejected_fraction"] = (out["rti_rejected"] / out["rti_steps"] if out["rti_steps"]
                                    else math.nan)
    return out


def _rti_paths_table(rows: list[dict[str, Any]]) -> list[str]:
    """The real-time iterations' paths per cell (rows with RTI steps only; none: no lines)."""
    rti = [r for r in rows if _finite_number(r.get("rti_steps")) and r["rti_steps"] > 0]
    if not rti:
        return []
    body = [[f"{r['env']} `{r['scenario']}`, {r['cell']}", r["label"], r["episodes"],
             r["rti_steps"], r["rti_recovered"], r["rti_rejected"],
             f"{100 * r['rti_rejected_fraction']:.1f}%"] for r in rti]
    return ["", "Real-time iteration paths per cell (summed over the episodes): RTI steps taken, "
            "steps *recovered* by further SQP iterations within the iteration budget "
            "(`RTI.recovery_iterations`), steps *rejected* (replaced by a converged solve):",
            "", *markdown_table(["cell", "controller", "episodes", "RTI steps", "recovered",
                                 "rejected", "rejected %"], body,
                                ["---", "---"] + ["---:"] * 5)]


def _finite_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and math.isfinite(value)


# ----------------------------------------------------------------------------- sections
@dataclass
class Context:
    """What a report section sees."""

    out_dir: Path
    trials: dict[TrialSpec, Trial]
    summaries: dict[str, list[dict[str, Any]]]
    compute_rows: list[dict[str, Any]]
    peer_rows: list[dict[str, Any]]

    def of(self, experiment: Experiment) -> list[Trial]:
        """The experiment's trials."""
        return [self.trials[s] for s in experiment.specs]


SectionFn = Callable[[Context, Experiment], list[str]]


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
            f"{r['env']} `{r['scenario']}`{cell}", r["label"], r["episodes"],
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
                label = CONTROLLERS[f"{base}-mpc"].label.replace(" MPC", "")
                body.append([env, label, *cells])
        lines += markdown_table(
            ["env", "model", "episodic cost", "episodic success (final / held)",
             "episodic final distance", "MPC cost", "MPC success", "MPC final distance"],
            body, ["---", "---", "---:", "---:", "---:", "---:", "---:", "---:"])
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


def _first_ok(trials: Sequence[Trial]) -> Trial | None:
    ok = sorted((t for t in trials if t.ok), key=lambda t: t.spec.seed)
    return ok[0] if ok else None


def trajectories_figure(env: str, scenario: str, chosen: dict[str, Trial]) -> Any:
    """States and controls against time, one line per controller (one trial each), each panel
    labelled with its unit; the goal of every weighted state dotted."""
    model = _env_model(env, scenario)
    system = _system(env)
    names = [*model.state_names, *model.control_names]
    n, ncols = len(names), 4 if len(names) > 9 else 3
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 2.6 * nrows), squeeze=False)
    seeds = sorted({t.spec.seed for t in chosen.values()})
    for c, t in chosen.items():
        obs, act = t.arrays["obs"], t.arrays["action"]
        t_obs = np.arange(len(obs)) * model.dt
        st = _style(c)
        for i in range(n):
            ax = axes.flat[i]
            if i < model.n_states:
                ax.plot(t_obs, obs[:, i], label=_label(c), **st.line(len(t_obs)))
            else:
                ax.step(t_obs[:-1], act[:, i - model.n_states], where="post", label=_label(c),
                        **st.line(len(t_obs) - 1))
    goal = model.task.goal
    for i, name in enumerate(names):
        ax = axes.flat[i]
        ax.set_ylabel(axis_label(system, name), fontsize=9)
        ax.grid(alpha=0.3)
        if i < model.n_states and model.task.Q[i, i] > 0:
            ax.axhline(goal[i], color="0.45", lw=0.8, ls=":", zorder=1)
        if i >= n - ncols:
            ax.set_xlabel("time (s)")
    spare = list(axes.flat)[n:]
    for ax in spare:
        ax.axis("off")
    if spare:  # the legend in an empty panel, where it hides no line
        handles, labels = axes.flat[0].get_legend_handles_labels()
        spare[0].legend(handles, labels, loc="center", fontsize=8,
                        ncols=1 if len(labels) <= 8 else 2)
    else:
        axes.flat[0].legend(fontsize=7)
    seed_text = f"seed {seeds[0]}" if len(seeds) == 1 else f"lowest seed each ({seeds})"
    fig.suptitle(f"{_env_title(env, scenario)}: states and controls, {seed_text}"
                 f"{_notes(_scheme_notes(chosen))}", fontsize=10)
    fig.tight_layout()
    return fig


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
        name = _save(fig, ctx.out_dir, f"{exp.name}_trajectories_{env}_{scenario}.png")
        lines += ["", f"![{env} {scenario} trajectories]({name})"]
    return lines


def paths_figure(env: str, scenario: str, groups: dict[str, list[Trial]]) -> Any:
    """Paths in the plane of the first two states of every episode, one panel per controller,
    with the task's obstacles (and obstacle + body radius, dashed), each episode's start, the
    goal, and the points in contact with an obstacle."""
    model = _env_model(env, scenario)
    task, system = model.task, _system(env)
    goal = np.asarray(task.goal, float)[:2]
    points = [goal[None, :]]
    for ob in task.obstacles:
        reach = ob.radius + task.body_radius
        points.append(np.asarray(ob.center, float) + np.array([[-reach, -reach], [reach, reach]]))
    points += [t.arrays["obs"][:, :2] for ts in groups.values() for t in ts]
    allp = np.concatenate(points)
    finite = allp[np.all(np.isfinite(allp), axis=1)]
    low, high = finite.min(axis=0), finite.max(axis=0)
    pad = 0.08 * float(np.max(high - low)) + 0.1
    fig, axes = plt.subplots(1, len(groups), figsize=(4.3 * len(groups), 4.5), squeeze=False,
                             sharex=True, sharey=True)
    for ax, (c, ts) in zip(axes.flat, groups.items(), strict=True):
        for ob in task.obstacles:
            ax.add_patch(plt.Circle(ob.center, ob.radius, color="0.75", zorder=1))
            ax.add_patch(plt.Circle(ob.center, ob.radius + task.body_radius, fill=False,
                                    ls="--", color="0.4", lw=0.8, zorder=1))
        st = _style(c)
        n_viol = n_goal = 0
        for t in ts:
            xy = t.arrays["obs"][:, :2]
            n_viol += t.metrics["violations"] > 0
            n_goal += bool(t.metrics["success"])
            ax.plot(xy[:, 0], xy[:, 1], color=st.color, ls=st.linestyle, lw=1.0, alpha=0.75,
                    zorder=3)
            ax.plot(*xy[0], "o", color="0.2", ms=4, zorder=4)
            contact = np.zeros(len(xy), bool)
            for ob in task.obstacles:
                contact |= ob.clearance(xy, task.body_radius) < 0
            if contact.any():
                ax.plot(xy[contact, 0], xy[contact, 1], "x", color="tab:red", ms=7, mew=1.8,
                        zorder=5)
        ax.plot(*goal, "*", color="tab:green", ms=13, zorder=4)
        ax.set_aspect("equal")
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_xlabel(axis_label(system, model.state_names[0]))
        ax.grid(alpha=0.3)
        ax.set_title(f"{_label(c)}: {len(ts)} episodes\n{n_goal} reached the goal, "
                     f"{n_viol} touched an obstacle", fontsize=9, color=st.color)
    axes.flat[0].set_ylabel(axis_label(system, model.state_names[1]))
    fig.suptitle(f"{_env_title(env, scenario)}: paths"
                 + _notes("dot: start, star: goal, red x: obstacle contact",
                          "dashed circle: obstacle + body radius",
                          [n.replace("dashed", "dashed path") for n in _scheme_notes(groups)]),
                 fontsize=10)
    fig.tight_layout()
    return fig


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
        name = _save(fig, ctx.out_dir, f"{exp.name}_{env}_{scenario}_paths.png" if several
                     else f"{exp.name}_{env}_paths.png")
        lines += ["", f"![{env} {scenario} paths]({name})"]
    return lines


def _style_boxes(parts: dict[str, Any], controllers: Sequence[str]) -> None:
    """Colour each box of an ``Axes.boxplot(..., patch_artist=True)`` as its controller."""
    for i, c in enumerate(controllers):
        st = _style(c)
        box = parts["boxes"][i]
        box.set(facecolor=matplotlib.colors.to_rgba(st.color, 0.25), edgecolor=st.color,
                linestyle=st.linestyle, linewidth=1.4, label=_label(c))
        for key in ("whiskers", "caps"):
            for artist in parts[key][2 * i: 2 * i + 2]:
                artist.set(color=st.color)
        parts["medians"][i].set(color="k", linewidth=1.6)
        if parts["fliers"]:
            parts["fliers"][i].set(markeredgecolor=st.color, marker=st.marker)


def step_times_figure(groups: dict[str, dict[str, list[np.ndarray]]], scenarios: dict[str, str]
                      ) -> Any:
    """Box plots of the per-step ``act`` times, one panel per env (``groups[env][controller]``
    are the trials' ``act_time`` arrays in seconds), each with the env's control period."""
    fig, axes = plt.subplots(1, len(groups), figsize=(5.2 * len(groups), 4.4), squeeze=False)
    for ax, (env, per) in zip(axes.flat, groups.items(), strict=True):
        names = list(per)
        data = [1e3 * np.concatenate(per[c]) for c in names]
        parts = ax.boxplot(data, whis=(5, 95), showfliers=True, patch_artist=True,
                           flierprops={"markersize": 2})
        _style_boxes(parts, names)
        period = _control_period_line(ax, _env_model(env, scenarios[env]).dt)
        ax.set_xticks(range(1, len(names) + 1), [_label(c) for c in names], rotation=60,
                      ha="right", fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel("act() time per step (ms)")
        ax.set_title(ENVS[env].env_id or env, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
        ax.legend(handles=[period], fontsize=7, loc="best")
    controllers = {c for per in groups.values() for c in per}
    fig.suptitle("Per-step compute" + _notes("whiskers 5-95%",
                                             "above the control period: not real-time",
                                             [n.replace("dashed", "dashed box").replace(
                                                 "dash-dot", "dash-dot box")
                                              for n in _scheme_notes(controllers)]),
                 fontsize=10)
    fig.tight_layout()
    return fig


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
            rows.append([env, _label(c), len(d), float(np.median(d)),
                         float(np.percentile(d, 95)), float(d.max())])
    name = _save(fig, ctx.out_dir, f"{exp.name}_step_times.png")
    lines = ["", f"![step times]({name})", ""]
    lines += markdown_table(["env", "controller", "steps", "median (ms)", "p95 (ms)", "max (ms)"],
                            rows, ["---", "---", "---:", "---:", "---:", "---:"])
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
                          label=f"{algo.upper()} learning curve (training evals)")
                ax_r.plot(steps, [p["mean_return"] for p in curve], **curve_style,
                          label=f"{algo.upper()} learning curve (training evals)")
        for r in rows:
            if not r["episodes"]:
                table.append([r["label"], "", "", "", "", r["status"]])
                continue
            point = _style(r["controller"]).point()
            interaction = r.get("interaction_mean_s", math.nan)
            before = (interaction / dt if r["controller"] not in RL_ALGORITHMS
                      and math.isfinite(interaction) else math.nan)
            x = before if math.isfinite(before) else r["data_steps_mean"]
            ax_s.plot([x], [r["success_rate"]], label=r["label"], **point)
            ax_r.plot([x], [-r["cost_mean"]], label=r["label"], **point)
            table.append([r["label"], _fmt(before, 0), _fmt(r["data_steps_mean"], 0),
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
        name = _save(fig, ctx.out_dir, f"{exp.name}_sample_efficiency_{env}_{scenario}.png")
        lines += ["", f"![{env} sample efficiency]({name})", ""]
        lines += markdown_table(["controller", "env steps of interaction before success",
                                 "env steps of data used", "success rate", "mean return",
                                 "evaluated"], table,
                                ["---", "---:", "---:", "---:", "---:", "---"])
    return lines


def compute_rows(trials: Iterable[Trial]) -> list[dict[str, Any]]:
    """Rows of ``compute.csv``: the scaling and update-time measurements."""
    rows = []
    for t in trials:
        if t.spec.kind in ("ssgp-act-scaling", "ssgp-update-time", *STEP_SCALING) and t.ok:
            rows.append({"key": t.spec.key, "measurement": t.spec.kind, "env": t.spec.env,
                         "scenario": t.spec.scenario, "controller": t.spec.controller,
                         "seed": t.spec.seed, "param": t.spec.param, **t.metrics})
    return rows


def scaling_figure(groups: Sequence[tuple[str, str, str]],
                   trials: dict[tuple[str, str, str], list[Trial]]) -> Any:
    """Box plots of the ``act`` times against the samples learned, one panel per (env,
    scenario, controller), each with the env's control period."""
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 3.8), squeeze=False)
    for ax, group in zip(axes.flat, groups, strict=True):
        env, scenario, controller = group
        st = _style(controller)
        params = []
        for t in trials[group]:
            if t.ok:
                params.append(t.spec.param)
                parts = ax.boxplot([1e3 * t.arrays["act_time"]], positions=[t.spec.param],
                                   widths=[0.25 * t.spec.param], whis=(5, 95),
                                   showfliers=False, patch_artist=True)
                _style_boxes(parts, [controller])
        period = _control_period_line(ax, _env_model(env, scenario).dt)
        ax.set_xscale("log")
        ax.set_xticks(params, [str(p) for p in params])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("samples learned before the episode")
        ax.set_ylabel("act() time per step (ms)")
        ax.set_title(f"{_label(controller)}, {env} `{scenario}`", fontsize=9, color=st.color)
        ax.grid(alpha=0.3)
        ax.legend(handles=[period], fontsize=7, loc="best")
    fig.suptitle("Per-step compute against the samples learned (whiskers 5-95%)", fontsize=10)
    fig.tight_layout()
    return fig


def section_scaling(ctx: Context, exp: Experiment) -> list[str]:
    """SSGP-MPC step time against the number of samples learned."""
    keys = {s.key for s in exp.specs}
    rows = [r for r in ctx.compute_rows if r["measurement"] == "ssgp-act-scaling"
            and _row_key(r) in keys]
    if not rows:
        return []
    rows.sort(key=lambda r: (r["env"], r.get("controller", "ssgp-mpc"), r["param"]))
    groups = list(dict.fromkeys((r["env"], r["scenario"], r.get("controller", "ssgp-mpc"))
                                for r in rows))
    fig = scaling_figure(groups, {g: [ctx.trials[s] for s in exp.specs
                                      if s.kind == "ssgp-act-scaling"
                                      and (s.env, s.scenario, s.controller) == g]
                                  for g in groups})
    name = _save(fig, ctx.out_dir, f"{exp.name}_ssgp_act_scaling.png")
    lines = ["", "SSGP-MPC recipes (r = 50), seed 0, after learning N samples:",
             "", f"![act time vs samples]({name})", ""]
    lines += markdown_table(
        ["env", "scenario", "controller", "samples learned", "act median (ms)", "p95 (ms)",
         "max (ms)", "batch update (s)", "success", "cost"],
        [[r["env"], r["scenario"], _label(r.get("controller", "ssgp-mpc")), r["param"],
          r["act_median_ms"], r["act_p95_ms"], r["act_max_ms"], r["batch_update_s"],
          r["success"], r["cost"]] for r in rows], ["---"] * 3 + ["---:"] * 7)
    return lines


def step_scaling_figure(rows: Sequence[dict[str, Any]]) -> Any:
    """Median step time against each scaled setting (one column per kind of
    :data:`benchmarks.compute.STEP_SCALING`, one row per env), one line per recipe."""
    kinds = [k for k in STEP_SCALING if any(r["measurement"] == k for r in rows)]
    envs = list(dict.fromkeys((r["env"], r["scenario"]) for r in rows))
    fig, axes = plt.subplots(len(envs), len(kinds), figsize=(4.2 * len(kinds), 3.3 * len(envs)),
                             squeeze=False)
    for i, (env, scenario) in enumerate(envs):
        for j, kind in enumerate(kinds):
            ax = axes[i, j]
            mine = [r for r in rows if (r["env"], r["scenario"], r["measurement"])
                    == (env, scenario, kind)]
            for c in dict.fromkeys(r["controller"] for r in mine):
                pts = sorted((r["param"], r["act_median_ms"]) for r in mine
                             if r["controller"] == c)
                ax.plot(*zip(*pts, strict=True), **_style(c).line(len(pts), len(pts)),
                        label=_label(c))
            _control_period_line(ax, _env_model(env, scenario).dt)
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.yaxis.set_minor_formatter(NullFormatter())
            ax.set_xticks(sorted({r["param"] for r in mine}))
            ax.set_xlabel(STEP_SCALING[kind])
            ax.set_ylabel("act median (ms)")
            ax.set_title(f"{env} `{scenario}`", fontsize=9)
            ax.grid(alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=7)
    fig.suptitle("Step time against one setting at a time (seed 0, medians)", fontsize=10)
    fig.tight_layout()
    return fig


def section_step_scaling(ctx: Context, exp: Experiment) -> list[str]:
    """The converged and RTI step time against LG nodes, horizon and rank r."""
    keys = {s.key for s in exp.specs}
    rows = [r for r in ctx.compute_rows if r["measurement"] in STEP_SCALING
            and _row_key(r) in keys]
    if not rows:
        return []
    name = _save(step_scaling_figure(rows), ctx.out_dir, f"{exp.name}_step_scaling.png")
    steps = max(int(r["steps"]) for r in rows)
    lines = ["", "Median `act` time (ms) with one setting changed from the recipe's default, "
             f"seed 0, {steps} periods (the first `act`, which builds the NLP, left out); "
             "`(k rej.)`: k of the RTI's steps were rejected by its safety net and replaced by a "
             "converged solve (where that is most of them, the median is a converged step's); "
             "`*`: the episode had solver failures:", "", f"![step time scaling]({name})"]
    for kind, what in STEP_SCALING.items():
        mine = [r for r in rows if r["measurement"] == kind]
        if not mine:
            continue
        values = sorted({int(r["param"]) for r in mine})
        groups = list(dict.fromkeys((r["env"], r["scenario"], r["controller"]) for r in mine))
        by = {(r["env"], r["scenario"], r["controller"], int(r["param"])): r for r in mine}

        def cell(r: dict[str, Any] | None) -> str:
            if r is None:
                return "n/a"
            text = _fmt(r["act_median_ms"], 2) + ("*" if r["solver_failures"] else "")
            return text + (f" ({r['rti_rejected']} rej.)" if r["rti_rejected"] else "")

        lines += ["", f"Against the {what}:", ""]
        lines += markdown_table(
            ["env", "controller", *[str(v) for v in values]],
            [[f"{e} `{sc}`", _label(c), *[cell(by.get((e, sc, c, v))) for v in values]]
             for e, sc, c in groups], ["---", "---"] + ["---:"] * len(values))
    return lines


def _row_key(row: dict[str, Any]) -> str:
    return str(row["key"])


def update_time_figure(rows: Sequence[dict[str, Any]]) -> Any:
    """Median and p95 single-sample update time against the rank r (rows of
    :func:`compute_rows`, measurement ``ssgp-update-time``); ticks at the ranks measured."""
    ranks = [int(r["r"]) for r in rows]
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    color = _style("ssgp-mpc").color
    ax.plot(ranks, [r["update_median_ms"] for r in rows], "o-", color=color, label="median")
    ax.plot(ranks, [r["update_p95_ms"] for r in rows], "s--", color=color, mfc="none",
            label="p95")
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(FixedLocator(ranks))
    ax.xaxis.set_major_formatter(FixedFormatter([str(r) for r in ranks]))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_yscale("log")
    ax.set_xlabel("rank r (frequencies, count; 2r features per output)")
    ax.set_ylabel("update time per sample (ms)")
    envs = sorted({str(r["env"]) for r in rows})
    ax.set_title(f"IncrementalSSGP.update, one sample at a time ({', '.join(envs)})",
                 fontsize=9)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def section_update_time(ctx: Context, exp: Experiment) -> list[str]:
    """SSGP single-sample update time against the rank r."""
    keys = {s.key for s in exp.specs}
    rows = sorted((r for r in ctx.compute_rows if r["measurement"] == "ssgp-update-time"
                   and _row_key(r) in keys), key=lambda r: r["param"])
    if not rows:
        return []
    fig = update_time_figure(rows)
    name = _save(fig, ctx.out_dir, f"{exp.name}_ssgp_update_time.png")
    lines = ["", f"IncrementalSSGP.update on single samples ({rows[0]['updates']} timed updates "
             f"after a fit on the initial data; {rows[0]['n_outputs']} outputs, "
             f"{', '.join(sorted({str(r['env']) for r in rows}))}):", "",
             f"![update time vs r]({name})", ""]
    lines += markdown_table(["r", "median (ms)", "p95 (ms)", "max (ms)", "fit (s)"],
                            [[r["r"], r["update_median_ms"], r["update_p95_ms"],
                              r["update_max_ms"], r["fit_s"]] for r in rows], ["---:"] * 5)
    return lines


def peer_rows(trials: Iterable[Trial]) -> list[dict[str, Any]]:
    """Rows of ``peers.csv``: one per seed."""
    return [{"env": t.spec.env, "scenario": t.spec.scenario, "seed": t.spec.seed, **t.metrics}
            for t in trials if t.spec.kind == "peers" and t.ok]


def section_peers(ctx: Context, exp: Experiment) -> list[str]:
    """Pseudospectral MPC vs do-mpc: step times, their ratio, closed-loop costs, verdict."""
    trials = [t for t in ctx.of(exp) if t.spec.kind == "peers"]
    if not trials:
        return []
    rows = [r for r in ctx.peer_rows if any(t.ok and t.spec.seed == r["seed"] and
                                            t.spec.env == r["env"] for t in trials)]
    if not rows:
        reasons = {t.record["message"] for t in trials if t.record and not t.ok}
        return ["", "No peer comparison available: " + ("; ".join(sorted(reasons)) or
                                                       "not run yet") + "."]
    first = rows[0]
    lines = ["", f"Horizon {first['horizon_s']} s. This project: {first['ps_nodes']} "
             f"({first['ps_nlp_variables']} NLP variables); do-mpc {first['dompc_version']}: "
             f"{first['dompc_discretization']} ({first['dompc_nlp_variables']} NLP variables).",
             ""]
    has_rti = all("rti_cost" in r for r in rows)
    body = [[r["seed"], r["ps_act_median_ms"], r["dompc_act_median_ms"], r["time_ratio"],
             r["ps_solve_median_ms"], r["dompc_solve_median_ms"], r["ps_cost"], r["dompc_cost"],
             f"{_fmt(r['ps_success'])} / {_fmt(r['dompc_success'])}"]
            + ([r["rti_act_median_ms"], r["rti_time_ratio"], r["rti_cost"],
                _fmt(r["rti_success"])] if has_rti else []) for r in rows]
    head = ["seed", "ours act median (ms)", "do-mpc act median (ms)", "ratio", "ours IPOPT (ms)",
            "do-mpc IPOPT (ms)", "ours cost", "do-mpc cost", "success ours / do-mpc"]
    if has_rti:
        head += ["RTI act median (ms)", "RTI ratio", "RTI cost", "RTI success"]
    lines += markdown_table(head, body, ["---:"] * 8 + ["---"]
                            + (["---:"] * 3 + ["---"] if has_rti else []))
    ps_all = np.concatenate([t.arrays["ps_act_time"] for t in trials if t.ok])
    do_all = np.concatenate([t.arrays["dompc_act_time"] for t in trials if t.ok])
    ratio = float(np.median(ps_all) / np.median(do_all))
    cost_ok = all(r["ps_cost"] <= r["dompc_cost"] * (1 + 5e-3) for r in rows)
    met = ratio <= 0.5 and cost_ok
    lines += ["", f"Over all {len(ps_all)} steps: median step time ours "
              f"{1e3 * np.median(ps_all):.2f} ms vs do-mpc {1e3 * np.median(do_all):.2f} ms, "
              f"ratio **{ratio:.2f}**; closed-loop cost ours "
              f"{'<=' if cost_ok else 'NOT <='} do-mpc's in every seed.",
              "Target (ratio <= 0.5, cost at most do-mpc's within 0.5% on every seed): "
              f"**{'met' if met else 'not met'}**."]
    if has_rti:
        rti_all = np.concatenate([t.arrays["rti_act_time"] for t in trials if t.ok])
        rti_ratio = float(np.median(rti_all) / np.median(do_all))
        rti_cost = all(abs(r["rti_cost"] - r["dompc_cost"]) <= 0.02 * r["dompc_cost"]
                       or r["rti_cost"] <= r["dompc_cost"] for r in rows)
        lines += ["", f"Real-time iteration (`scheme=\"rti\"`, same OCP): median step "
                  f"{1e3 * np.median(rti_all):.2f} ms, ratio to do-mpc **{rti_ratio:.2f}**; "
                  f"cost {'within 2% of (or below)' if rti_cost else 'NOT within 2% of'} "
                  "do-mpc's in every seed. Target (ratio <= 0.1, cost within 2%): "
                  f"**{'met' if rti_ratio <= 0.1 and rti_cost else 'not met'}**."]
    return lines


SPEED_TARGET = 1.5
"""The MPC issue's speed target: an SSGP recipe's median act time at most this many times the
nominal MPC's (an RTI recipe's: the nominal RTI's), measured in the same run."""
RTI_TARGET = 0.15
"""The RTI issue's target: the nominal (and oracle) RTI step at most this many times the
converged one's, measured in the same run."""


def section_acceptance(ctx: Context, exp: Experiment) -> list[str]:
    """Headline numbers of the MPC issue's acceptance runs, for every MPC recipe in them."""
    by = {(r["env"], r["scenario"], r["controller"]): r for r in ctx.summaries[exp.name]}
    order = list(dict.fromkeys(s.controller for s in exp.specs if s.kind in EPISODE_KINDS))
    lines = [""]

    def get(env: str, scenario: str, c: str) -> dict[str, Any] | None:
        r = by.get((env, scenario, c))
        return r if r and r["episodes"] else None

    rejected: dict[tuple[str, str, str], list[int]] = defaultdict(lambda: [0, 0])
    for t in ctx.of(exp):  # the RTI safety net's rejections, from the per-step statuses
        if t.spec.kind in EPISODE_KINDS and t.ok and "diag_status" in t.arrays:
            status = [str(v) for v in t.arrays["diag_status"]]
            count = rejected[(t.spec.env, t.spec.scenario, t.spec.controller)]
            count[0] += sum(v.startswith("RTI rejected") for v in status)
            count[1] += sum(v == "RTI" or v.startswith("RTI rejected") for v in status)

    def speed(env: str, scenario: str, c: str, r: dict[str, Any]) -> str:
        text = (f"act median {_fmt(r['act_median_ms'], 2)} ms (solver "
                f"{_fmt(r['solve_median_ms'], 2)} ms, the rest {_fmt(r['outside_median_ms'], 2)} "
                "ms, medians over the replanning steps)")
        if c.endswith("-split"):
            return text + _split_speed(env, scenario, c, r, get, rejected)
        rti = "-rti" in c
        reference, target = ("nominal-mpc-rti", SPEED_TARGET) if rti else ("nominal-mpc",
                                                                           SPEED_TARGET)
        if rti and c.startswith(("nominal", "oracle")):  # against its converged references
            base = c[: -len("-rti")]
            refs = [(base, f"the converged {_label(base)}'s"),
                    (f"{base}-warm-duals", "with warm duals")]
            parts = []
            for ref, name in refs:
                conv = get(env, scenario, ref)
                if conv and conv["act_median_ms"] > 0:
                    ratio = r["act_median_ms"] / conv["act_median_ms"]
                    verdict = "met" if ratio <= RTI_TARGET else "not met"
                    parts.append(f"**{ratio:.2f}x** {name} (target {RTI_TARGET}x: {verdict})")
            if parts:
                text += " = " + ", ".join(parts)
        nominal = get(env, scenario, reference)
        if c.startswith("ssgp") and nominal and nominal["act_median_ms"] > 0:  # act vs act
            ratio = r["act_median_ms"] / nominal["act_median_ms"]
            verdict = "met" if ratio <= target else "not met"
            text += (f" = **{ratio:.2f}x** the {_label(reference)}'s (target {target}x: "
                     f"{verdict})")
        n_rej, n_rti = rejected.get((env, scenario, c), (0, 0))
        if rti and n_rti:
            text += f"; {n_rej} of {n_rti} RTI steps rejected ({100 * n_rej / n_rti:.0f}%)"
        return text

    for c in order:
        r = get("cartpole", "online", c)
        if r:
            lines.append(f"- cart pole `online`, {_label(c)}: success "
                         f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, mean "
                         f"cost {_fmt(r['cost_mean'])}, {speed('cartpole', 'online', c, r)}")
    for scenario in ("gp", "online"):
        for c in order:
            r = get("quadrotor", scenario, c)
            if r:
                lines.append(f"- quadrotor `{scenario}`, {_label(c)}: final position error mean "
                             f"{_fmt(r['final_position_error_mean'], 4)} m (max "
                             f"{_fmt(r['final_position_error_max'], 4)} m), success "
                             f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, "
                             f"{speed('quadrotor', scenario, c, r)}")
    for c in order:
        r = get("dubins", "paper", c)
        if r:
            lines.append(f"- Dubins, {_label(c)}: goal reached "
                         f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, "
                         f"episodes touching the obstacle {r['episodes_with_violation']}, "
                         f"{speed('dubins', 'paper', c, r)}")
    return lines + _linearization_errors(ctx, exp)


def _split_speed(env: str, scenario: str, c: str, r: dict[str, Any],
                 get: Callable[[str, str, str], dict[str, Any] | None],
                 rejected: Mapping[tuple[str, str, str], Sequence[int]]) -> str:
    """The split RTI's latency (``act`` minus the preparation after the action) and its
    ratios: a nominal or oracle one against its converged MPC's act median, an SSGP one against
    the nominal split RTI's latency, the nominal one-call RTI's act median and, where it ran
    (the cart pole, whose nominal RTI steps are all rejected), the oracle split RTI's latency:
    the same OCP with the true model, whose RTI steps are accepted."""
    text = (f"; latency median **{_fmt(r['latency_median_ms'], 2)} ms**, preparation "
            f"{_fmt(r['preparation_median_ms'], 2)} ms")
    refs = ([("nominal-mpc-rti-split", "latency_median_ms", "latency"),
             ("nominal-mpc-rti", "act_median_ms", "act median"),
             ("oracle-mpc-rti-split", "latency_median_ms", "latency")] if c.startswith("ssgp")
            else [(c.removesuffix("-rti-split"), "act_median_ms", "act median")])
    target = SPEED_TARGET if c.startswith("ssgp") else RTI_TARGET
    for ref, key, what in refs:
        other = get(env, scenario, ref)
        if other and other[key] > 0 and r["latency_median_ms"] > 0:
            ratio = r["latency_median_ms"] / other[key]
            text += (f"; **{ratio:.2f}x** the {_label(ref)}'s {what} (target {target}x: "
                     f"{'met' if ratio <= target else 'not met'})")
    n_rej, n_rti = rejected.get((env, scenario, c), (0, 0))
    if n_rti:
        text += f"; {n_rej} of {n_rti} RTI steps rejected ({100 * n_rej / n_rti:.0f}%)"
    accepted = r.get("accepted_latency_median_ms", math.nan)
    if np.isfinite(accepted):
        text += f"; latency median over the accepted RTI steps {_fmt(accepted, 2)} ms"
        other = get(env, scenario, "nominal-mpc-rti-split") if c.startswith("ssgp") else None
        if other and np.isfinite(other.get("accepted_latency_median_ms", math.nan)):
            text += f" ({accepted / other['accepted_latency_median_ms']:.2f}x the nominal's)"
    return text


def _linearization_errors(ctx: Context, exp: Experiment) -> list[str]:
    """How far the linearized recipes' per-node expansions were off at their plans."""
    groups: dict[tuple[str, str, str], list[np.ndarray]] = defaultdict(list)
    for t in ctx.of(exp):
        if (t.spec.kind not in EPISODE_KINDS or not t.ok
                or "diag_linearization_error" not in t.arrays):
            continue
        recipe = CONTROLLERS.get(t.spec.controller)
        if recipe is None or learned_term(recipe, t.spec.env) not in (
                "linearized", "linearized-pattern"):
            continue
        err = t.arrays["diag_linearization_error"][t.arrays["diag_replanned"].astype(bool)]
        groups[(t.spec.env, t.spec.scenario, t.spec.controller)].append(err)
    if not groups:
        return []
    rows = []
    for (env, scenario, c), errs in groups.items():
        e = np.concatenate(errs)
        e = e[np.isfinite(e)]  # NaN: a solve that gave no finite plan to check
        if not e.size:
            continue
        rows.append([f"{env} `{scenario}`", _label(c), e.size, float(np.median(e)),
                     float(np.percentile(e, 90)), float(np.mean(e > 1.0))])
    if not rows:
        return []
    table = markdown_table(["env", "controller", "solves", "median", "p90", "share > 1"], rows,
                           ["---", "---", "---:", "---:", "---:", "---:"])
    return ["", "Linearized recipes: error of the per-node expansion at the plan it produced, "
            "as a fraction of its tolerance (10% of the largest residual over the nodes plus "
            "1e-3, per output; <= 1 is within it), over all solves:", "", *table]


def section_robustness(ctx: Context, exp: Experiment) -> list[str]:
    """Success per cell of the envelope, each learning MPC's as a share of the oracle's."""
    rows = ctx.summaries[exp.name]
    controllers = list(dict.fromkeys(r["controller"] for r in rows))
    cells: dict[tuple[str, str, str, int], dict[str, dict[str, Any]]] = defaultdict(dict)
    for r in rows:
        cells[(r["env"], r["scenario"], r["cell"], r["n_init"])][r["controller"]] = r
    learners = [c for c in controllers if CONTROLLERS[c].learner is not None]
    header = ["env", "scenario", "cell", "initial samples", *[_label(c) for c in controllers],
              *[f"{_label(c)} / oracle" for c in learners if "oracle-mpc" in controllers],
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
        line.append(", ".join(f"{_label(r['controller'])} {r['episodes_with_violation']}"
                              for r in present if r["episodes_with_violation"]) or "0")
        line.append(", ".join(f"{_label(r['controller'])} {_fmt(r['final_position_error_max'], 3)}"
                              for r in present if np.isfinite(r["final_position_error_max"]))
                    or "n/a")
        line.append(", ".join(f"{_label(r['controller'])} {r['recovered']}/{r['episodes']}, "
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
    return lines


@dataclass(frozen=True)
class PublishedAnchor:
    """A published data-efficiency figure on PILCO's cart pole, cited with its setup.

    Attributes:
        method: who. success: the reported success rate (NaN: not reported as a rate).
        trials: trials until that success, counting the first random one.
        interaction_s: interaction time until then, s, as the source counts it.
        source: the citation. setup: how its setup differs from this package's.
    """

    method: str
    success: float
    trials: int
    interaction_s: float
    source: str
    setup: str


PUBLISHED_ANCHORS: dict[str, tuple[PublishedAnchor, ...]] = {
    "pilco_cartpole": (
        PublishedAnchor(
            "GP-MPC", 0.9, 3, 9.0, "Kamthe & Deisenroth, AISTATS 2018 (as quoted in issue 44)",
            "no physics prior; GP with moment-matching uncertainty propagation in the plan; "
            "every transition added at once, replanned every step; whole trials counted "
            "(9 s over 3 trials suggests 3 s trials; here trials are 4 s, PILCO's MATLAB "
            "code); success = tip within 8 cm for 10 consecutive steps, as here"),
        PublishedAnchor(
            "PILCO (in GP-MPC's comparison)", float("nan"), 5, 15.0,
            "Kamthe & Deisenroth, AISTATS 2018 (as quoted in issue 44)",
            "no physics prior; a parametric policy learned between trials (no online "
            "learning within a trial); whole trials counted"),
        PublishedAnchor(
            "PILCO (real cart pole)", float("nan"), 0, 17.5,
            "Deisenroth & Rasmussen, ICML 2011",
            "the real hardware, not this simulation; no physics prior; a policy learned "
            "between trials; whole trials counted (trials count not given here)"),
    ),
}
"""The published anchors of the data-efficiency section, by system."""


def _seconds(n: int, dt: float) -> str:
    return f"{n} ({n * dt:g} s)"


def data_efficiency_figure(env: str, rows: Sequence[dict[str, Any]], dt: float) -> Any:
    """Success rate and mean interaction time before success against the initial samples, per
    controller (the references as horizontal lines), with the published anchors of ``env``."""
    fig, (ax_s, ax_t) = plt.subplots(1, 2, figsize=(11, 4))
    by: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        by[r["controller"]].append(r)
    for c, group in by.items():
        st = _style(c)
        if CONTROLLERS[c].learner is None:
            r = group[0]
            ax_s.axhline(r["success_rate"], color=st.color, ls=":", lw=1, label=r["label"])
            if math.isfinite(r["interaction_mean_s"]):
                ax_t.axhline(r["interaction_mean_s"], color=st.color, ls=":", lw=1,
                             label=r["label"])
            continue
        group = sorted(group, key=lambda r: r["n_init"])
        x = [r["n_init"] * dt for r in group]
        ax_s.plot(x, [r["success_rate"] for r in group], **st.line(len(x), len(x)),
                  label=f"{group[0]['label']} (trial 1)")
        ax_s.plot(x, [r["trials_success_rate"] for r in group], color=st.color, ls="--",
                  lw=0.8, label=f"{group[0]['label']} (within {_max_trials()} trials)")
        ax_t.plot(x, [r["interaction_trials_mean_s"] for r in group],
                  **st.line(len(x), len(x)), label=group[0]["label"])
    for a in PUBLISHED_ANCHORS.get(env, ()):  # whole trials counted: see the table's notes
        rate = f", {a.success:.0%} success" if math.isfinite(a.success) else ""
        ax_t.axhline(a.interaction_s, color="0.5", ls="-.", lw=0.8)
        ax_t.annotate(f"{a.method} (published{rate})", (0, a.interaction_s), fontsize=7,
                      color="0.3", xytext=(2, 2), textcoords="offset points")
    ax_s.set_xlabel("initial data (s of interaction)")
    ax_s.set_ylabel("success rate")
    ax_s.set_ylim(-0.05, 1.05)
    ax_t.set_xlabel("initial data (s of interaction)")
    ax_t.set_ylabel(f"interaction before success, within {_max_trials()} trials (s)")
    ax_s.legend(fontsize=6)
    ax_t.legend(fontsize=6)
    fig.suptitle(f"{env}: data efficiency")
    fig.tight_layout()
    return fig


def _max_trials() -> int:
    from benchmarks.trial import MAX_TRIALS

    return MAX_TRIALS


def section_data_efficiency(ctx: Context, exp: Experiment) -> list[str]:
    """Per env: success, cost and interaction time before success against the initial
    samples, the multi-trial protocol's trials to success, and the published anchors."""
    by: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for r in ctx.summaries[exp.name]:
        by[(r["env"], r["scenario"])].append(r)
    k = _max_trials()
    lines = ["", "*success*: the first trial ends held at the goal (`info['success']`); "
             "*interaction before success*: initial data plus `info['at_goal_since']` at the "
             "end of that trial, mean over the seeds that succeeded [BCa 95% interval]; "
             f"*within {k} trials*: GP-MPC's protocol (a learning recipe that failed runs "
             "another trial on the same system from a new start, pretrained on every "
             "transition so far), its success rate, mean trials and interaction time "
             "(initial data, the failed trials' whole length, and the successful trial's "
             "`at_goal_since`). Success rates with Wilson 95% intervals, costs with BCa "
             "intervals over seeds."]
    header = ["controller", "initial samples (time)", "episodes", "success [95% CI]",
              "cost [95% CI]", "interaction before success, s [95% CI] (n)",
              f"success within {k} trials", "trials to success", "interaction incl. trials, s"]
    for (env, scenario), rows in by.items():
        dt = float(_env_model(env, scenario).dt)
        rows = sorted(rows, key=lambda r: (CONTROLLERS[r["controller"]].learner is not None,
                                           r["controller"], r["n_init"]))
        body = []
        for r in rows:
            learning = CONTROLLERS[r["controller"]].learner is not None
            n_ok = round(r["success_rate"] * r["episodes"]) if r["episodes"] else 0
            body.append([
                r["label"], _seconds(r["n_init"], dt) if learning else "-", r["episodes"],
                f"{_fmt(r['success_rate'])} {_interval(r['success_ci_low'], r['success_ci_high'])}",
                f"{_fmt(r['cost_mean'])} {_interval(r['cost_ci_low'], r['cost_ci_high'])}",
                f"{_fmt(r['interaction_mean_s'])} "
                f"{_interval(r['interaction_ci_low'], r['interaction_ci_high'])} ({n_ok})",
                (f"{_fmt(r['trials_success_rate'])} "
                 f"{_interval(r['trials_success_ci_low'], r['trials_success_ci_high'])}"
                 if learning else "-"),
                _fmt(r["trials_to_success_mean"]) if learning else "-",
                (f"{_fmt(r['interaction_trials_mean_s'])} "
                 f"{_interval(r['interaction_trials_ci_low'], r['interaction_trials_ci_high'])}"
                 if learning else "-")])
        for a in PUBLISHED_ANCHORS.get(env, ()):
            body.append([f"{a.method} (published)", "-", "-",
                         _fmt(a.success) if math.isfinite(a.success) else "-", "-", "-",
                         "-", str(a.trials) if a.trials else "-", f"{a.interaction_s:g}"])
        name = _save(data_efficiency_figure(env, [r for r in rows if r["episodes"]], dt),
                     ctx.out_dir, f"{exp.name}_{env}.png")
        lines += ["", f"### {_env_title(env, scenario)}", "", f"![data efficiency]({name})", ""]
        lines += markdown_table(header, body, ["---", "---:"] + ["---:"] * (len(header) - 2))
        anchors = PUBLISHED_ANCHORS.get(env, ())
        if anchors:
            lines += ["", "Published figures (cited, not measured here) and how their setup "
                      "differs:", ""]
            lines += [f"- **{a.method}** ({a.source}): {a.setup}." for a in anchors]
    return lines


@dataclass(frozen=True)
class PublishedReturn:
    """A published return on a DeepMind Control task, computed from its authors' result files.

    Attributes:
        method: who. steps: environment (physics) steps of interaction, action repeat
            included. mean, low, high: the return's mean, min and max over the published
            seeds. source: the file (repository, path, commit).
    """

    method: str
    steps: int
    mean: float
    low: float
    high: float
    source: str


_TDMPC2 = "nicklashansen/tdmpc2 at e9f5932, results/{}/cartpole-swingup.csv (3 seeds)"
PUBLISHED_RETURNS: dict[str, tuple[PublishedReturn, ...]] = {
    "dmc-cartpole": (
        PublishedReturn("TD-MPC2", 100_000, 839.4, 789.8, 867.9, _TDMPC2.format("tdmpc2")),
        PublishedReturn("TD-MPC2", 4_000_000, 877.2, 866.2, 883.0, _TDMPC2.format("tdmpc2")),
        PublishedReturn("TD-MPC", 100_000, 863.1, 850.7, 877.5, _TDMPC2.format("tdmpc")),
        PublishedReturn("TD-MPC", 4_000_000, 882.9, 882.9, 883.0, _TDMPC2.format("tdmpc")),
        PublishedReturn("SAC", 100_000, 835.0, 825.8, 844.8, _TDMPC2.format("sac")),
        PublishedReturn("SAC", 4_000_000, 825.5, 790.5, 855.2, _TDMPC2.format("sac")),
        PublishedReturn("DreamerV3", 100_000, 676.7, 637.2, 718.6, _TDMPC2.format("dreamerv3")),
        PublishedReturn("DreamerV3", 200_000, 795.6, 774.0, 811.9, _TDMPC2.format("dreamerv3")),
        PublishedReturn("DreamerV3", 3_900_000, 830.2, 820.9, 839.1,
                        _TDMPC2.format("dreamerv3")),
    ),
}
"""Published returns beside the own-env section's table, by benchmark env. The steps count
environment steps with TD-MPC2's action repeat of 2 included (its ``envs/dmcontrol.py``), so
100k steps are 50k agent decisions; returns are over DMC's 1000-step episodes."""


@functools.cache
def _physics_steps_per_step(env: str, scenario: str) -> int:
    """Simulator steps per env step of benchmark env ``env`` (a DMC env's action repeat; 1
    for every other)."""
    made = make_env(env, scenario)
    try:
        repeat = made.get_wrapper_attr("action_repeat")
    except AttributeError:
        repeat = 1
    finally:
        made.close()
    return int(repeat) if isinstance(repeat, int) else 1


def section_own_env(ctx: Context, exp: Experiment) -> list[str]:
    """Outside simulators (:mod:`benchmarks.outside_envs`): the env's own return with 95%
    intervals per recipe and initial data, the data in simulator steps, how often the learned
    residual was switched off, the act latency; the published returns beside DMC's task."""
    by: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for r in ctx.summaries[exp.name]:
        by[(r["env"], r["scenario"])].append(r)
    header = ["controller", "initial samples", "episodes", "return [95% CI]",
              "success [95% CI]", "simulator steps of data", "residual off (steps of the "
              "episode)", "act median (ms)", "status"]
    lines = ["", "*return*: the env's own reward summed over the episode (DMC's, 0-1000; "
             "Pendulum-v1's, at most 0), mean over the evaluation seeds with its BCa 95% "
             "interval; *success*: the nominal model's task (`info['success']`, held at the "
             "goal for its hold time), Wilson interval; *simulator steps of data*: the initial "
             "data and the episode, in the simulator's own steps (DMC: env steps times the "
             "action repeat); *residual off*: steps in which the learner's nominal fallback "
             "had switched the learned residual off because it predicted the newest samples "
             "worse than the nominal model (mean over episodes; '-' without a learner)."]
    for (env, scenario), rows in by.items():
        repeat = _physics_steps_per_step(env, scenario)
        rows = sorted(rows, key=lambda r: (CONTROLLERS[r["controller"]].learner is not None,
                                           r["controller"], r["n_init"]))
        body = []
        for r in rows:
            learning = CONTROLLERS[r["controller"]].learner is not None
            body.append([
                r["label"], r["n_init"] if learning else "-", r["episodes"],
                f"{_fmt(r['return_mean'], 1)} "
                f"{_interval(r['return_ci_low'], r['return_ci_high'], 1)}",
                f"{_fmt(r['success_rate'])} {_interval(r['success_ci_low'], r['success_ci_high'])}",
                _fmt(r["data_steps_mean"] * repeat, 0),
                _fmt(r["residual_off_steps_mean"], 1) if learning else "-",
                _fmt(r["act_median_ms"], 1), r["status"]])
        lines += ["", f"### {_env_title(env, scenario)}", ""]
        lines += markdown_table(header, body, ["---"] + ["---:"] * 7 + ["---"])
        published = PUBLISHED_RETURNS.get(env, ())
        if published and scenario == ENVS[env].default_scenario:
            lines += ["", "Published returns on the same task (cited, computed from the "
                      "authors' result files, not measured here): mean [min, max] over their "
                      "seeds. Their setting differs: they learn from the reward and pixels or "
                      "DMC's observation alone, with no physics prior and no state in a "
                      "model's coordinates, at action repeat 2.", ""]
            lines += markdown_table(
                ["method", "environment steps", "return [min, max]", "source"],
                [[p.method, f"{p.steps:,}", f"{p.mean:.1f} [{p.low:.1f}, {p.high:.1f}]",
                  p.source] for p in published], ["---", "---:", "---:", "---"])
    return lines


def _time_varying(row: dict[str, Any]) -> bool:
    """Whether a summary row is of a time-varying scenario (it has recovery times to show)."""
    return bool(_env_model_changes(row["env"], row["scenario"]))


@functools.cache
def _env_model_changes(env: str, scenario: str) -> tuple[Any, ...]:
    return scenario_changes(env, scenario)


SECTIONS: dict[str, SectionFn] = {
    "summary": section_summary,
    "own_env": section_own_env,
    "data_efficiency": section_data_efficiency,
    "paper_tables": section_paper_tables,
    "trajectories": section_trajectories,
    "paths": section_paths,
    "step_times": section_step_times,
    "sample_efficiency": section_sample_efficiency,
    "scaling": section_scaling,
    "step_scaling": section_step_scaling,
    "update_time": section_update_time,
    "peers": section_peers,
    "acceptance": section_acceptance,
    "robustness": section_robustness,
}
"""Report sections by name (used by :class:`benchmarks.presets.Experiment`)."""


# ----------------------------------------------------------------------------- report
def package_versions() -> dict[str, str]:
    """Installed versions of the packages the results depend on (``"-"`` if absent)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = "-"
    return out


def _git_commit() -> str:
    try:
        res = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10, cwd=Path(__file__).resolve().parent)
        return res.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _record_counts(trials: Iterable[Any], key: str) -> str:
    """``"value (trials), ..."`` of a trial-record field (e.g. the code version, the CPU)."""
    counts: dict[str, int] = defaultdict(int)
    for t in trials:
        if t.record is not None:
            counts[str(t.record.get(key, "not recorded"))] += 1
    return ", ".join(f"{v} ({n})" for v, n in sorted(counts.items()))


def _capped(trials: Iterable[Any]) -> str:
    capped = [int(c) for t in trials if t.ok and t.spec.kind in EPISODE_KINDS
              for c in [t.metrics.get("capped_solves", math.nan)]
              if isinstance(c, int | float) and math.isfinite(c)]
    return (f"{sum(capped)} in {sum(c > 0 for c in capped)} of {len(capped)} MPC episode(s)"
            if capped else "no MPC episodes")


def write_report(out_dir: Path, preset: Preset, command: str,
                 run_info: dict[str, Any] | None = None) -> Path:
    """Write CSVs, figures and ``report.md`` for ``preset`` from the trial files in ``out_dir``.

    Args:
        out_dir: results directory (trial files in ``out_dir/runs``).
        preset: the preset (its experiments choose the trials and sections).
        command: the exact command line that produced the run.
        run_info: facts about the latest invocation (e.g. ``wall_s``, ``ran``, ``skipped``,
            ``workers``, ``scheduler``).

    Returns:
        Path of ``report.md``.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    trials = load_trials(out_dir, preset.specs)
    all_trials = list(trials.values())
    summaries = {e.name: summarize(e.name, [trials[s] for s in e.specs])
                 for e in preset.experiments}
    ctx = Context(out_dir, trials, summaries, compute_rows(all_trials), peer_rows(all_trials))
    _write_csv(out_dir / "metrics.csv", METRIC_COLUMNS, metric_rows(all_trials))
    _write_csv(out_dir / "summary.csv", SUMMARY_COLUMNS,
               [r for rows in summaries.values() for r in rows])
    if ctx.compute_rows:
        cols = list(dict.fromkeys(k for r in ctx.compute_rows for k in r))
        _write_csv(out_dir / "compute.csv", cols, ctx.compute_rows)
    if ctx.peer_rows:
        cols = list(dict.fromkeys(k for r in ctx.peer_rows for k in r))
        _write_csv(out_dir / "peers.csv", cols, ctx.peer_rows)

    counts = defaultdict(int)
    for t in all_trials:
        counts[t.status] += 1
    trial_s = sum(float(t.record.get("wall_s", 0.0)) for t in all_trials if t.record)
    info = dict(run_info or {})
    lines = [f"# Benchmark report: `{preset.name}`", "",
             f"{preset.description}. Generated by `benchmarks` from the trial files in `runs/` "
             "(git-ignored); every number below is computed from them.", "",
             "```bash", command, "```", ""]
    status_counts = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    lines += [f"- trials: {len(all_trials)} ({status_counts})",
              f"- summed trial wall time: {trial_s:.0f} s"]
    if "wall_s" in info:
        lines.append(f"- last invocation: {info['wall_s']:.0f} s wall clock, ran "
                     f"{info.get('ran', '?')} trial(s), kept {info.get('skipped', '?')} finished "
                     f"one(s); workers: {info.get('workers', '?')}, scheduler: "
                     f"{info.get('scheduler') or 'none (local)'}")
    lines += [f"- machine: {platform.machine()}, {os.cpu_count()} CPU(s) (shared), "
              f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, "
              f"{platform.platform(terse=True)}",
              f"- CPU model, trials: {_record_counts(all_trials, 'cpu')}",
              f"- solves that hit the iteration cap (the only cap; no wall-clock limit): "
              f"{_capped(all_trials)}",
              f"- git commit: {_git_commit()}; trials by code version: "
              f"{_record_counts(all_trials, 'code_version')}; written "
              f"{_dt.datetime.now(_dt.UTC).strftime('%Y-%m-%d %H:%M UTC')}",
              "- versions: " + ", ".join(f"{k} {v}" for k, v in package_versions().items()),
              "", "Tables: `metrics.csv` (one row per episode), `summary.csv` (per experiment and "
              "controller)" + (", `compute.csv`" if ctx.compute_rows else "")
              + (", `peers.csv`" if ctx.peer_rows else "") + ". Step times are wall clock on "
              "a shared machine: compare them within a run, not across machines.", ""]
    lines += ["## Contents", ""] + [f"- [{e.title}](#{e.name})" for e in preset.experiments]
    for exp in preset.experiments:
        lines += ["", f'<a id="{exp.name}"></a>', "", f"## {exp.title}", "", exp.description]
        for section in exp.sections:
            lines += SECTIONS[section](ctx, exp)
    path = out_dir / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
