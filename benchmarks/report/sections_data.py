"""Report sections on data: data efficiency against the initial samples, and outside
simulators' own returns, each beside the published figures."""

from __future__ import annotations

import functools
import math
from collections import defaultdict
from typing import Any

from benchmarks.controllers import CONTROLLERS, ENVS, make_env
from benchmarks.presets import Experiment
from benchmarks.report import figures
from benchmarks.report.common import (
    Context,
    _env_model,
    _env_title,
    _fmt,
    _interval,
    _max_trials,
    _name,
    _seconds,
    controller_legend,
    markdown_table,
)
from benchmarks.report.figures import data_efficiency_figure
from benchmarks.report.published import PUBLISHED_ANCHORS, PUBLISHED_RETURNS


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
                _name(r["controller"]), _seconds(r["n_init"], dt) if learning else "-",
                r["episodes"],
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
        name = figures._save(data_efficiency_figure(env, [r for r in rows if r["episodes"]], dt),
                             ctx.out_dir, f"{exp.name}_{env}.png")
        lines += ["", f"### {_env_title(env, scenario)}", "", f"![data efficiency]({name})", ""]
        lines += markdown_table(header, body, ["---", "---:"] + ["---:"] * (len(header) - 2))
        lines += controller_legend(r["controller"] for r in rows)
        measures = what_it_measures(rows)
        if measures:
            lines += ["", measures]
        anchors = PUBLISHED_ANCHORS.get(env, ())
        if anchors:
            lines += ["", "Published figures (cited, not measured here) and how their setup "
                      "differs:", ""]
            lines += [f"- **{a.method}** ({a.source}): {a.setup}." for a in anchors]
    return lines


PRIOR_SUCCEEDS = 0.9
"""A nominal MPC success rate from which a data-efficiency table measures the physics prior."""
PRIOR_FAILS = 0.1
"""One up to which it measures what the learning recipes learn."""


def what_it_measures(rows: list[dict[str, Any]]) -> str:
    """The sentence saying what a data-efficiency table of summary ``rows`` measures, from its
    nominal MPC row (the physics prior with no data): the prior where the nominal MPC alone
    succeeds (success rate >= :data:`PRIOR_SUCCEEDS`), learning where it fails (<=
    :data:`PRIOR_FAILS`), both in between; empty without a nominal row."""
    nominal = [r for r in rows if r["controller"] == "nominal-mpc" and r["episodes"]]
    if not nominal:
        return ""
    r = nominal[0]
    n = int(r["episodes"])
    k = round(float(r["success_rate"]) * n)
    said = f"The nominal MPC alone, with no data, succeeds on {k} of {n} seeds here"
    if r["success_rate"] >= PRIOR_SUCCEEDS:
        return (f"**What this table measures: the prior.** {said}: the learning recipes' "
                "figures measure the physics prior they start from, not what they learn.")
    if r["success_rate"] <= PRIOR_FAILS:
        return (f"**What this table measures: learning.** {said}: what the learning recipes "
                "reach beyond it, they learned from the data.")
    return (f"**What this table measures: the prior and learning together.** {said}: part of "
            "the learning recipes' figures is the prior's.")


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
                _name(r["controller"]), r["n_init"] if learning else "-", r["episodes"],
                f"{_fmt(r['return_mean'], 1)} "
                f"{_interval(r['return_ci_low'], r['return_ci_high'], 1)}",
                f"{_fmt(r['success_rate'])} {_interval(r['success_ci_low'], r['success_ci_high'])}",
                _fmt(r["data_steps_mean"] * repeat, 0),
                _fmt(r["residual_off_steps_mean"], 1) if learning else "-",
                _fmt(r["act_median_ms"], 1), r["status"]])
        lines += ["", f"### {_env_title(env, scenario)}", ""]
        lines += markdown_table(header, body, ["---"] + ["---:"] * 7 + ["---"])
        lines += controller_legend(r["controller"] for r in rows)
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
