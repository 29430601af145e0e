"""What RL is compared with: the oracle MPC's cost bound and the data-efficiency preset's MPC
cells (the anchors), and the sample-efficiency section of a plan against them."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import gp_envs  # noqa: F401  (registers the envs)
from benchmarks.rl.seeds import OUT, SeedRun, _rel, median_iqr_ci
from benchmarks.rl.train import ENV_SHORT_NAMES

TRAINING_EVAL_SEEDS = range(1000, 1020)
"""Reset seeds of the training evaluations (:mod:`benchmarks.rl.train`); the oracle MPC that
sets RL's cost bound runs on the same ones."""
COST_MARGIN = 1.1
"""The cost criterion: a mean cost at most this times the oracle MPC's."""
SUCCESS_BAR = 0.8
"""The success criterion: a success rate of at least this (the RL issue's acceptance bar)."""
DATA_EFFICIENCY = OUT.parent / "data-efficiency"
"""The data-efficiency preset's committed results (``python -m benchmarks --preset
data-efficiency``; ``summary.csv``, ``metrics.csv``, ``report.md``): the MPC side of the
sample-efficiency comparison."""
MPC_ANCHORS = ("robust-mpc", "blackbox-mpc")
"""The MPC recipes RL is compared with: the recommended recipe and the same MPC without a
physics prior (the no-prior anchor, GP-MPC's setting)."""
PLAIN_CELL = "fixed truth"
"""The preset cell of the scenario as registered (``benchmarks.trial.Cell().describe()``): the
system the RL plans train and evaluate on."""
MPC_CRITERIA = ("success", "trials", "cost")
"""What an MPC cell is asked (:func:`anchor_cell`)."""
_TEXT_COLUMNS = ("experiment", "env", "scenario", "cell", "controller", "label", "status")


def env_dt(env: str, scenario: str) -> float:
    """The control period (s) of ``env`` (``--env`` short name or registered id) in
    ``scenario``, read from the env: one env step is this much interaction."""
    made = gym.make(ENV_SHORT_NAMES.get(env, env), scenario=scenario)
    try:
        return float(made.unwrapped.DT)
    finally:
        made.close()


def _float(text: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return float("nan")


def read_data_efficiency(env: str, scenario: str, results: Path = DATA_EFFICIENCY
                         ) -> list[dict[str, Any]]:
    """The data-efficiency preset's cells of ``env`` (short name) in ``scenario`` on the
    scenario as registered (:data:`PLAIN_CELL`) with at least one episode, from
    ``results/summary.csv``: text columns as text, ``n_init`` as int, the others as floats
    (NaN where empty). Empty if the file is missing or has no such cell."""
    path = results / "summary.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        rows = [{k: v if k in _TEXT_COLUMNS else _float(v) for k, v in r.items()}
                for r in csv.DictReader(fh)
                if (r["env"], r["scenario"], r["cell"]) == (env, scenario, PLAIN_CELL)]
    for r in rows:
        r["n_init"] = int(r["n_init"])
    return [r for r in rows if r["episodes"] > 0]


def preset_seeds(env: str, scenario: str, results: Path = DATA_EFFICIENCY) -> list[int]:
    """The evaluation seeds of the preset's episodes of ``env`` in ``scenario`` (its
    ``metrics.csv``; empty if missing)."""
    path = results / "metrics.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return sorted({int(r["seed"]) for r in csv.DictReader(fh)
                       if (r["env"], r["scenario"]) == (env, scenario)})


def _seed_range(seeds: list[int]) -> str:
    if seeds and seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}-{seeds[-1]}"
    return ", ".join(map(str, seeds))


@dataclass(frozen=True)
class EnvAnchors:
    """What the RL plans of one env/scenario are compared with.

    Attributes:
        env, scenario: ``--env`` short name and scenario.
        oracle: :func:`benchmarks.rl.summary.oracle_reference` on RL's evaluation seeds (RL's
            cost bound).
        preset: :func:`read_data_efficiency` rows (empty: the preset has no such cell).
        seeds: the preset's evaluation seeds (:func:`preset_seeds`).
        dt: the env's control period (s): one env step of interaction.
    """

    env: str
    scenario: str
    oracle: dict[str, float]
    preset: list[dict[str, Any]]
    seeds: list[int]
    dt: float


@dataclass(frozen=True)
class AnchorCell:
    """The data-efficiency cell with which an MPC recipe met a criterion.

    Attributes:
        controller: benchmark recipe name (``"robust-mpc"``).
        label: its name in reports (``"robust MPC"``).
        n_init: initial samples of the cell (the fewest that met the criterion).
        episodes: seeds of the cell (each a fresh learner on the same system).
        success_rate: success rate of the first trial over the seeds.
        trials_success_rate: success rate within the multi-trial protocol's trials.
        cost: mean cost of the first trial (the env's, ``-return``).
        interaction_s: mean interaction time before success (s) over the seeds that
            succeeded: initial data plus the time at which the final stretch held at the goal
            began; for the ``"trials"`` criterion the failed trials count whole.
        ci_low, ci_high: its 95% interval from the preset (s; NaN where it gives none).
        seeds: the seeds the mean is over (those that succeeded).
    """

    controller: str
    label: str
    n_init: int
    episodes: int
    success_rate: float
    trials_success_rate: float
    cost: float
    interaction_s: float
    ci_low: float
    ci_high: float
    seeds: int

    def steps(self, dt: float) -> tuple[float, float, float]:
        """:attr:`interaction_s` and its interval in env steps of ``dt`` seconds."""
        return self.interaction_s / dt, self.ci_low / dt, self.ci_high / dt


def mpc_cost_bound(rows: list[dict[str, Any]]) -> float:
    """:data:`COST_MARGIN` times the mean cost of the preset's oracle MPC cell among ``rows``
    (one env/scenario); NaN if it has none."""
    oracle = [r["cost_mean"] for r in rows if r["controller"] == "oracle-mpc"]
    return COST_MARGIN * oracle[0] if oracle else float("nan")


def anchor_cell(rows: list[dict[str, Any]], controller: str, criterion: str
                ) -> AnchorCell | str:
    """The cell of ``controller`` with the fewest initial samples among the preset ``rows`` of
    one env/scenario that meets ``criterion``, or why there is none.

    Criteria: ``"success"``, first-trial success rate >= :data:`SUCCESS_BAR`; ``"trials"``,
    success within the multi-trial protocol's trials (GP-MPC's: a failed trial is counted whole
    and another runs on the same system) >= :data:`SUCCESS_BAR`; ``"cost"``, first-trial mean
    cost <= :func:`mpc_cost_bound` (the preset's own oracle cell). The interaction time is the
    first trial's for ``"success"`` and ``"cost"``, the trials' for ``"trials"``.

    Returns:
        The cell, or ``"not in the preset"`` (no cell of ``controller``), ``"not measured"``
        (``"cost"`` without an oracle cell), ``"not met at <n>-<m> initial samples"``.
    """
    if criterion not in MPC_CRITERIA:
        raise ValueError(f"criterion must be one of {list(MPC_CRITERIA)}, got {criterion!r}")
    cells = sorted((r for r in rows if r["controller"] == controller),
                   key=lambda r: r["n_init"])
    if not cells:
        return "not in the preset"
    bound = mpc_cost_bound(rows)
    if criterion == "cost" and not np.isfinite(bound):
        return "not measured"

    def meets(r: dict[str, Any]) -> bool:
        if criterion == "success":
            return r["success_rate"] >= SUCCESS_BAR
        if criterion == "trials":
            return r["trials_success_rate"] >= SUCCESS_BAR
        return r["cost_mean"] <= bound

    r = next((c for c in cells if meets(c)), None)
    if r is None:
        return f"not met at {cells[0]['n_init']}-{cells[-1]['n_init']} initial samples"
    prefix = "interaction_trials" if criterion == "trials" else "interaction"
    rate = r["trials_success_rate"] if criterion == "trials" else r["success_rate"]
    return AnchorCell(controller, str(r["label"]), int(r["n_init"]), int(r["episodes"]),
                      r["success_rate"], r["trials_success_rate"], r["cost_mean"],
                      r[f"{prefix}_mean_s"], r[f"{prefix}_ci_low"], r[f"{prefix}_ci_high"],
                      round(rate * r["episodes"]))


def first_step(curve: list[dict[str, float]], ok: Any) -> float:
    """The first training-evaluation step whose row satisfies ``ok`` (NaN: none)."""
    return next((c["timesteps"] for c in curve if ok(c)), float("nan"))


def censored_steps(runs: list[SeedRun], budget: int) -> float:
    """The value standing for "never within the budget": one more than ``budget`` or than the
    last step any seed was evaluated at (TQC trains in chunks and may pass the budget)."""
    return float(max([budget, *(c["timesteps"] for r in runs for c in r.curve)]) + 1)


def rl_steps_to(runs: list[SeedRun], ok: Any, censored: float
                ) -> tuple[dict[str, float], int]:
    """Env steps to the first training evaluation satisfying ``ok``, over the seeds: the
    :func:`median_iqr_ci` statistics with a seed that never got there counted as ``censored``
    (:func:`censored_steps`), and the number of seeds that got there."""
    steps = [first_step(r.curve, ok) for r in runs]
    values = [v if np.isfinite(v) else censored for v in steps]
    return median_iqr_ci(values), int(sum(np.isfinite(v) for v in steps))


def _interval(mid: str, lo: float, hi: float, fmt: Any) -> str:
    return mid + (f" [{fmt(lo)}, {fmt(hi)}]" if np.isfinite(lo) and np.isfinite(hi) else "")


def ratio_text(rl_median: float, mpc_steps: float, budget: int, censored: float) -> str:
    """RL / MPC env steps: ``"> Nx"`` with the ``budget`` in RL's place when RL's median is
    ``censored`` (:func:`rl_steps_to`); ``"n/a"`` without an MPC value."""
    if not (np.isfinite(mpc_steps) and mpc_steps > 0):
        return "n/a"
    if rl_median >= censored:
        return f"> {budget / mpc_steps:.0f}x"
    return f"{rl_median / mpc_steps:.0f}x"


MPC_REFERENCES = ("nominal-mpc", "oracle-mpc")
"""The preset's recipes without learning or data, quoted next to the anchors: where the nominal
MPC already meets a criterion, the prior, not the learning, is what the anchor measures."""


def _reference_line(preset: list[dict[str, Any]]) -> list[str]:
    """One paragraph quoting the preset's :data:`MPC_REFERENCES` cells (none: nothing)."""
    parts = []
    for c in MPC_REFERENCES:
        r = next((r for r in preset if r["controller"] == c), None)
        if r is not None:
            t = r["interaction_mean_s"]
            parts.append(f"{r['label']} (`{c}`) success {r['success_rate']:.2f}, cost "
                         f"{r['cost_mean']:.2f}, interaction before success "
                         + (f"{t:.2f} s" if np.isfinite(t) else "n/a (no seed succeeded)"))
    if not parts:
        return []
    return ["Without learning or data, in the same preset: " + "; ".join(parts) + ". Where "
            "the nominal MPC meets a criterion, an anchor with 0 initial samples measures the "
            "physics prior, not the learning, and its interaction time is mostly the time the "
            "task takes to reach the goal (compare the oracle's).", ""]


def sample_efficiency_lines(runs: list[SeedRun], anchors: EnvAnchors, budget: int
                            ) -> list[str]:
    """The sample-efficiency section of one plan: RL's env steps (and seconds) to (i) success
    >= 0.8 and (ii) cost within 10% of the oracle MPC's (training evaluations, one value per
    seed, censored beyond ``budget``); the MPC anchors' interaction time before success from
    the data-efficiency preset (:func:`anchor_cell`, in seconds and env steps); the RL / MPC
    ratios. Without preset cells for the env/scenario, one line says so instead."""
    from benchmarks.trial import MAX_TRIALS

    oracle, preset, dt = anchors.oracle, anchors.preset, anchors.dt
    env, scenario, seeds = anchors.env, anchors.scenario, anchors.seeds

    n = len(TRAINING_EVAL_SEEDS)
    censored = censored_steps(runs, budget)
    bound = COST_MARGIN * oracle["mean_cost"]
    rl = {"success": rl_steps_to(runs, lambda c: c["success_rate"] >= SUCCESS_BAR, censored),
          "cost": rl_steps_to(runs, lambda c: c["mean_cost"] <= bound, censored)}

    def steps_fmt(v: float) -> str:
        return f"> {budget}" if v >= censored else f"{v:.0f}"

    def seconds_fmt(v: float) -> str:
        return f"> {budget * dt:.0f}" if v >= censored else f"{v * dt:.0f}"

    lines = ["### Sample efficiency", "",
             f"**RL**: env steps of training until a deterministic training evaluation ({n} "
             f"episodes on reset seeds {TRAINING_EVAL_SEEDS.start}.."
             f"{TRAINING_EVAL_SEEDS.stop - 1}; the evaluation episodes are not counted) first "
             "met the criterion, one value per seed (a seed that never met it within its "
             f"{budget} steps counts as more: `>`), median and bootstrap 95% CI over the seeds; "
             f"in seconds of interaction, env steps x dt (dt = {dt:g} s, the env's). Its cost "
             f"bound is {COST_MARGIN:g}x the oracle MPC's mean cost on the same reset seeds "
             f"({oracle['episodes']} episodes: {oracle['mean_cost']:.2f}).", "",
             "| criterion | RL seeds that met it | RL env steps, median [95% CI] | RL interaction, "
             "s (env steps x dt) |", "|---|---:|---|---|"]
    labels = {"success": f"success rate >= {SUCCESS_BAR:g}",
              "cost": f"mean cost <= {bound:.2f} ({COST_MARGIN:g}x the oracle MPC's "
                      f"{oracle['mean_cost']:.2f})"}
    for key in ("success", "cost"):
        st, met = rl[key]
        lines.append(f"| {labels[key]} | {met}/{len(runs)} | "
                     + _interval(steps_fmt(st["median"]), st["ci_lo"], st["ci_hi"], steps_fmt)
                     + " | "
                     + _interval(seconds_fmt(st["median"]), st["ci_lo"], st["ci_hi"],
                                 seconds_fmt) + " |")
    lines.append("")
    if not preset:
        return [*lines, f"**MPC**: the data-efficiency preset (`{_rel(DATA_EFFICIENCY)}`) has "
                f"no cell for `{env}` `{scenario}` as registered: no MPC anchor, no ratio.", ""]
    mpc_bound = mpc_cost_bound(preset)
    where = f"seeds {_seed_range(seeds)}, " if seeds else ""
    lines += [f"**MPC**: the data-efficiency preset's committed cells (`{_rel(DATA_EFFICIENCY)}"
              f"/summary.csv`, `{env}` `{scenario}` as registered, {where}one fresh learner per "
              "seed) for the recommended recipe (`robust-mpc`) and the same MPC without a physics "
              "prior (`blackbox-mpc`, the no-prior anchor): per criterion the fewest initial "
              "samples whose cell meets it and that cell's *interaction time before success*: "
              "the initial data plus the time at which the episode's final stretch held at the "
              "goal began, mean over the seeds that succeeded with the preset's 95% interval "
              f"where it gives one, and in env steps (seconds / dt). *Within {MAX_TRIALS} "
              "trials*: GP-MPC's multi-trial protocol (a failed trial counts whole, then "
              "another runs on the same system from a new start). Cost: the cell's first-trial "
              f"mean cost against {COST_MARGIN:g}x the preset's own oracle cell"
              + (f" ({mpc_bound / COST_MARGIN:.2f}: <= {mpc_bound:.2f})"
                 if np.isfinite(mpc_bound) else " (none here: not measured)") + ".", "",
              *_reference_line(preset),
              "What is counted differs: RL counts every training step, failed episodes whole, "
              "until a policy evaluated apart from training meets the criterion; the MPC counts "
              "real interaction up to the start of the successful stretch (the rest of that "
              "episode is not counted), learning online within it. RL's success rate is one "
              f"policy's over {n} episodes, the MPC's that of independent learners over the "
              "preset's seeds.", "",
              "| criterion | MPC recipe | fewest initial samples meeting it | that cell: success "
              f"(trial 1 / within {MAX_TRIALS} trials), cost (trial 1) | interaction before "
              "success, s, mean [95% CI] (seeds) | in env steps | RL / MPC |",
              "|---|---|---|---|---|---|---|"]
    mpc_labels = {"success": f"success rate >= {SUCCESS_BAR:g}",
                  "trials": f"success rate >= {SUCCESS_BAR:g} (MPC: within {MAX_TRIALS} "
                            "trials)",
                  "cost": f"mean cost <= {COST_MARGIN:g}x the oracle MPC's"}
    for key in MPC_CRITERIA:
        st, _met = rl["cost" if key == "cost" else "success"]
        for controller in MPC_ANCHORS:
            cell = anchor_cell(preset, controller, key)
            if isinstance(cell, str):
                lines.append(f"| {mpc_labels[key]} | `{controller}` | {cell} | | | | n/a |")
                continue
            mid, lo, hi = cell.steps(dt)
            lines.append(
                f"| {mpc_labels[key]} | `{controller}` | {cell.n_init} "
                f"({cell.n_init * dt:g} s) | {cell.success_rate:.2f} / "
                f"{cell.trials_success_rate:.2f}, {cell.cost:.2f} | "
                + _interval(f"{cell.interaction_s:.2f}", cell.ci_low, cell.ci_high,
                            lambda v: f"{v:.2f}") + f" ({cell.seeds}) | "
                + _interval(f"{mid:.0f}", lo, hi, lambda v: f"{v:.0f}") + " | "
                + ratio_text(st["median"], mid, budget, censored) + " |")
    return [*lines, ""]
