"""Where the learning real-time iteration's step time goes (issue 43, item 2).

Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_step_profile [--systems cartpole,...]
        [--steps 60] [--repeats 3] [--calls 200] [--out benchmarks/results/rti_step_profile]

Two measurements per system, in one process, interleaved:

1. **Closed loops** (``--repeats`` blocks of ``--steps`` periods from ``env.reset(seed=100 +
   block)``, the four controllers alternating, the order flipped every block): the nominal
   one-call RTI (``make_mpc(env, "nominal", scheme="rti")``), the nominal split RTI, and the
   learning RTIs (``make_mpc(env, "robust", scheme=...)`` pretrained on
   ``collect_initial_data(env, 200, seed=100 + block)`` before each block, untimed).
   Per episode the median over the steps after the first of the whole ``act`` call (one-call)
   and of the latency (split: ``act_time - preparation_time``); the ratio learning / nominal
   per block, and its median over the blocks.
2. **Pieces** of the learning one-call step, each called ``--calls`` times at the plan and state
   where the last closed loop stopped, each compiled piece as its own
   :class:`~gp_agents.pseudospectral.BufferedFunction` (the step's own calling convention):
   the whole compiled step; the learned term's expansion at the shifted plan's nodes; the
   expansion with the Jacobian gap's adjoint correction (a term with one); the QP step alone
   with the expanded parameters (its active-set iterations); the expansion error at the new
   plan; the nominal compiled step at the same point; and the Python-side learner pieces: one
   sample's ``learner.update``, its LAPACK factor updates and weight solves alone, and the
   export of its parameters (``expansion_param_values``).

The report (``report.md``) is generated from the measured numbers (``profile.json``).
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from gp_agents.mpc.diagnostics import StepStatus

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "benchmarks" / "results" / "rti_step_profile"
SCENARIOS = {"cartpole": "online", "quadrotor": "online", "dubins": "paper",
             "pendulum": "damped"}
BASE_SEED = 100


def _median_ms(values: np.ndarray) -> float:
    rest = values[1:] if len(values) > 1 else values
    return float(np.median(rest) * 1e3)


def _time(fn: Callable[[], Any], calls: int) -> float:
    """Median milliseconds of ``calls`` calls of ``fn`` (after one untimed call)."""
    fn()
    out = []
    for _ in range(calls):
        start = time.perf_counter()
        fn()
        out.append(time.perf_counter() - start)
    return float(np.median(out) * 1e3)


def closed_loop(env: Any, agent: Any, seed: int, steps: int) -> dict[str, Any]:
    obs, _ = env.reset(seed=seed)
    agent.reset()
    for _ in range(steps):
        u = agent.act(obs)
        nxt, _, term, trunc, _ = env.step(u)
        agent.observe(obs, u, nxt)
        obs = nxt
        if term or trunc:
            break
    d = agent.diagnostics_arrays()
    act, prep = np.asarray(d["act_time"], float), np.asarray(d["preparation_time"], float)
    status = [str(s) for s in d["status"][1:]]
    plain = np.array([False] + [s == StepStatus.RTI for s in status])
    return {"act_ms": _median_ms(act), "latency_ms": _median_ms(act - prep),
            "plain_act_ms": float(np.median(act[plain]) * 1e3) if plain.any() else np.nan,
            "plain_latency_ms": (float(np.median((act - prep)[plain]) * 1e3) if plain.any()
                                 else np.nan),
            "preparation_ms": _median_ms(prep), "steps": len(act),
            "plain": sum(s == StepStatus.RTI for s in status),
            "recovered": sum(s == StepStatus.RTI_RECOVERED for s in status),
            "rejected": sum(s == StepStatus.RTI_REJECTED for s in status), "obs": obs}


def pieces(nominal: Any, learning: Any, obs: np.ndarray, calls: int) -> dict[str, Any]:
    """The learning one-call step's pieces at ``learning``'s current plan (module doc)."""
    import casadi as ca

    from gp_agents.pseudospectral import BufferedFunction

    pl, term = learning.planner, learning.planner.planning.term
    p, theta = pl.planning.param_values(), term.expansion_param_values()
    w_prev = learning.plan.solution.nlp_x
    step = pl._learned_step(theta.size)
    args = [w_prev, obs, p, theta]
    if step.fn.n_in() == 5:
        args.append(pl._multipliers(learning.plan))
    out: dict[str, Any] = {"theta_size": int(theta.size)}
    out["compiled step"] = _time(lambda: step(*args), calls)
    ws = np.asarray(pl._shift(w_prev, obs)).ravel()
    n_w = pl.ocp.n_variables
    W = ca.MX.sym("w", n_w)
    T = ca.MX.sym("theta", theta.size)
    expansion = BufferedFunction(ca.Function(
        "profile_expansion", [W, T], [ca.vec(term.node_param_expr(*pl._nodes(W), T))]))
    Q = expansion(ws, theta)[0]
    out["expansion"] = _time(lambda: expansion(ws, theta), calls)
    P_full = np.concatenate([p, Q])
    grad_offset = np.zeros(n_w)
    if step.fn.n_in() == 5:  # the gap's gradient comes from the expansion's Jacobians
        Pm = ca.MX.sym("P", P_full.size)
        offset, lam_sym = pl._gap_offset(W, Pm, T, theta.size,
                                         term.node_expansion_expr(*pl._nodes(W), T))
        gap = BufferedFunction(ca.Function("profile_gap", [W, Pm, T, lam_sym],
                                           [ca.densify(offset)]))
        lam = args[4]
        grad_offset = gap(ws, P_full, theta, lam)[0]
        out["expansion + gap correction"] = _time(lambda: gap(ws, P_full, theta, lam), calls)
    qp = BufferedFunction(pl._qp_step)
    res = qp(ws, P_full, grad_offset)
    out["qp iterations"] = float(res[5][0])
    out["QP step"] = _time(lambda: qp(ws, P_full, grad_offset), calls)
    w_new = res[0]
    M, n_q = pl.ocp.node_indices()[0].shape[0], term.n_node_params()
    Qm = ca.MX.sym("Q", n_q, M)
    error = BufferedFunction(ca.Function("profile_error", [W, Qm, T],
                                         [term.plan_error_expr(*pl._nodes(W), Qm, T)]))
    out["expansion error"] = _time(lambda: error(w_new, Q, theta), calls)
    npl = nominal.planner
    p_nom = npl.planning.param_values()
    out["nominal compiled step"] = _time(lambda: npl._step(w_prev, obs, p_nom), calls)
    learner = learning.learner
    X = np.array([obs, obs])
    U = np.array([learning.plan.action(learning.plan.step, learning.model.u_lb,
                                       learning.model.u_ub)] * 2)
    Z, Y = learning.residual.targets(X[:1], U[:1], X[1:])
    scratch = copy.deepcopy(learner)
    out["learner update (1 sample)"] = _time(lambda: scratch.update(Z, Y), calls)
    # its LAPACK floor: the factor updates (one dtpqrt per output with the sample's row and
    # the restored prior row) and the weights' two triangular solves per output
    from gp_agents.learners.cholesky_update import cholesky_add_rows

    rows = np.ones((2, learner._chol[0].shape[0])) * 1e-3
    out["factor updates (dtpqrt)"] = _time(
        lambda: [cholesky_add_rows(R, rows, 0.99) for R in learner._chol], calls)

    def weights() -> None:
        scratch._weights_cache = None
        scratch.weights_  # noqa: B018

    out["weights solves"] = _time(weights, calls)
    out["parameter export"] = _time(term.expansion_param_values, calls)
    out["planning.param_values"] = _time(pl.planning.param_values, calls)
    return out


class _Timed:
    """Calls ``call`` and adds its wall time to ``into[agent._step]`` (the step it served); a
    BufferedFunction's ``fn`` (the Function) stays readable as ``.fn``."""

    def __init__(self, call: Callable[..., Any], into: dict[int, float], agent: Any) -> None:
        self._call, self._into, self._agent = call, into, agent
        if hasattr(call, "fn"):
            self.fn = call.fn

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return self._call(*args, **kwargs)
        finally:
            k = self._agent._step
            self._into[k] = self._into.get(k, 0.0) + time.perf_counter() - start


def act_breakdown(env: Any, agent: Any, data: Any, seed: int, steps: int) -> dict[str, float]:
    """Where the learning one-call ``act`` goes, on its plain RTI steps: one closed loop of
    ``steps`` periods with timers around the learner update (``_flush_learning``: the
    residual targets and ``learner.update``), the parameter export, the compiled step and the
    acceptance check (``_accept``, with the solution object); the rest of ``act`` is Python
    glue (state checks, the action, the diagnostics record). Median ms per piece."""
    agent.pretrain(data)
    planner = agent._planner()
    term = planner.planning.term
    times: dict[str, dict[int, float]] = {k: {} for k in (
        "learner update", "parameter export", "compiled step", "acceptance check")}
    theta = term.expansion_param_values()
    step = planner._learned_step(theta.size)
    agent._flush_learning = _Timed(agent._flush_learning, times["learner update"], agent)
    term.expansion_param_values = _Timed(term.expansion_param_values,
                                         times["parameter export"], agent)
    planner._learned_steps[theta.size, True] = _Timed(step, times["compiled step"], agent)
    planner._accept = _Timed(planner._accept, times["acceptance check"], agent)
    obs, _ = env.reset(seed=seed)
    agent.reset()
    for _ in range(steps):
        u = agent.act(obs)
        nxt, _, done, trunc, _ = env.step(u)
        agent.observe(obs, u, nxt)
        obs = nxt
        if done or trunc:
            break
    d = agent.diagnostics_arrays()
    plain = [int(k) for k, s in zip(d["step"], d["status"], strict=True)
             if s == StepStatus.RTI and int(k) > 0]
    act = dict(zip((int(k) for k in d["step"]), np.asarray(d["act_time"], float),
                   strict=True))
    out = {"act": float(np.median([act[k] for k in plain]) * 1e3)}
    for key, values in times.items():
        out[key] = float(np.median([values.get(k, 0.0) for k in plain]) * 1e3)
    out["rest of act (Python)"] = out["act"] - sum(out[k] for k in times)
    out["plain steps"] = len(plain)
    return out


def run_system(name: str, steps: int, repeats: int, calls: int) -> dict[str, Any]:
    import gymnasium as gym

    import gp_envs
    from gp_agents import collect_initial_data, make_mpc

    env = gym.make(gp_envs.SYSTEMS[name].env_id, scenario=SCENARIOS[name])
    agents: dict[str, Any] = {}
    for scheme in ("rti", "rti-split"):
        agents[f"nominal {scheme}"] = make_mpc(env, "nominal", scheme=scheme)
        agents[f"robust {scheme}"] = make_mpc(env, "robust", scheme=scheme)
    rows = []
    last_obs = None
    for block in range(repeats):
        # each block's learners pretrained on that seed's system (a reset may redraw the
        # nominal model, as the Dubins scenario's does), untimed
        data = collect_initial_data(env, 200, seed=BASE_SEED + block)
        for label, agent in agents.items():
            if label.startswith("robust"):
                agent.pretrain(data)
        order = list(agents) if block % 2 == 0 else list(reversed(agents))
        for label in order:
            agent = agents[label]
            r = closed_loop(env, agent, BASE_SEED + block, steps)
            if label == "robust rti":
                last_obs = r["obs"]
            rows.append({"system": name, "block": block, "controller": label,
                         **{k: v for k, v in r.items() if k != "obs"}})
    assert last_obs is not None
    parts = pieces(agents["nominal rti"], agents["robust rti"], last_obs, calls)
    breakdown = act_breakdown(env, make_mpc(env, "robust", scheme="rti"),
                              collect_initial_data(env, 200, seed=BASE_SEED), BASE_SEED, steps)
    return {"rows": rows, "pieces": parts, "act breakdown": breakdown,
            "term": type(agents["robust rti"].config.term).__name__,
            "qp_solver": repr(agents["robust rti"].config.scheme.qp_solver)}


def _ratio(rows: list[dict[str, Any]], a: str, b: str, key: str) -> list[float]:
    by = {(r["block"], r["controller"]): r for r in rows}
    return [by[(k, a)][key] / by[(k, b)][key] for k in sorted({r["block"] for r in rows})]


def write_report(out: Path, results: dict[str, Any], command: str, seconds: float) -> Path:
    lines = ["# Where the learning RTI step's time goes (issue 43, item 2)", "",
             "Generated by `benchmarks/studies/rti_step_profile.py` from `profile.json`.", "",
             f"Command: `{command}` ({seconds / 60:.1f} min)", "",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores (shared with other "
             f"work), Python {platform.python_version()}, "
             f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}; load average at the end "
             f"{' '.join(Path('/proc/loadavg').read_text().split()[:3])}.", "",
             "## Closed loops: learning vs nominal (medians; ratios within each block)", "",
             "| system | learned term | one-call step nominal (ms) | one-call step learning "
             "(ms) | ratio (median, min-max) | split latency nominal (ms) | split latency "
             "learning (ms) | ratio (median, min-max) | learning split preparation (ms) | "
             "learning RTI steps plain / recovered / rejected |",
             "|---|---|---:|---:|---|---:|---:|---|---:|---|"]
    for name, res in results.items():
        rows = res["rows"]

        def med(label: str, key: str, rows: list[dict[str, Any]] = rows) -> float:
            return float(np.median([r[key] for r in rows if r["controller"] == label]))

        one = _ratio(rows, "robust rti", "nominal rti", "act_ms")
        split = _ratio(rows, "robust rti-split", "nominal rti-split", "latency_ms")
        counts = [sum(r[k] for r in rows if r["controller"].startswith("robust"))
                  for k in ("plain", "recovered", "rejected")]
        lines.append(
            f"| {name} | {res['term']} | {med('nominal rti', 'act_ms'):.3f} "
            f"| {med('robust rti', 'act_ms'):.3f} "
            f"| {np.median(one):.2f} ({min(one):.2f}-{max(one):.2f}) "
            f"| {med('nominal rti-split', 'latency_ms'):.3f} "
            f"| {med('robust rti-split', 'latency_ms'):.3f} "
            f"| {np.median(split):.2f} ({min(split):.2f}-{max(split):.2f}) "
            f"| {med('robust rti-split', 'preparation_ms'):.3f} "
            f"| {counts[0]} / {counts[1]} / {counts[2]} |")
    lines += ["", "*plain steps*: the same medians over the accepted RTI steps only (status "
              "`RTI`: neither recovered nor replaced by a converged solve), so that the two "
              "controllers' step costs are compared on steps of the same kind (the nominal "
              "model's closed loops reject more steps on the cart pole and the Dubins vehicle, "
              "and their converged replacements dominate the medians above):", "",
              "| system | plain one-call step nominal (ms) | learning (ms) | ratio (median, "
              "min-max) | plain split latency nominal (ms) | learning (ms) | ratio (median, "
              "min-max) |", "|---|---:|---:|---|---:|---:|---|"]
    for name, res in results.items():
        rows = res["rows"]

        def pmed(label: str, key: str, rows: list[dict[str, Any]] = rows) -> float:
            return float(np.nanmedian([r[key] for r in rows if r["controller"] == label]))

        one = _ratio(rows, "robust rti", "nominal rti", "plain_act_ms")
        split = _ratio(rows, "robust rti-split", "nominal rti-split", "plain_latency_ms")
        lines.append(
            f"| {name} | {pmed('nominal rti', 'plain_act_ms'):.3f} "
            f"| {pmed('robust rti', 'plain_act_ms'):.3f} "
            f"| {np.nanmedian(one):.2f} ({np.nanmin(one):.2f}-{np.nanmax(one):.2f}) "
            f"| {pmed('nominal rti-split', 'plain_latency_ms'):.3f} "
            f"| {pmed('robust rti-split', 'plain_latency_ms'):.3f} "
            f"| {np.nanmedian(split):.2f} ({np.nanmin(split):.2f}-{np.nanmax(split):.2f}) |")
    lines += ["", "Targets of the issue: one-call ratio <= 1.5, split-latency ratio <= 1.2.",
              "", "## Pieces of the learning one-call step (median ms per call)", ""]
    keys = ["compiled step", "expansion", "expansion + gap correction", "QP step",
            "qp iterations", "expansion error", "nominal compiled step",
            "learner update (1 sample)", "factor updates (dtpqrt)", "weights solves",
            "parameter export", "planning.param_values", "theta_size"]
    lines += ["| piece | " + " | ".join(results) + " |",
              "|---|" + "---:|" * len(results)]
    for k in keys:
        cells = []
        for res in results.values():
            v = res["pieces"].get(k)
            cells.append("-" if v is None else (f"{v:.0f}" if k in ("qp iterations",
                                                                    "theta_size")
                                                else f"{v:.3f}"))
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    lines += ["", "## The learning one-call `act` on its plain steps (median ms; one closed "
              f"loop of the robust recipe from seed {BASE_SEED} per system)", "",
              "| piece | " + " | ".join(results) + " |", "|---|" + "---:|" * len(results)]
    for k in ("act", "learner update", "parameter export", "compiled step",
              "acceptance check", "rest of act (Python)"):
        lines.append(f"| {k} | " + " | ".join(
            f"{res['act breakdown'][k]:.3f}" for res in results.values()) + " |")
    lines += ["", "*learner update*: `_flush_learning` (the residual targets and "
              "`learner.update`); *acceptance check*: `_accept` (the safety net's test and "
              "the solution object); *rest*: `act` less the four (state checks, the action, "
              "the diagnostics record). Timers add a few microseconds per piece."]
    lines += ["", "*compiled step*: the learning one-call step's one compiled function (shift, "
              "expansion, gap correction, QP, error); the next four rows are its pieces built "
              "as functions of their own (they overlap the whole only approximately: "
              "separate calls). *QP step*: the active-set QP with the expanded parameters, "
              "*qp iterations* its active-set iterations at this point. *learner update*: "
              "`IncrementalSSGP.update` with one transition (numpy/LAPACK; with the recipe's "
              "change detector and nominal fallback each sample is predicted first). "
              "*factor updates*: its LAPACK part, one `dtpqrt` per output adding two rows "
              "(the sample's and a restored prior coordinate's); *weights solves*: the two "
              "triangular solves per output for the weights (done once per update, by the "
              "export or the next prediction). "
              "*parameter export*: `expansion_param_values()` (the weights' solves and the "
              "packing into the CasADi vector of *theta_size* numbers: the mean-only vector, "
              "`casadi_mean_param_values`). *expansion + gap correction*: the expansion and "
              "the adjoint correction computed from its Jacobians, as in the step.", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", default="cartpole,quadrotor,dubins,pendulum")
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--calls", type=int, default=200)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    results = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in args.systems.split(","):
            results[name] = run_system(name, args.steps, args.repeats, args.calls)
            print(name, json.dumps(results[name]["pieces"]), flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "profile.json").write_text(json.dumps(results, indent=1))
    command = "OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_step_profile " + " ".join(
        sys.argv[1:] if argv is None else argv)
    path = write_report(args.out, results, command.strip(), time.perf_counter() - started)
    print(f"report: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
