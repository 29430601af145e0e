"""Loading a results directory: the trial files, and the rows of ``metrics.csv``,
``compute.csv`` and ``peers.csv`` computed from them."""

from __future__ import annotations

import csv
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.compute import STEP_SCALING
from benchmarks.controllers import CONTROLLERS
from benchmarks.runner import load_arrays, load_record, trial_path
from benchmarks.trial import EPISODE_KINDS, STATUS_OK, STATUS_UNAVAILABLE, TrialSpec

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


def _write_csv(path: Path, columns: Sequence[str], rows: Iterable[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: row.get(k, "") for k in columns})


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


def compute_rows(trials: Iterable[Trial]) -> list[dict[str, Any]]:
    """Rows of ``compute.csv``: the scaling and update-time measurements."""
    rows = []
    for t in trials:
        if t.spec.kind in ("ssgp-act-scaling", "ssgp-update-time", *STEP_SCALING) and t.ok:
            rows.append({"key": t.spec.key, "measurement": t.spec.kind, "env": t.spec.env,
                         "scenario": t.spec.scenario, "controller": t.spec.controller,
                         "seed": t.spec.seed, "param": t.spec.param, **t.metrics})
    return rows


def peer_rows(trials: Iterable[Trial]) -> list[dict[str, Any]]:
    """Rows of ``peers.csv``: one per seed."""
    return [{"env": t.spec.env, "scenario": t.spec.scenario, "seed": t.spec.seed, **t.metrics}
            for t in trials if t.spec.kind == "peers" and t.ok]
