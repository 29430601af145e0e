"""One trial: its specification, its execution, and the metrics of one episode.

A trial is the unit the runner schedules, stores (one file each) and resumes. Most trials are
closed-loop episodes (``kind="episode"``): build a controller (:mod:`benchmarks.controllers`),
reset the env with the trial's seed, run ``agent.act`` / ``env.step`` / ``agent.observe`` to the
end, and compute the metrics of :func:`episode_metrics`. Other kinds measure compute
(:mod:`benchmarks.compute`) or compare with a peer library (:mod:`benchmarks.peers`).

:func:`execute` never raises: a failing trial returns ``status="error"`` with the traceback, an
unavailable controller ``status="unavailable"`` with the reason; the runner records both.
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import subprocess
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import gp_envs
from benchmarks.controllers import (
    CONTROLLERS,
    ENVS,
    N_INITIAL_POINTS,
    BuiltController,
    ControllerUnavailableError,
    build_controller,
    check_env_scenario,
    check_name,
    make_env,
    scenario_changes,
)
from benchmarks.systems import benchmark_system
from gp_agents.agent import rollout
from gp_agents.mpc import Constraints

DISTRIBUTION = "gp-pseudospectral-mpc"
"""The distribution (``pip install`` name) of this package, for :func:`code_version`."""

EPISODE_KINDS = ("episode", "trials")
"""Trial kinds that run closed-loop episodes (``"trials"``: several, :func:`run_trials`)."""

STATUS_OK = "ok"
STATUS_ERROR = "error"
STATUS_UNAVAILABLE = "unavailable"


DATA_SOURCES = ("same", "diff", "own")
"""Values of :attr:`Cell.data`."""
STARTS = ("default", "perturbed")
"""Values of :attr:`Cell.start`."""


@dataclass(frozen=True, order=True)
class Cell:
    """How an episode's system, data and start differ from the scenario's defaults (the
    robustness envelope; all defaults: the scenario as registered).

    Attributes:
        randomize: the env's ``randomize`` (relative spread of the true parameters per reset).
        data: where the learning recipes' initial data come from when the truth is
            randomized: ``"same"``, the system then controlled (the episode's truth draw);
            ``"diff"``, an independent draw of the same spread (the system changed between
            data collection and control). Without randomization both are the episode's truth.
            ``"own"``: as a user collects them, ``gp_agents.collect_initial_data(env, n,
            seed=seed)`` on the trial's own env (the system ``env.reset(seed=seed)`` gives; in
            a time-varying scenario the data episodes see its changes).
        noise: the env's ``observation_noise``: standard deviation added to every observed
            component, in its unit (m, rad, m/s, rad/s), during data collection and control.
        start: ``"default"`` (the env's reset) or ``"perturbed"`` (the reset state plus a
            seeded uniform offset within the system's registered ``perturbation`` widths;
            cart pole: x0 +-0.5 m, theta0 +-0.3 rad, rates +-0.1).
        kappa: the MPC's ``uncertainty_radius`` (the paper's U_r scale of the obstacle margin).
    """

    randomize: float = 0.0
    data: str = "same"
    noise: float = 0.0
    start: str = "default"
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if self.data not in DATA_SOURCES:
            raise ValueError(f"Cell.data must be one of {list(DATA_SOURCES)}, got {self.data!r}")
        if self.start not in STARTS:
            raise ValueError(f"Cell.start must be one of {list(STARTS)}, got {self.start!r}")
        for name in ("randomize", "noise", "kappa"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Cell.{name} must be a finite number >= 0, got {value!r}")

    @property
    def key(self) -> str:
        """Key suffix: empty for the default cell (so that existing trial names stay)."""
        parts = []
        if self.randomize:
            parts.append(f"r{self.randomize:g}")
        if self.data != "same":
            parts.append(f"d{self.data}")
        if self.noise:
            parts.append(f"noise{self.noise:g}")
        if self.start != "default":
            parts.append(self.start)
        if self.kappa:
            parts.append(f"k{self.kappa:g}")
        return "_".join(parts)

    def describe(self) -> str:
        """One line for tables: ``"fixed truth"`` or e.g. ``"randomize 0.1, diff data"``."""
        parts = []
        if self.randomize:
            parts.append(f"randomize {self.randomize:g}, {self.data} data")
        if self.noise:
            parts.append(f"noise {self.noise:g}")
        if self.start != "default":
            parts.append(f"{self.start} start")
        if self.kappa:
            parts.append(f"kappa {self.kappa:g}")
        return ", ".join(parts) or "fixed truth"


@dataclass(frozen=True, order=True)
class TrialSpec:
    """What to run; the :attr:`key` names the trial's file.

    Attributes:
        kind: ``"episode"``, or a measurement of :data:`JOB_KINDS` (``"ssgp-act-scaling"``,
            ``"ssgp-update-time"``, ``"peers"``).
        env: benchmark env short name (:data:`benchmarks.controllers.ENVS`).
        scenario: the env's scenario.
        controller: controller name (episodes), or the measurement's subject.
        seed: seeds the env resets, the initial data and anything random in the trial.
        param: the measurement's parameter (samples learned, SSGP rank r), else None.
        max_steps: stop the episode after this many steps (smoke runs), None for the full one.
        n_init: initial transitions collected for the learning recipes.
        cell: the episode's variation of system, data and start (:class:`Cell`; a dict of
            its fields is accepted, as stored in trial files).
        models: the user's RL model directory, absolute (``gp-bench --models``, or the
            ``./benchmarks/models`` of the command's directory), which the RL recipes look in
            before the shipped models (:func:`benchmarks.controllers.rl_model_dirs`); it
            travels with the spec to the worker processes. Not part of the :attr:`key` nor of
            the comparisons (the trial is the same; its record names the model it ran), and
            left out of :meth:`to_dict` when None.
    """

    kind: str
    env: str
    scenario: str
    controller: str
    seed: int
    param: int | None = None
    max_steps: int | None = None
    n_init: int = N_INITIAL_POINTS
    cell: Cell = Cell()
    models: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if isinstance(self.cell, dict):
            object.__setattr__(self, "cell", Cell(**self.cell))

    @property
    def key(self) -> str:
        """File-name-safe unique name of the trial."""
        parts = [self.kind, self.env, self.scenario, self.controller, f"s{self.seed}"]
        if self.cell.key:
            parts.append(self.cell.key)
        if self.param is not None:
            parts.append(f"p{self.param}")
        if self.n_init != N_INITIAL_POINTS:
            parts.append(f"n{self.n_init}")
        if self.max_steps is not None:
            parts.append(f"t{self.max_steps}")
        return "_".join(parts)

    def validate(self) -> None:
        """Raise :class:`benchmarks.controllers.UnknownNameError` for unknown names."""
        check_name("trial kind", self.kind, list(JOB_KINDS))
        check_env_scenario(self.env, self.scenario)
        if self.kind in EPISODE_KINDS:
            check_name("controller", self.controller, list(CONTROLLERS))

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (stored in the trial file; without ``models`` when it is None)."""
        out = asdict(self)
        if out["models"] is None:
            del out["models"]
        return out


def _percentile(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def build_episode(spec: TrialSpec) -> tuple[Any, BuiltController, dict[str, Any] | None]:
    """The env, the controller (initial data collected and learned) and the reset options of
    episode ``spec``, exactly as :func:`run_episode` runs it; the env is reset with the seed.

    Raises:
        ControllerUnavailableError: the controller cannot run on this env/scenario.
    """
    cell = spec.cell
    env = make_env(spec.env, spec.scenario, randomize=cell.randomize,
                   observation_noise=cell.noise)
    options = _start_options(env, spec)
    built = build_controller(spec.controller, env, spec.env, spec.seed, spec.n_init,
                             data_env=None if cell.data == "own" else _data_env(env, spec),
                             same_system=cell.data == "own",
                             settings={"constraints": Constraints(uncertainty_radius=cell.kappa)}
                             if cell.kappa else None,
                             options=options, models=spec.models)
    return env, built, options


def interaction_time(initial_steps: int, dt: float, final_info: dict[str, Any],
                     earlier_steps: int = 0) -> float:
    """Interaction time (s) before success: the initial data's ``initial_steps`` and the
    ``earlier_steps`` of earlier (failed) trials at ``dt`` each, plus the time within the
    episode at which its final stretch at the goal began (``final_info["at_goal_since"]``,
    the env's; the episode ended successfully: ``final_info["success"]``); NaN if it did not."""
    since = final_info.get("at_goal_since")
    if not final_info.get("success") or since is None:
        return float("nan")
    return (int(initial_steps) + int(earlier_steps)) * float(dt) + float(since)


def run_episode(spec: TrialSpec) -> dict[str, Any]:
    """Run one closed-loop episode; returns ``{"metrics": ..., "arrays": ...}``.

    Raises:
        ControllerUnavailableError: the controller cannot run on this env/scenario.
    """
    t_build = time.perf_counter()
    env, built, options = build_episode(spec)
    build_s = time.perf_counter() - t_build
    out = _episode_result(spec, env, built, options, build_s)
    env.close()
    return {"metrics": out["metrics"], "arrays": out["arrays"]}


def _episode_result(spec: TrialSpec, env: Any, built: BuiltController,
                    options: dict[str, Any] | None, build_s: float) -> dict[str, Any]:
    """Run the episode of ``built`` on ``env``: ``{"metrics", "arrays", "episode"}``."""
    recipe = CONTROLLERS[spec.controller]
    agent = built.agent
    goal = np.asarray(gp_envs.nominal_model(env).task.goal, float)
    t_episode = time.perf_counter()
    episode = rollout(env, agent, spec.seed, options=options, max_steps=spec.max_steps)
    episode_s = time.perf_counter() - t_episode
    observations, info, steps = episode.observations, episode.final_info, episode.steps
    success_arr = np.array([bool(i["success"]) for i in episode.infos])
    violations = np.array([bool(i["constraint_violation"]) for i in episode.infos])
    times = np.array([float(i["time"]) for i in episode.infos])
    first = int(np.argmax(success_arr)) if success_arr.any() else -1
    if episode.terminated:
        termination = info.get("termination_reason") or "terminated"
    elif episode.truncated:
        termination = "time limit"
    else:
        termination = "max steps"
    # the true final state (observations may be noisy; an outside env's are exact)
    final = (observations[-1] if ENVS[spec.env].outside is not None
             else gp_envs.oracle_state(env))
    position_error = float("nan")
    k = benchmark_system(spec.env).position_dims
    if k:
        position_error = float(np.linalg.norm(final[:k] - goal[:k]))
    recovery = _recovery_time(env, spec, observations, times, goal)
    act = episode.act_times
    is_mpc = recipe.family == "mpc"
    episodic = is_mpc and recipe.mode == "episodic"
    # episodic plans are scored at the plan's final time (the paper's reading; an open-loop plan
    # of an unstable system cannot hold the goal), receding ones by the env's held criterion
    at_goal_final = bool(info.get("at_goal", False))
    learning = recipe.learner is not None
    data_steps = built.prior_data_steps + (steps if is_mpc else 0)
    dt = float(gp_envs.nominal_model(env).dt)
    since = info.get("at_goal_since")
    metrics: dict[str, Any] = {
        "family": recipe.family,
        "mode": recipe.mode if is_mpc else "policy",
        "success": at_goal_final if episodic else bool(success_arr[-1]),
        "success_held": bool(success_arr[-1]),
        "at_goal_final": at_goal_final,
        "time_to_success_s": times[first] if first >= 0 else float("nan"),
        # when the final stretch held at the goal began (s into the episode; NaN: no success)
        "at_goal_since_s": (float(since) if bool(success_arr[-1]) and since is not None
                            else float("nan")),
        # initial data plus that: the interaction time before success (issue 44's headline)
        "interaction_s": interaction_time(built.prior_data_steps if learning else 0, dt, info)
        if not episodic else float("nan"),
        "cost": episode.cost,
        # the env's own return (gp_envs envs: minus the cost; an outside env's reward is its own)
        "return": float(np.sum(episode.rewards)),
        "final_distance": float(info.get("distance_to_goal", np.nan)),
        "final_position_error": position_error,
        "recovery_s": recovery,
        "violations": int(np.sum(violations)),
        "termination": termination,
        "steps": steps,
        "data_steps": int(data_steps),
        "initial_data_steps": int(built.prior_data_steps if learning else 0),
        "act_median_ms": 1e3 * _percentile(act, 50),
        "act_p95_ms": 1e3 * _percentile(act, 95),
        "act_max_ms": 1e3 * float(act.max()) if act.size else float("nan"),
        "solver_failures": int(agent.counts.failures) if is_mpc else float("nan"),
        "capped_solves": int(agent.counts.capped) if is_mpc else float("nan"),
        "plan_plant_defect": _plan_plant_defect(env, agent) if episodic else float("nan"),
        "fallbacks": int(agent.counts.fallbacks) if is_mpc else float("nan"),
        "solves": int(agent.counts.solves) if is_mpc else float("nan"),
        # changes the learner's ChangeDetector declared (adaptive recipes; NaN without one)
        "learner_changes": (int(agent.learner.n_changes_) if is_mpc and getattr(
            getattr(agent, "learner", None), "detector_", None) is not None else float("nan")),
        # the episode's fallback paths (PseudospectralMPC.health; degraded: > 10% of replans)
        "rti_steps": int(agent.health()["rti_steps"]) if is_mpc else float("nan"),
        "rti_recovered": int(agent.health()["rti_recovered"]) if is_mpc else float("nan"),
        "rti_recovery_iterations": (int(agent.health()["rti_recovery_iterations"]) if is_mpc
                                    else float("nan")),
        "rti_rejected": int(agent.health()["rti_rejected"]) if is_mpc else float("nan"),
        # steps whose learned residual was not in the plan: switched off by the learner's
        # nominal fallback (it predicted the newest samples worse than the nominal model), or
        # the learned plan replaced by the nominal one (Converged(nominal_above=...)); NaN
        # without learning
        "residual_off_steps": (int(np.sum(~np.asarray(agent.diagnostics_arrays()
                                                      ["residual_on"], bool)))
                               if is_mpc and learning and agent.diagnostics else float("nan")),
        "degraded": bool(agent.health()["degraded"]) if is_mpc else False,
        "build_s": build_s,
        "episode_s": episode_s,
        **{f"recipe_{k}": v for k, v in built.info.items()},
    }
    arrays: dict[str, np.ndarray] = {
        "obs": observations,
        "action": episode.actions,
        "reward": episode.rewards,
        "success": success_arr,
        "constraint_violation": violations,
        "time": times,
        "act_time": act,
        "goal": goal,
    }
    if is_mpc:
        for name, value in agent.diagnostics_arrays().items():
            arrays[f"diag_{name}"] = value
    return {"metrics": metrics, "arrays": arrays, "episode": episode}


MAX_TRIALS = 5
"""Most controlled trials of a multi-trial run (``kind="trials"``): PILCO needed 5 in GP-MPC's
comparison."""


def run_trials(spec: TrialSpec) -> dict[str, Any]:
    """Trials on one system until success (``kind="trials"``), GP-MPC's protocol.

    Trial 1 is :func:`run_episode`'s episode (its metrics are this trial's metrics). While it
    has not succeeded, a learning recipe runs another trial, up to :data:`MAX_TRIALS`: a fresh
    agent of the same recipe pretrained on every transition so far (the initial data and every
    earlier trial's), learning online as always, from a new start on the same system
    (``env.reset(options={"keep_system": True})``, the env's own start distribution continuing
    from the seeded first reset). Recipes that learn nothing run one trial.

    Added metrics: ``trials`` (run), ``trials_to_success`` (NaN: none within the limit),
    ``interaction_trials_s`` (the initial data, every failed trial's steps, and the successful
    trial's ``at_goal_since``; NaN: no success), ``trial_costs`` / ``trial_successes``
    (per trial, as text) and ``data_steps_trials`` (env steps of data used by the end).

    Raises:
        ControllerUnavailableError: the controller cannot run on this env/scenario.
        ValueError: a controller not built from a library recipe (``make_mpc``).
    """
    from gp_agents import Transitions, make_mpc

    recipe = CONTROLLERS[spec.controller]
    if recipe.family != "mpc" or recipe.recipe is None:
        raise ValueError(f"multi-trial runs take a recipe-built MPC (<recipe>-mpc), got "
                         f"{spec.controller!r}")
    t_build = time.perf_counter()
    env, built, options = build_episode(spec)
    first = _episode_result(spec, env, built, options, time.perf_counter() - t_build)
    metrics, arrays = dict(first["metrics"]), dict(first["arrays"])
    episode = first["episode"]
    dt = float(gp_envs.nominal_model(env).dt)
    learning = recipe.learner is not None
    data = built.data
    initial = len(data) if data is not None else 0
    costs, successes = [episode.cost], [episode.success]
    earlier = 0
    while learning and not episode.success and len(costs) < MAX_TRIALS:
        earlier += episode.steps
        new = Transitions(episode.observations[:-1], episode.actions.astype(np.float32)
                          .astype(float), episode.observations[1:])
        data = new if data is None else Transitions(*(np.concatenate([a, b]) for a, b in zip(
            (data.X, data.U, data.X_next), (new.X, new.U, new.X_next), strict=True)))
        settings = ({"constraints": Constraints(uncertainty_radius=spec.cell.kappa)}
                    if spec.cell.kappa else {})
        agent = make_mpc(env, recipe.recipe, scheme=recipe.scheme, **settings)
        agent.pretrain(data)
        episode = rollout(env, agent, None, options={"keep_system": True},
                          max_steps=spec.max_steps)
        costs.append(episode.cost)
        successes.append(episode.success)
        k = len(costs)
        arrays[f"trial{k}_obs"] = episode.observations
        arrays[f"trial{k}_action"] = episode.actions
    k = len(costs)
    metrics.update({
        "trials": k,
        "trials_to_success": k if episode.success else float("nan"),
        "interaction_trials_s": interaction_time(initial, dt, episode.final_info, earlier),
        "trial_costs": " ".join(f"{c:.3f}" for c in costs),
        "trial_successes": "".join("1" if x else "0" for x in successes),
        "data_steps_trials": int(initial + earlier + episode.steps),
    })
    env.close()
    return {"metrics": metrics, "arrays": arrays}


RECOVERY_TOLERANCE = 0.01
"""Position error (m) within which a time-varying episode counts as recovered."""


def _recovery_time(env: Any, spec: TrialSpec, observations: np.ndarray, times: np.ndarray,
                   goal: np.ndarray) -> float:
    """Seconds from a time-varying scenario's first change until the position error (the
    system's ``position_dims``) is below :data:`RECOVERY_TOLERANCE` for the rest of the episode;
    NaN if it never is, or for a scenario without changes or a system without a position.

    Args:
        observations: (T + 1, n) observed states (t = 0 first). times: (T,) the time after
            each step, s. goal: (n,) the goal state.
    """
    changes = scenario_changes(spec.env, spec.scenario)
    k = benchmark_system(spec.env).position_dims
    if not changes or not k or spec.cell.noise:
        return float("nan")
    t = np.concatenate([[0.0], times])
    err = np.linalg.norm(observations[:, :k] - goal[:k], axis=1)
    outside = np.flatnonzero((err >= RECOVERY_TOLERANCE) | (t < changes[0].time))
    if outside.size and outside[-1] == len(t) - 1:
        return float("nan")
    first_in = outside[-1] + 1 if outside.size else 0
    return float(t[first_in] - changes[0].time)


def _start_options(env: Any, spec: TrialSpec) -> dict[str, Any] | None:
    """Reset options of the episode: None, or the perturbed start state of ``spec.cell``."""
    if spec.cell.start == "default":
        return None
    env.reset(seed=spec.seed)  # the env's own start for this seed, then a seeded offset
    width = benchmark_system(spec.env).perturbation
    if width is None:
        raise ValueError(f"system {spec.env!r} has no perturbation widths "
                         f"(benchmarks.systems): no perturbed start")
    width = np.asarray(width, float)
    offset = np.random.default_rng([spec.seed, 0x7374617274]).uniform(-width, width)
    return {"state": gp_envs.oracle_state(env) + offset}


def _data_env(env: Any, spec: TrialSpec) -> Any:
    """The env the learning recipes collect their initial data on (see :class:`Cell`): the
    trial's env itself, except with randomized truth, where it is an env of the episode's
    own truth draw (``"same"``) or one of an independent draw (``"diff"``), and in a
    time-varying scenario, whose data come from the system before its changes."""
    cell = spec.cell
    varying = bool(scenario_changes(spec.env, spec.scenario))
    if not cell.randomize:
        return (make_env(spec.env, spec.scenario, observation_noise=cell.noise,
                         time_varying=False) if varying else None)
    if cell.data == "diff":
        other = make_env(spec.env, spec.scenario, randomize=cell.randomize,
                         observation_noise=cell.noise)
        other.reset(seed=spec.seed + 1_000_003)  # a draw no episode seed of the suite makes
        truth = dict(gp_envs.oracle_model(other).params)
    else:
        env.reset(seed=spec.seed)
        truth = dict(gp_envs.oracle_model(env).params)
    return make_env(spec.env, spec.scenario, true_params=truth, observation_noise=cell.noise,
                    time_varying=False)


def _plan_plant_defect(env: Any, agent: Any) -> float:
    """Largest one-period defect of an episodic agent's plan against the plant, inf-norm.

    For each period k of the plan: the plan's state at the period's end minus the plant's RK4
    step (``gp_envs.oracle_model(env).step``, what the env integrates) from the plan's state at
    its start under the plan's action. For the oracle's plan this measures the transcription
    alone; for the others it includes their model error.
    """
    plan, truth = agent.plan, gp_envs.oracle_model(env)
    if plan is None:
        return float("nan")
    sol, dt = plan.solution, truth.dt
    periods = round(float(sol.tf) / dt)
    worst = 0.0
    for k in range(periods):
        u = plan.action(plan.step + k, truth.u_lb, truth.u_ub)
        nxt = truth.step(sol.state(k * dt), u)
        worst = max(worst, float(np.max(np.abs(sol.state((k + 1) * dt) - nxt))))
    return worst


def _lazy(module: str, function: str) -> Callable[[TrialSpec], dict[str, Any]]:
    def run(spec: TrialSpec) -> dict[str, Any]:
        import importlib

        return getattr(importlib.import_module(module), function)(spec)

    run.__name__ = f"{module}.{function}"
    return run


JOB_KINDS: dict[str, Callable[[TrialSpec], dict[str, Any]]] = {
    "episode": run_episode,
    "trials": run_trials,
    "ssgp-act-scaling": _lazy("benchmarks.compute", "run_act_scaling"),
    "ssgp-update-time": _lazy("benchmarks.compute", "run_update_time"),
    "step-vs-nodes": _lazy("benchmarks.compute", "run_step_scaling"),
    "step-vs-horizon": _lazy("benchmarks.compute", "run_step_scaling"),
    "step-vs-rank": _lazy("benchmarks.compute", "run_step_scaling"),
    "peers": _lazy("benchmarks.peers", "run_peers"),
}
"""Trial kinds and the function that runs each."""


@functools.cache
def cpu_model() -> str:
    """The processor's model name (``/proc/cpuinfo``; ``platform.processor()`` elsewhere)."""
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


@functools.cache
def code_version() -> str:
    """Short git commit of the code that runs, with ``-dirty`` if tracked files under the
    packages differ from it; outside a checkout of this repository (an installed package, even
    in a virtual environment inside some other git repository) ``"v<package version>"``, or
    ``"unknown"``."""
    root = Path(__file__).resolve().parent.parent

    def git(*args: str) -> str:
        res = subprocess.run(["git", *args], capture_output=True, text=True, timeout=10,
                             cwd=root, check=True)
        return res.stdout.strip()

    try:
        if Path(git("rev-parse", "--show-toplevel")).resolve() != root:
            raise subprocess.SubprocessError("not a checkout of this repository")
        commit = git("rev-parse", "--short", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--",
                    "gp_envs", "gp_agents", "benchmarks/*.py", "pyproject.toml")
    except (OSError, subprocess.SubprocessError):
        try:
            return f"v{importlib.metadata.version(DISTRIBUTION)}"
        except importlib.metadata.PackageNotFoundError:
            return "unknown"
    return f"{commit}-dirty" if dirty else commit


def execute(spec: TrialSpec) -> dict[str, Any]:
    """Run a trial in this process; never raises.

    Returns:
        ``{"spec": dict, "status": "ok"|"error"|"unavailable", "message": str, "metrics": dict,
        "arrays": dict, "host": str, "code_version": str, "wall_s": float}``.
    """
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    start = time.perf_counter()
    out: dict[str, Any] = {"spec": spec.to_dict(), "status": STATUS_OK, "message": "",
                           "metrics": {}, "arrays": {}}
    try:
        spec.validate()
        result = JOB_KINDS[spec.kind](spec)
        out["metrics"], out["arrays"] = result["metrics"], result["arrays"]
    except ControllerUnavailableError as err:
        out.update(status=STATUS_UNAVAILABLE, message=str(err))
    except Exception:  # recorded: a benchmark run goes on
        out.update(status=STATUS_ERROR, message=traceback.format_exc(limit=20))
    out["host"] = os.uname().nodename
    out["cpu"] = cpu_model()
    out["code_version"] = code_version()
    out["wall_s"] = time.perf_counter() - start
    return out
