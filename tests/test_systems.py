"""One registration per system (gp_envs.systems: the env; gp_agents.defaults: the controllers'
defaults; benchmarks.systems: the benchmark's entry): what each gives, what it refuses, and where
the fourth system (the pendulum) is named."""

from __future__ import annotations

import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import gp_envs
from benchmarks.controllers import ENVS
from benchmarks.systems import unregister_benchmark_system
from benchmarks.trial import TrialSpec, execute
from gp_agents import Converged, PseudospectralMPC, collect_initial_data
from gp_agents.agent import rollout
from gp_agents.defaults import PlanningDefaults, unregister_defaults
from gp_envs.systems import (
    SYSTEMS,
    System,
    get_system,
    register_system,
    system_of,
    unregister_system,
)

REPO = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------- a user's own system
# A damped point mass on a line, written the way a user would in their own package `userpm`:
# a physics module named like the system, an env class, and the registration.
_PHYSICS = """
import casadi as ca
from gp_envs.physics.ranges import ParamRange

PARAM_RANGES = {"m": ParamRange.positive("mass, kg"), "c": ParamRange.nonnegative("damping, 1/s")}
PARAM_NAMES = tuple(PARAM_RANGES)
STATE_NAMES = ("p", "v")
STATE_UNITS = ("m", "m/s")
CONTROL_NAMES = ("f",)
CONTROL_UNITS = ("N",)


def ode(x, u, p):
    return ca.vertcat(x[1], u[0] / p[0] - p[1] * x[1])
"""
_ENV = """
import numpy as np
from gp_envs.base import GPEnv, Scenario
from gp_envs.model import Task, diag
from gp_envs.systems import System, register_system
from userpm import pointmass


class PointMassEnv(GPEnv):
    physics = pointmass
    SCENARIOS = {"default": Scenario("unmodeled damping", {"m": 1.0, "c": 0.5},
                                     {"m": 1.0, "c": 0.0}, (-2.0,), (2.0,))}
    DEFAULT_SCENARIO = "default"
    DT, SUBSTEPS = 0.1, 4
    X_LB, X_UB = np.array([-5.0, -5.0]), np.array([5.0, 5.0])
    DYNAMIC_INDICES = (1,)

    def _task(self):
        return Task(goal=np.array([1.0, 0.0]), Q=diag([1.0, 0.1]), R=diag([0.01]),
                    Qf=diag([10.0, 1.0]), u_ref=np.zeros(1),
                    goal_tolerance=np.array([0.05, np.inf]), hold_time=0.5, duration=4.0)

    def _initial_state(self):
        return np.zeros(2)

    def _render_frame(self, ax):
        ax.plot(self._state[0], 0.0, "o")


SYSTEM = register_system(System(
    name="pointmass", env_id="user/PointMass-v0", entry_point="userpm.env:PointMassEnv",
    max_episode_steps=40))
"""
_CONTROL = """
import numpy as np
from gp_agents import PlanningDefaults, SystemDefaults, register_defaults


def data_policy(model, rng):
    amp = rng.uniform(0.5, 1.0)
    return lambda obs, t: np.array([amp * np.sin(2.0 * t)])


register_defaults("pointmass", SystemDefaults(PlanningDefaults(horizon=1.2, n_nodes=8),
                                              data_policy, data_start=(-1.0, 0.0)))
"""
_BENCH = """
from benchmarks.systems import BenchmarkSystem, register_benchmark_system

register_benchmark_system("pointmass", BenchmarkSystem(position_dims=1))
"""


def _write_plugin(root: Path, entry_module: str = "userpm.env") -> Path:
    """The package ``userpm`` under ``root`` and an installed-distribution record declaring
    ``entry_module`` in the ``gp_envs.systems`` entry-point group."""
    pkg = root / "userpm"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "pointmass.py").write_text(_PHYSICS)
    (pkg / "env.py").write_text(_ENV)
    (pkg / "control.py").write_text(_CONTROL)
    (pkg / "bench.py").write_text(_BENCH)
    info = root / "userpm-0.1.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: userpm\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        f"[gp_envs.systems]\npointmass = {entry_module}\n\n"
        "[gp_agents.systems]\npointmass = userpm.control\n\n"
        "[benchmarks.systems]\npointmass = userpm.bench\n")
    return root


@pytest.fixture()
def user_system(tmp_path):
    sys.path.insert(0, str(_write_plugin(tmp_path)))
    try:
        system = importlib.import_module("userpm.env").SYSTEM
        importlib.import_module("userpm.control")
        importlib.import_module("userpm.bench")
        yield system
    finally:
        if "pointmass" in SYSTEMS:
            unregister_system("pointmass")
        unregister_defaults("pointmass")
        unregister_benchmark_system("pointmass")
        for name in [m for m in sys.modules if m == "userpm" or m.startswith("userpm.")]:
            del sys.modules[name]
        sys.path.remove(str(tmp_path))


def test_one_registration_gives_env_mpc_defaults_data_and_benchmark_entry(user_system):
    env = gym.make("user/PointMass-v0")
    assert env.spec.max_episode_steps == 40 and system_of(env) is user_system
    agent = PseudospectralMPC.from_env(env)
    assert agent.config.schedule.horizon == pytest.approx(1.2)
    assert isinstance(agent.config.scheme, Converged)
    # a registered system without RTI tuning of its own gets the defaults
    rti = PseudospectralMPC.from_env(env, scheme="rti")
    assert rti.config.scheme.qp_solver == "active-set:proxqp"
    assert rti.config.scheme.levenberg_marquardt == 0.0
    data = collect_initial_data(env, 30, seed=0)
    assert data.X.shape == (30, 2)
    np.testing.assert_allclose(data.X[0], [-1.0, 0.0])  # the registered data start
    # the registered policy drove the data: the first action is amp * sin(0) + noise only
    assert abs(data.U[0, 0]) < 0.5
    ep = rollout(env, agent, 0)
    assert ep.final_info["success"], ep.observations[-1]
    assert "pointmass" in ENVS and ENVS["pointmass"].scenarios == ("default",)
    record = execute(TrialSpec("episode", "pointmass", "default", "nominal-mpc", 0,
                               max_steps=5))
    assert record["status"] == "ok", record.get("error")
    assert np.isfinite(record["metrics"]["final_position_error"])


def test_unregister_removes_the_system_and_its_id(user_system):
    unregister_system("pointmass")
    assert "pointmass" not in SYSTEMS and "pointmass" not in ENVS
    with pytest.raises(gym.error.Error):
        gym.make("user/PointMass-v0")
    register_system(user_system)  # for the fixture's teardown
    assert gym.make("user/PointMass-v0") is not None


def test_registration_refuses_inconsistent_systems(user_system):
    base = user_system
    with pytest.raises(ValueError, match="already registered"):
        register_system(System(**{**base.__dict__, "max_episode_steps": 41}))
    assert register_system(base) is base  # the identical system again is a no-op
    with pytest.raises(ValueError, match=r"env id .* already registered"):
        register_system(System(**{**base.__dict__, "name": "other"}))
    with pytest.raises(ValueError, match="names its model 'pointmass'"):
        register_system(System(**{**base.__dict__, "name": "pointmass2",
                                  "env_id": "user/PM2-v0"}))
    unregister_system("pointmass")
    with pytest.raises(ValueError, match="max_episode_steps"):
        register_system(System(**{**base.__dict__, "max_episode_steps": 0}))
    assert "pointmass" not in SYSTEMS and "user/PointMass-v0" not in gym.registry
    physics = base.env_class().physics
    physics.STATE_UNITS = ("m",)
    with pytest.raises(ValueError, match="needs STATE_UNITS"):
        register_system(base)
    physics.STATE_UNITS = ("m", "m/s")
    register_system(base)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"horizon": 0.0, "n_nodes": 8}, "horizon"), ({"horizon": np.nan, "n_nodes": 8}, "horizon"),
    ({"horizon": 1.0, "n_nodes": 0}, "n_nodes"), ({"horizon": 1.0, "n_nodes": 2.5}, "n_nodes"),
    ({"horizon": 1.0, "n_nodes": 8, "n_intervals": 0}, "n_intervals")])
def test_planning_defaults_are_checked(kwargs, message):
    with pytest.raises(ValueError, match=message):
        PlanningDefaults(**kwargs)


def test_controller_and_benchmark_entries_are_checked():
    from benchmarks.systems import BenchmarkSystem, register_benchmark_system
    from gp_agents import SystemDefaults, register_defaults

    with pytest.raises(TypeError, match="PlanningDefaults"):
        SystemDefaults(planning=1.5)
    with pytest.raises(TypeError, match="data_policy"):
        SystemDefaults(data_policy="pd")
    with pytest.raises(ValueError, match="data_start"):
        SystemDefaults(data_start=(np.nan, 0.0))
    with pytest.raises(TypeError, match="SystemDefaults"):
        register_defaults("x", {"planning": None})
    with pytest.raises(ValueError, match="position_dims"):
        BenchmarkSystem(position_dims=-1)
    with pytest.raises(ValueError, match="perturbation"):
        BenchmarkSystem(perturbation=(0.1, -0.1))
    with pytest.raises(TypeError, match="BenchmarkSystem"):
        register_benchmark_system("x", None)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"levenberg_marquardt": -1e-3}, "levenberg_marquardt"),
    ({"levenberg_marquardt": np.inf}, "levenberg_marquardt"),
    ({"learned_term": ""}, "learned_term"), ({"learned_term": None}, "learned_term"),
    ({"qp_solver": ""}, "qp_solver"),
    ({"recovery_iterations": -1}, "recovery_iterations"),
    ({"recovery_iterations": True}, "recovery_iterations")])
def test_rti_tuning_is_checked(kwargs, message):
    from gp_agents.mpc import RTITuning

    with pytest.raises(ValueError, match=message):
        RTITuning(**kwargs)


def test_the_rti_tuning_is_data_and_names_no_recipe():
    """Per-system tuning holds data only: no field and no entry names a recipe (a recipe's own
    values live with the recipes)."""
    import dataclasses

    from gp_agents.mpc import RECIPES, RTITuning
    from gp_agents.mpc.tuning import RTI_TUNING

    assert not [f.name for f in dataclasses.fields(RTITuning) if "recipe" in f.name]
    for tuning in RTI_TUNING.values():
        assert not set(map(str, dataclasses.astuple(tuning))) & set(RECIPES)


def test_gp_envs_knows_no_solver():
    """Solver tuning lives with the controller: no gp_envs module names a QP solver or the
    real-time iteration's settings."""
    import pathlib

    import gp_envs as package

    root = pathlib.Path(package.__file__).parent
    words = ("qp_solver", "levenberg", "proxqp", "piqp", "osqp", "rti_learned")
    hits = [(p.name, w) for p in root.rglob("*.py") for w in words if w in p.read_text()]
    assert hits == []


def test_unknown_systems_are_named_errors():
    with pytest.raises(ValueError, match=r"unknown system 'nope'; registered: \['cartpole'"):
        get_system("nope")
    with pytest.raises(ValueError, match="gp_envs env or a ControlModel"):
        system_of(object())
    model = gym.make("gp_envs/PendulumSwingUp-v0").unwrapped.nominal_model
    unnamed = type(model)(**{**{k: getattr(model, k) for k in (
        "ode", "param_names", "params", "state_names", "control_names", "dt", "x_lb", "x_ub",
        "u_lb", "u_ub", "task", "substeps", "angle_indices", "dynamic_indices")},
        "name": "unregistered", "param_ranges": model.param_ranges})
    # a model without controller defaults: min(50 periods, a quarter of the task), 12 nodes
    default = PseudospectralMPC(unnamed).config.schedule
    assert default.horizon == pytest.approx(min(50 * model.dt, model.task.duration / 4))
    assert (default.n_nodes, default.n_intervals) == (12, 1)
    assert PseudospectralMPC(unnamed, horizon=1.0).config.schedule.horizon == 1.0


def test_built_in_systems_are_registered_in_their_env_modules():
    built_in = ("cartpole", "quadrotor", "dubins", "pendulum")
    assert set(SYSTEMS) >= set(built_in)
    assert tuple(SYSTEMS[n].env_id for n in built_in) == gp_envs.ENV_IDS
    for system in SYSTEMS.values():
        module = sys.modules[system.entry_point.split(":")[0]]
        assert module.SYSTEM is system


def test_the_pendulum_is_named_in_its_own_files_and_its_entries_only():
    """The fourth system: outside its physics module and env module, only the package's import
    list (gp_envs/__init__, gp_envs/physics/__init__), the controllers' entries for it (its
    defaults, data policy and RTI tuning, by name), the benchmark's entry and the experiments
    that study it (benchmarks/presets.py) name it."""
    allowed = {"gp_envs/pendulum_swingup.py", "gp_envs/physics/pendulum.py",
               "gp_envs/__init__.py", "gp_envs/physics/__init__.py", "gp_agents/defaults.py",
               "gp_agents/data_policies.py", "gp_agents/mpc/tuning.py",
               "benchmarks/systems.py", "benchmarks/presets.py",
               # Gymnasium's Pendulum-v1, another pendulum, and the tools that name it
               "benchmarks/outside_envs.py", "benchmarks/rl/train.py"}
    named = {str(p.relative_to(REPO)) for pkg in ("gp_envs", "gp_agents", "benchmarks")
             for p in (REPO / pkg).rglob("*.py")
             if re.search(r"\bpendulum\b|PendulumSwingUp", p.read_text())}
    named = {n for n in named if not n.startswith("benchmarks/studies/")}  # studies measure it
    assert named <= allowed, sorted(named - allowed)


def test_gp_envs_knows_no_planner_and_no_benchmark():
    """gp_envs imports nothing of gp_agents or benchmarks and defines none of their notions
    (planning defaults, data policies, benchmark scenarios, perturbations)."""
    code = ("import sys, gp_envs, gp_envs.dmc, gp_envs.wrapper; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('gp_agents', 'benchmarks')))")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(REPO)}, cwd=REPO, timeout=120)
    assert res.returncode == 0 and res.stdout.strip() == "[]", res.stderr[-2000:]
    words = re.compile(r"PlanningDefaults|data_policy|DataPolicy|benchmark_scenarios|"
                       r"perturbation|position_dims|n_nodes|nodes_per_period")
    hits = [(str(p.relative_to(REPO)), m.group(0)) for p in (REPO / "gp_envs").rglob("*.py")
            for m in words.finditer(p.read_text())]
    assert hits == []


def _run(args: list[str], pythonpath: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(pythonpath), str(REPO)]))
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


@pytest.mark.slow
def test_an_installed_plugin_system_runs_in_the_benchmarks_spawned_workers(tmp_path):
    """Declared as an entry point, the user's system is registered in every process that
    imports gp_envs: the benchmark CLI and its spawned worker process run it."""
    root = _write_plugin(tmp_path / "site")
    res = _run(["-m", "benchmarks", "--controllers", "nominal-mpc", "--envs", "pointmass",
                "--seeds", "0", "--max-steps", "3", "--workers", "1", "--no-progress",
                "--out", str(tmp_path / "out")], root, tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    metrics = (tmp_path / "out" / "metrics.csv").read_text()
    assert "pointmass" in metrics and "nominal-mpc" in metrics


def test_a_broken_plugin_is_skipped_with_a_warning(tmp_path):
    root = _write_plugin(tmp_path / "site", entry_module="userpm.missing")
    res = _run(["-W", "always", "-c", "import gp_envs; print(sorted(gp_envs.SYSTEMS))"], root,
               tmp_path)
    assert res.returncode == 0, res.stderr
    assert "gp_envs.systems: plugin 'pointmass' (userpm.missing) failed to load" in res.stderr
    assert "'cartpole'" in res.stdout and "pointmass" not in res.stdout
