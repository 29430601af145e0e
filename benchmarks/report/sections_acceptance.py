"""The report section of the MPC acceptance runs: headline numbers against the speed targets,
the RTI safety net's rejections and the linearized recipes' expansion errors."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from benchmarks.controllers import CONTROLLERS, learned_term
from benchmarks.presets import Experiment
from benchmarks.report.common import Context, _fmt, _name, controller_legend, markdown_table
from benchmarks.trial import EPISODE_KINDS
from gp_agents.mpc.diagnostics import StepStatus

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
            status = np.asarray(t.arrays["diag_status"]).astype(str)
            count = rejected[(t.spec.env, t.spec.scenario, t.spec.controller)]
            # RTI steps: accepted as they were, or rejected (recovered steps are neither)
            count[0] += int(np.count_nonzero(status == StepStatus.RTI_REJECTED))
            count[1] += int(np.count_nonzero(np.isin(status, [StepStatus.RTI,
                                                              StepStatus.RTI_REJECTED])))

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
            refs = [(base, f"the converged {_name(base)}'s"),
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
            text += (f" = **{ratio:.2f}x** the {_name(reference)}'s (target {target}x: "
                     f"{verdict})")
        n_rej, n_rti = rejected.get((env, scenario, c), (0, 0))
        if rti and n_rti:
            text += f"; {n_rej} of {n_rti} RTI steps rejected ({100 * n_rej / n_rti:.0f}%)"
        return text

    for c in order:
        r = get("cartpole", "online", c)
        if r:
            lines.append(f"- cart pole `online`, {_name(c)}: success "
                         f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, mean "
                         f"cost {_fmt(r['cost_mean'])}, {speed('cartpole', 'online', c, r)}")
    for scenario in ("gp", "online"):
        for c in order:
            r = get("quadrotor", scenario, c)
            if r:
                lines.append(f"- quadrotor `{scenario}`, {_name(c)}: final position error mean "
                             f"{_fmt(r['final_position_error_mean'], 4)} m (max "
                             f"{_fmt(r['final_position_error_max'], 4)} m), success "
                             f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, "
                             f"{speed('quadrotor', scenario, c, r)}")
    for c in order:
        r = get("dubins", "paper", c)
        if r:
            lines.append(f"- Dubins, {_name(c)}: goal reached "
                         f"{round(r['success_rate'] * r['episodes'])}/{r['episodes']}, "
                         f"episodes touching the obstacle {r['episodes_with_violation']}, "
                         f"{speed('dubins', 'paper', c, r)}")
    lines += controller_legend(c for c in order if any(k[2] == c and v["episodes"]
                                                      for k, v in by.items()))
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
            text += (f"; **{ratio:.2f}x** the {_name(ref)}'s {what} (target {target}x: "
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
        rows.append([f"{env} `{scenario}`", _name(c), e.size, float(np.median(e)),
                     float(np.percentile(e, 90)), float(np.mean(e > 1.0))])
    if not rows:
        return []
    table = markdown_table(["env", "controller", "solves", "median", "p90", "share > 1"], rows,
                           ["---", "---", "---:", "---:", "---:", "---:"])
    return ["", "Linearized recipes: error of the per-node expansion at the plan it produced, "
            "as a fraction of its tolerance (10% of the largest residual over the nodes plus "
            "1e-3, per output; <= 1 is within it), over all solves:", "", *table,
            *controller_legend(c for _e, _s, c in groups)]
