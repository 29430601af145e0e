"""The per-cell aggregates of ``summary.csv``: success, cost, errors, step times, RTI paths."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np

from benchmarks.report.common import _description
from benchmarks.report.load import Trial
from benchmarks.report.stats import _finite_number, _max_finite, _mean, mean_ci, wilson_ci
from benchmarks.trial import EPISODE_KINDS, STATUS_UNAVAILABLE, Cell
from gp_agents.mpc.diagnostics import StepStatus


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
        accepted = (np.concatenate([t.arrays["diag_status"][k] == StepStatus.RTI
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
            "label": _description(controller), "status": status,
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
