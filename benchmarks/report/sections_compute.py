"""Report sections on compute: step time against samples and settings, the SSGP update time,
and the comparison with do-mpc."""

from __future__ import annotations

from typing import Any

import numpy as np

from benchmarks.compute import STEP_SCALING
from benchmarks.presets import Experiment
from benchmarks.report import figures
from benchmarks.report.common import (
    Context,
    _fmt,
    _name,
    _row_key,
    controller_legend,
    markdown_table,
)
from benchmarks.report.figures import scaling_figure, step_scaling_figure, update_time_figure


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
    name = figures._save(fig, ctx.out_dir, f"{exp.name}_ssgp_act_scaling.png")
    lines = ["", "SSGP-MPC recipes (r = 50), seed 0, after learning N samples:",
             "", f"![act time vs samples]({name})", ""]
    lines += markdown_table(
        ["env", "scenario", "controller", "samples learned", "act median (ms)", "p95 (ms)",
         "max (ms)", "batch update (s)", "success", "cost"],
        [[r["env"], r["scenario"], _name(r.get("controller", "ssgp-mpc")), r["param"],
          r["act_median_ms"], r["act_p95_ms"], r["act_max_ms"], r["batch_update_s"],
          r["success"], r["cost"]] for r in rows], ["---"] * 3 + ["---:"] * 7)
    lines += controller_legend(c for _e, _s, c in groups)
    return lines


def section_step_scaling(ctx: Context, exp: Experiment) -> list[str]:
    """The converged and RTI step time against LG nodes, horizon and rank r."""
    keys = {s.key for s in exp.specs}
    rows = [r for r in ctx.compute_rows if r["measurement"] in STEP_SCALING
            and _row_key(r) in keys]
    if not rows:
        return []
    name = figures._save(step_scaling_figure(rows), ctx.out_dir, f"{exp.name}_step_scaling.png")
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
            [[f"{e} `{sc}`", _name(c), *[cell(by.get((e, sc, c, v))) for v in values]]
             for e, sc, c in groups], ["---", "---"] + ["---:"] * len(values))
        lines += controller_legend(c for _e, _s, c in groups)
    return lines


def section_update_time(ctx: Context, exp: Experiment) -> list[str]:
    """SSGP single-sample update time against the rank r."""
    keys = {s.key for s in exp.specs}
    rows = sorted((r for r in ctx.compute_rows if r["measurement"] == "ssgp-update-time"
                   and _row_key(r) in keys), key=lambda r: r["param"])
    if not rows:
        return []
    fig = update_time_figure(rows)
    name = figures._save(fig, ctx.out_dir, f"{exp.name}_ssgp_update_time.png")
    lines = ["", f"IncrementalSSGP.update on single samples ({rows[0]['updates']} timed updates "
             f"after a fit on the initial data; {rows[0]['n_outputs']} outputs, "
             f"{', '.join(sorted({str(r['env']) for r in rows}))}):", "",
             f"![update time vs r]({name})", ""]
    lines += markdown_table(["r", "median (ms)", "p95 (ms)", "max (ms)", "fit (s)"],
                            [[r["r"], r["update_median_ms"], r["update_p95_ms"],
                              r["update_max_ms"], r["fit_s"]] for r in rows], ["---:"] * 5)
    return lines


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
