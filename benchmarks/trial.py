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
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

import gp_envs
from benchmarks.controllers import (
    CONTROLLERS,
    N_INITIAL_POINTS,
    ControllerUnavailableError,
    build_controller,
    check_env_scenario,
    check_name,
    make_env,
)
from gp_agents.agent import rollout

DISTRIBUTION = "gp-pseudospectral-mpc"
"""The distribution (``pip install`` name) of this package, for :func:`code_version`."""

STATUS_OK = "ok"
STATUS_ERROR = "error"
STATUS_UNAVAILABLE = "unavailable"


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
    """

    kind: str
    env: str
    scenario: str
    controller: str
    seed: int
    param: int | None = None
    max_steps: int | None = None
    n_init: int = N_INITIAL_POINTS

    @property
    def key(self) -> str:
        """File-name-safe unique name of the trial."""
        parts = [self.kind, self.env, self.scenario, self.controller, f"s{self.seed}"]
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
        if self.kind == "episode":
            check_name("controller", self.controller, list(CONTROLLERS))

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (stored in the trial file)."""
        return asdict(self)


def _percentile(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def run_episode(spec: TrialSpec) -> dict[str, Any]:
    """Run one closed-loop episode; returns ``{"metrics": ..., "arrays": ...}``.

    Raises:
        ControllerUnavailableError: the controller cannot run on this env/scenario.
    """
    env = make_env(spec.env, spec.scenario)
    recipe = CONTROLLERS[spec.controller]
    t_build = time.perf_counter()
    built = build_controller(spec.controller, env, spec.env, spec.seed, spec.n_init)
    build_s = time.perf_counter() - t_build
    agent = built.agent
    goal = np.asarray(env.unwrapped.nominal_model.task.goal, float)
    t_episode = time.perf_counter()
    episode = rollout(env, agent, spec.seed, max_steps=spec.max_steps)
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
    final = observations[-1]
    position_error = float("nan")
    if spec.env in ("quadrotor", "dubins"):
        k = 3 if spec.env == "quadrotor" else 2
        position_error = float(np.linalg.norm(final[:k] - goal[:k]))
    act = episode.act_times
    is_mpc = recipe.family == "mpc"
    episodic = is_mpc and recipe.mode == "episodic"
    # episodic plans are scored at the plan's final time (the paper's reading; an open-loop plan
    # of an unstable system cannot hold the goal), receding ones by the env's held criterion
    at_goal_final = bool(info.get("at_goal", False))
    learning = recipe.learner is not None
    data_steps = built.prior_data_steps + (steps if is_mpc else 0)
    metrics: dict[str, Any] = {
        "family": recipe.family,
        "mode": recipe.mode if is_mpc else "policy",
        "success": at_goal_final if episodic else bool(success_arr[-1]),
        "success_held": bool(success_arr[-1]),
        "at_goal_final": at_goal_final,
        "time_to_success_s": times[first] if first >= 0 else float("nan"),
        "cost": episode.cost,
        "final_distance": float(info.get("distance_to_goal", np.nan)),
        "final_position_error": position_error,
        "violations": int(np.sum(violations)),
        "termination": termination,
        "steps": steps,
        "data_steps": int(data_steps),
        "initial_data_steps": int(built.prior_data_steps if learning else 0),
        "act_median_ms": 1e3 * _percentile(act, 50),
        "act_p95_ms": 1e3 * _percentile(act, 95),
        "act_max_ms": 1e3 * float(act.max()) if act.size else float("nan"),
        "solver_failures": int(getattr(agent, "n_failures", 0)) if is_mpc else float("nan"),
        "capped_solves": int(getattr(agent, "n_capped", 0)) if is_mpc else float("nan"),
        "plan_plant_defect": _plan_plant_defect(env, agent) if episodic else float("nan"),
        "fallbacks": int(getattr(agent, "n_fallbacks", 0)) if is_mpc else float("nan"),
        "solves": int(getattr(agent, "n_solves", 0)) if is_mpc else float("nan"),
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
    env.close()
    return {"metrics": metrics, "arrays": arrays}


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
    "ssgp-act-scaling": _lazy("benchmarks.compute", "run_act_scaling"),
    "ssgp-update-time": _lazy("benchmarks.compute", "run_update_time"),
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
