"""Compute measurements of the SSGP-MPC: step time against samples learned, update time against r.

Two trial kinds (scheduled and stored like episodes, see :mod:`benchmarks.trial`):

- ``"ssgp-act-scaling"`` (``param`` = samples learned before the episode, e.g. 200, 1000,
  5000): the trial's SSGP-MPC recipe (``spec.controller``, e.g. ``ssgp-mpc``) pretrained
  on the usual initial data, then fed
  ``param - n_init`` further transitions of the same crude data controller
  (:func:`gp_agents.collect_initial_data`, another seed) with ``IncrementalSSGP.update``; the
  env is reset with the trial's seed and one closed-loop episode is run with every ``act``
  timed. An SSGP's cost does not grow with the samples seen: this checks it.
- ``"ssgp-update-time"`` (``param`` = r, the number of frequencies): an
  ``online_ssgp(r)`` (the SSGP-MPC's learner recipe with ``r`` frequencies) fitted on the initial
  data, then ``learner.update`` timed on each of 200 further transitions, one sample at a time
  (what the MPC does at every control period).
- ``"step-vs-nodes"``, ``"step-vs-horizon"``, ``"step-vs-rank"`` (:data:`STEP_SCALING`;
  ``param`` = LG nodes of the receding interval, the horizon in milliseconds, or the SSGP's
  rank r): the trial's MPC recipe (converged or RTI, nominal or SSGP) with that one setting
  changed, run closed loop for ``max_steps`` periods with every ``act`` timed (the first, which
  builds the NLP, left out).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from benchmarks.controllers import build_controller, make_env
from benchmarks.trial import TrialSpec
from gp_agents.agent import rollout

N_TIMED_UPDATES = 200
"""Single-sample updates timed per ``ssgp-update-time`` trial."""


STEP_SCALING: dict[str, str] = {
    "step-vs-nodes": "LG nodes (receding interval)",
    "step-vs-horizon": "horizon (ms)",
    "step-vs-rank": "SSGP rank r (frequencies)",
}
"""The step-time scaling trial kinds and what their ``param`` is."""


def _extra_seed(seed: int) -> int:
    return 10_000 + seed


def run_act_scaling(spec: TrialSpec) -> dict[str, Any]:
    """SSGP-MPC step times over an episode after learning ``spec.param`` samples."""
    from gp_agents import collect_initial_data

    n_samples = int(spec.param if spec.param is not None else spec.n_init)
    if n_samples < spec.n_init:
        raise ValueError(f"param (samples learned) must be >= n_init={spec.n_init}")
    env = make_env(spec.env, spec.scenario)
    built = build_controller(spec.controller, env, spec.env, spec.seed, spec.n_init)
    agent = built.agent
    update_s = 0.0
    if n_samples > spec.n_init:
        extra = collect_initial_data(env, n_samples - spec.n_init, seed=_extra_seed(spec.seed))
        Z, Y = agent.config.residual.model(agent.model).targets(extra.X, extra.U, extra.X_next)
        t0 = time.perf_counter()
        agent.learner.update(Z, Y)
        update_s = time.perf_counter() - t0
    episode = rollout(env, agent, spec.seed, max_steps=spec.max_steps)
    act_times, info = episode.act_times, episode.final_info
    samples = agent.diagnostics_arrays()["learner_samples"]
    act = np.array(act_times)
    metrics = {
        "samples_before_episode": n_samples,
        "batch_update_s": update_s,
        "act_median_ms": 1e3 * float(np.median(act)),
        "act_p95_ms": 1e3 * float(np.percentile(act, 95)),
        "act_max_ms": 1e3 * float(act.max()),
        "steps": len(act_times),
        "success": bool(info["success"]),
        "cost": episode.cost,
        "solver_failures": int(agent.counts.failures),
    }
    env.close()
    return {"metrics": metrics, "arrays": {"act_time": act, "learner_samples": np.array(samples),
                                           "reward": episode.rewards}}


def run_update_time(spec: TrialSpec) -> dict[str, Any]:
    """Time ``IncrementalSSGP.update`` on single samples for ``r = spec.param``."""
    from gp_agents import collect_initial_data, online_ssgp
    from gp_agents.residual import ResidualModel

    r = int(spec.param if spec.param is not None else 50)
    env = make_env(spec.env, spec.scenario)
    data = collect_initial_data(env, spec.n_init, seed=spec.seed)
    extra = collect_initial_data(env, N_TIMED_UPDATES, seed=_extra_seed(spec.seed))
    residual = ResidualModel(env.unwrapped.nominal_model)
    Z0, Y0 = residual.targets(data.X, data.U, data.X_next)
    Z, Y = residual.targets(extra.X, extra.U, extra.X_next)
    learner = online_ssgp(r)
    t0 = time.perf_counter()
    learner.fit(Z0, Y0)
    fit_s = time.perf_counter() - t0
    times = np.empty(len(Z))
    for i in range(len(Z)):
        t0 = time.perf_counter()
        learner.update(Z[i:i + 1], Y[i:i + 1])
        times[i] = time.perf_counter() - t0
    env.close()
    metrics = {
        "r": r,
        "n_outputs": int(Y.shape[1]),
        "fit_s": fit_s,
        "update_median_ms": 1e3 * float(np.median(times)),
        "update_p95_ms": 1e3 * float(np.percentile(times, 95)),
        "update_max_ms": 1e3 * float(times.max()),
        "updates": len(times),
    }
    return {"metrics": metrics, "arrays": {"update_time": times}}


def run_step_scaling(spec: TrialSpec) -> dict[str, Any]:
    """One MPC recipe's step time with one setting changed (:data:`STEP_SCALING`)."""
    from gp_agents import RecedingHorizon, online_ssgp

    if spec.kind not in STEP_SCALING:
        raise ValueError(f"unknown step-scaling kind {spec.kind!r}; known: {list(STEP_SCALING)}")
    if spec.param is None or int(spec.param) < 1:
        raise ValueError(f"{spec.kind} needs param >= 1, got {spec.param}")
    value = int(spec.param)
    settings: dict[str, Any] = {}
    learner = None
    if spec.kind == "step-vs-nodes":
        settings["horizon"] = RecedingHorizon(n_nodes=value)
    elif spec.kind == "step-vs-horizon":
        settings["horizon"] = RecedingHorizon(value / 1000.0)
    else:
        learner = online_ssgp(value)
    env = make_env(spec.env, spec.scenario)
    built = build_controller(spec.controller, env, spec.env, spec.seed, spec.n_init,
                             settings=settings, learner=learner)
    agent = built.agent
    episode = rollout(env, agent, spec.seed, max_steps=spec.max_steps)
    act = np.asarray(episode.act_times[1:], float)
    planner = agent.planner
    metrics = {
        "act_median_ms": 1e3 * float(np.median(act)),
        "act_p95_ms": 1e3 * float(np.percentile(act, 95)),
        "steps": len(episode.act_times),
        "success": bool(episode.final_info["success"]),
        "cost": episode.cost,
        "solver_failures": int(agent.counts.failures),
        "rti_rejected": int(agent.counts.rti_rejected),
        "mesh": planner.mesh.describe(),
        "horizon_s": float(agent.config.schedule.horizon),
        "rank": int(getattr(agent.learner, "n_frequencies", 0)),
    }
    env.close()
    return {"metrics": metrics, "arrays": {"act_time": act}}
