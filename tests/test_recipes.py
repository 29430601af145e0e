"""The named recipes (make_mpc), the settings objects, learner and data validation, and the
degradation warning."""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest

import gp_envs
from gp_agents import (
    RECIPES,
    RTI,
    Constraints,
    ControllerDegradedWarning,
    Converged,
    Episodic,
    IncrementalSSGP,
    PseudospectralMPC,
    RecedingHorizon,
    Residual,
    Transitions,
    collect_initial_data,
    make_mpc,
    online_ssgp,
    parametric_ssgp,
    rollout,
)
from gp_agents.mpc import GPInNLP, LinearizedGP, PatternLinearizedGP
from gp_agents.residual import ResidualModel


def _env(name: str = "cartpole", **kwargs) -> gym.Env:
    return gym.make(gp_envs.SYSTEMS[name].env_id, **kwargs)


# ----------------------------------------------------------------------------- recipes
def test_make_mpc_default_is_the_robust_recipe_with_its_own_columns():
    env = _env(scenario="online")
    agent = make_mpc(env)
    assert set(RECIPES) >= {"robust", "paper", "nominal", "oracle"}
    assert isinstance(agent.term, LinearizedGP) and agent.scheme == "converged"
    assert agent.residual_settings.sensitivities
    # the learner's linear features sit on exactly this agent's sensitivity columns
    assert tuple(agent.learner.linear_features) == agent.residual.sensitivity_columns
    names = agent.residual.input_names
    assert all(names[c].startswith("d") for c in agent.residual.sensitivity_columns), names


@pytest.mark.parametrize("system", ["cartpole", "dubins"])
def test_robust_recipe_acts_as_the_hand_built_parametric_recipe(system):
    """make_mpc(env) against the four coupled settings a user had to write before."""
    env = _env(system)
    data = collect_initial_data(env, 60, seed=3)
    obs, _ = env.reset(seed=3)
    columns = ResidualModel(env.unwrapped.nominal_model, sensitivities=True).sensitivity_columns
    with pytest.warns(DeprecationWarning, match="sensitivities"):
        old = PseudospectralMPC.from_env(env, parametric_ssgp(columns), sensitivities=True,
                                         learned_dynamics="linearized")
    new = make_mpc(env)
    actions = []
    for agent in (old.pretrain(data), new.pretrain(data)):
        agent.reset()
        actions.append([agent.act(obs) for _ in range(2)])
    np.testing.assert_array_equal(actions[0], actions[1])


def test_recipes_and_schemes_compose():
    env = _env("quadrotor")
    rti = make_mpc(env, "robust", scheme="rti-split")
    # the RTI takes the system's tuned learned term (the quadrotor's: the Jacobian pattern)
    assert rti.scheme == "rti-split" and isinstance(rti.term, PatternLinearizedGP)
    assert rti.qp_solver == "active-set:proxqp"
    paper = make_mpc(env, "paper")
    assert isinstance(paper.term, GPInNLP) and not paper.residual_settings.sensitivities
    assert make_mpc(env, "nominal").learner is None
    oracle = make_mpc(env, "oracle")
    env.reset(seed=0)
    assert oracle._model_source().params == gp_envs.oracle_model(env).params
    assert make_mpc(env, "paper", learner=online_ssgp(20)).learner.n_frequencies == 20
    with pytest.raises(ValueError, match=r"unknown MPC recipe 'fast'.*robust"):
        make_mpc(env, "fast")
    with pytest.raises(ValueError, match="learns nothing"):
        make_mpc(env, "nominal", learner=online_ssgp())
    with pytest.raises(TypeError, match=r"no nominal model.*gp_envs\.wrap"):
        make_mpc(gym.make("Pendulum-v1"))


def test_a_recipe_takes_its_own_levenberg_marquardt_where_the_system_tunes_one():
    """The Dubins tuning damps the robust recipe's RTI QP more than the other recipes'
    (``RTITuning.recipe_levenberg_marquardt``); an explicit ``RTI(levenberg_marquardt=...)``
    or the flat keyword wins; the converged scheme has none; a system without a recipe entry
    gives every recipe the system's value."""
    from gp_agents.mpc import rti_tuning

    tuning = rti_tuning("dubins")
    env = _env("dubins")
    mu = tuning.recipe_levenberg_marquardt["robust"]
    assert mu != tuning.levenberg_marquardt
    for scheme in ("rti", "rti-split", RTI(split=True)):
        assert make_mpc(env, "robust", scheme=scheme).levenberg_marquardt == mu
        assert make_mpc(env, "paper", scheme=scheme).levenberg_marquardt \
            == tuning.levenberg_marquardt
    assert make_mpc(env, "robust", scheme=RTI(levenberg_marquardt=0.5)) \
        .levenberg_marquardt == 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert make_mpc(env, "robust", scheme="rti", levenberg_marquardt=0.25) \
            .levenberg_marquardt == 0.25
    assert make_mpc(env, "robust").levenberg_marquardt is None
    cart = _env("cartpole")
    assert not rti_tuning("cartpole").recipe_levenberg_marquardt
    assert make_mpc(cart, "robust", scheme="rti").levenberg_marquardt \
        == rti_tuning("cartpole").levenberg_marquardt



def test_a_recipe_takes_its_own_recovery_budget_where_the_system_tunes_one():
    """On the Dubins vehicle only the robust recipe's RTI recovers rejected steps
    (``RTITuning.recipe_recovery_iterations``), as the built controller resolved it; an explicit
    ``RTI(recovery_iterations=...)`` wins, and a recipe ``mu`` does not disturb the budget."""
    from gp_agents.mpc import rti_tuning

    tuning = rti_tuning("dubins")
    env = _env("dubins")
    budget = tuning.recipe_recovery_iterations["robust"]
    assert budget > 0 == tuning.recovery_iterations

    def planned(agent: PseudospectralMPC) -> int:
        settings = agent.scheme_settings
        assert isinstance(settings, RTI) and settings.recovery_iterations is not None
        return settings.recovery_iterations

    for scheme in ("rti", "rti-split"):
        assert planned(make_mpc(env, "robust", scheme=scheme)) == budget
        for recipe in ("paper", "nominal", "oracle", "blackbox"):
            assert planned(make_mpc(env, recipe, scheme=scheme)) == 0, recipe
    assert planned(make_mpc(env, "robust", scheme=RTI(recovery_iterations=1))) == 1
    robust = make_mpc(env, "robust", scheme=RTI(levenberg_marquardt=0.5))
    assert planned(robust) == budget and robust.levenberg_marquardt == 0.5
    # the deprecated flat keywords change only what they name, the recipe's entries stay
    with pytest.warns(DeprecationWarning):
        legacy = make_mpc(env, "robust", scheme="rti-split", qp_solver="osqp")
    assert (planned(legacy), legacy.levenberg_marquardt, legacy.qp_solver) == (
        budget, tuning.recipe_levenberg_marquardt["robust"], "osqp")
    assert legacy.scheme == "rti-split"
    with pytest.warns(DeprecationWarning):
        legacy = make_mpc(env, "robust", scheme="rti", levenberg_marquardt=0.25)
    assert (planned(legacy), legacy.levenberg_marquardt) == (budget, 0.25)
    with pytest.raises(TypeError, match="both given"):
        make_mpc(env, "robust", scheme=RTI(), qp_solver="osqp")
    cart = _env("cartpole")
    assert not rti_tuning("cartpole").recipe_recovery_iterations
    assert planned(make_mpc(cart, "nominal", scheme="rti")) \
        == rti_tuning("cartpole").recovery_iterations > 0


def test_a_recipe_entry_of_the_rti_tuning_must_name_a_recipe():
    """A misspelt recipe in a system's per-recipe RTI tuning raises at the RTI's build
    instead of being ignored; the converged scheme does not read it."""
    from gp_agents.mpc import register_rti_tuning, rti_tuning

    base = rti_tuning("pendulum")
    register_rti_tuning("pendulum", dataclasses.replace(
        base, recipe_recovery_iterations={"robsut": 1}))
    try:
        env = _env("pendulum")
        with pytest.raises(ValueError, match="robsut"):
            make_mpc(env, "robust", scheme="rti")
        assert make_mpc(env, "robust").levenberg_marquardt is None
    finally:
        register_rti_tuning("pendulum", base)
    assert rti_tuning("pendulum") == base


# ----------------------------------------------------------------------------- settings
def _probe(agent: PseudospectralMPC) -> dict:
    """What a setting can change, measured on the built controller: the first actions and
    solver records of a short closed loop, the mesh, the planner and its QP settings, the
    learner's inputs and samples, and the OCP's cost and bounds at probe states."""
    env = agent._probe_env
    episode = rollout(env, agent, 0, max_steps=agent._probe_steps)
    d = agent.diagnostics_arrays()
    planner = agent.planner
    problem = planner.ocp.problem
    p = planner.planning.param_values()
    model = agent.model
    lb = np.where(np.isfinite(model.x_lb), model.x_lb, -1.0)
    ub = np.where(np.isfinite(model.x_ub), model.x_ub, 1.0)
    probes = [lb + 0.01 * (ub - lb), 0.5 * (lb + ub)]
    for ob in model.task.obstacles:
        x = np.array(probes[1])
        offset = np.array([ob.radius + model.task.body_radius + 0.05, 0.0])
        x[:2] = np.asarray(ob.center) + offset
        probes.append(x)
    u0 = np.asarray(model.task.u_ref, float)
    return {
        "actions": np.round(episode.actions, 9).tolist(),
        "status": [str(s) for s in d["status"]], "iterations": d["iterations"].tolist(),
        "mesh": agent.mesh.describe(), "planner": type(planner).__name__,
        "qp": repr(getattr(planner, "qp_solver", None)),
        "mu": getattr(planner, "levenberg_marquardt", None),
        "recovery": getattr(planner, "recovery_iterations", None),
        "warm_duals": planner.warm_start_duals, "solver": planner.ocp.solver_name,
        "jit": planner.ocp.jit, "inputs": agent.residual.input_names,
        "outputs": agent.residual.uncertain_indices, "term": type(agent.term).__name__,
        "samples": d["learner_samples"].tolist(),
        "cost": [round(float(problem.running_cost(x, u0, p)), 9) for x in probes],
        "bounds": (problem.x_lb.tolist(), problem.x_ub.tolist()),
    }


_DATA: dict[tuple[str, int], Transitions] = {}


def _agent(system: str, learner: bool, steps: int = 3, **settings) -> PseudospectralMPC:
    env = _env(system)
    n_data = settings.pop("_n_data", 40)  # initial samples (the refit setting needs few)
    if (system, n_data) not in _DATA:
        _DATA[(system, n_data)] = collect_initial_data(env, n_data, seed=1)
    env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, online_ssgp(10) if learner else None, **settings)
    if learner:
        agent.pretrain(_DATA[(system, n_data)])
    agent._probe_env, agent._probe_steps = env, steps
    return agent


# every setting of every settings object: (system, with a learner, base settings, changed)
_SETTINGS = {
    "RecedingHorizon.horizon": ("pendulum", False, {}, {"horizon": RecedingHorizon(2.0)}),
    "RecedingHorizon.n_nodes": ("pendulum", False, {}, {"horizon": RecedingHorizon(n_nodes=8)}),
    "RecedingHorizon.n_intervals": ("pendulum", False, {},
                                    {"horizon": RecedingHorizon(n_intervals=1)}),
    "RecedingHorizon.replan_every": ("pendulum", False, {},
                                     {"horizon": RecedingHorizon(replan_every=2)}),
    "RecedingHorizon.held_nodes": ("pendulum", False, {},
                                   {"horizon": RecedingHorizon(held_nodes=2)}),
    "Episodic.duration": ("pendulum", False, {"horizon": Episodic()},
                          {"horizon": Episodic(duration=3.0)}),
    "Episodic.nodes_per_period": ("pendulum", False, {"horizon": Episodic()},
                                  {"horizon": Episodic(nodes_per_period=2)}),
    "Converged.solver": ("pendulum", False, {}, {"scheme": Converged(solver="sqpmethod")}),
    "Converged.solver_options": ("pendulum", False, {},
                                 {"scheme": Converged(solver_options={"ipopt": {"tol": 1e-1}})}),
    "Converged.max_iterations": ("pendulum", False, {}, {"scheme": Converged(max_iterations=2)}),
    "Converged.warm_start_duals": ("pendulum", False, {},
                                   {"scheme": Converged(warm_start_duals=True)}),
    "RTI.split": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(split=True)}),
    "RTI.qp_solver": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(qp_solver="osqp")}),
    "RTI.levenberg_marquardt": ("pendulum", False, {"scheme": RTI()},
                                {"scheme": RTI(levenberg_marquardt=0.5)}),
    "RTI.recovery_iterations": ("pendulum", False, {"scheme": RTI()},
                                {"scheme": RTI(recovery_iterations=0)}),
    "RTI.fallback": ("pendulum", False, {"scheme": RTI()},
                     {"scheme": RTI(fallback=Converged(max_iterations=2))}),
    "term": ("pendulum", True, {}, {"term": "linearized"}),
    "Residual.uncertain": ("pendulum", True, {}, {"residual": Residual(uncertain=(0, 1))}),
    "Residual.inputs": ("pendulum", True, {}, {"residual": Residual(inputs=(1,))}),
    "Residual.sensitivities": ("pendulum", True, {},
                               {"residual": Residual(sensitivities=True)}),
    "Residual.learn_online": ("pendulum", True, {}, {"residual": Residual(learn_online=False)}),
    "Residual.refit_until": ("pendulum", True, {"_n_data": 2},
                             {"_n_data": 2, "residual": Residual(refit_until=10)}),
    "Constraints.state_margin": ("pendulum", False, {},
                                 {"constraints": Constraints(state_margin=0.2)}),
    "Constraints.state_penalty": ("pendulum", False, {},
                                  {"constraints": Constraints(state_penalty=None)}),
    "Constraints.obstacle_margin": ("dubins", False, {},
                                    {"constraints": Constraints(obstacle_margin=0.3)}),
    "Constraints.uncertainty_radius": ("dubins", True, {},
                                       {"constraints": Constraints(uncertainty_radius=1.0)}),
}


def _fields() -> set[str]:
    from gp_agents.mpc.settings import RTI as R

    out = {"term"}
    for cls in (RecedingHorizon, Episodic, Converged, R, Residual, Constraints):
        out |= {f"{cls.__name__}.{f.name}" for f in dataclasses.fields(cls)}
    return out


def test_every_setting_is_covered():
    assert _fields() - {"Converged.jit"} == set(_SETTINGS)


@pytest.mark.parametrize("name", sorted(_SETTINGS))
def test_every_setting_changes_behaviour(name):
    system, learner, base, changed = _SETTINGS[name]
    steps = 1 if name.startswith("Converged.solver") and "options" not in name else 3
    a = _probe(_agent(system, learner, steps, **base))
    b = _probe(_agent(system, learner, steps, **changed))
    assert a != b, name


def test_jit_reaches_the_solver_build(monkeypatch):
    import gp_agents.mpc.planner as planner_module

    seen = {}
    original = planner_module.build_ocp

    def spy(*args, **kwargs):
        seen.update(kwargs)
        return original(*args, **{**kwargs, "jit": False})  # no C compile in the test

    monkeypatch.setattr(planner_module, "build_ocp", spy)
    _agent("pendulum", False, scheme=Converged(jit=True))._planner()
    assert seen["jit"] is True


@pytest.mark.parametrize(("system", "learner", "settings", "error", "match"), [
    ("pendulum", False, {"horizon": Episodic(), "scheme": "rti"}, ValueError, "episodic"),
    ("pendulum", True, {"horizon": Episodic(), "residual": Residual(learn_online=True)},
     ValueError, "learns nothing"),
    ("pendulum", False, {"term": "linearized"}, ValueError, "no learner"),
    ("pendulum", True, {"horizon": Episodic(), "residual": Residual(refit_until=10)},
     ValueError, "refit"),
    ("pendulum", True, {"residual": Residual(learn_online=False, refit_until=10)},
     ValueError, "refit"),
    ("pendulum", False, {"residual": Residual(sensitivities=True)}, ValueError, "no learner"),
    ("pendulum", False, {"constraints": Constraints(obstacle_margin=0.3)}, ValueError,
     "no obstacles"),
    ("pendulum", False, {"constraints": Constraints(uncertainty_radius=1.0)}, ValueError,
     "no obstacles"),
    ("dubins", False, {"constraints": Constraints(uncertainty_radius=1.0)}, ValueError,
     "needs a learner"),
    ("pendulum", False, {"scheme": RTI(), "qp_solver": "osqp"}, TypeError, "both given"),
    ("pendulum", False, {"qp_solver": "osqp"}, ValueError, "do not apply to scheme='converged'"),
    ("pendulum", False, {"mode": "episodic", "replan_every": 2}, ValueError,
     "do not apply to an episodic"),
    ("pendulum", False, {"scheme": "fast"}, ValueError, "scheme must be one of"),
    ("pendulum", False, {"foo": 1}, TypeError, "unexpected keyword"),
])
def test_settings_that_do_not_apply_raise(system, learner, settings, error, match):
    env = _env(system)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        with pytest.raises(error, match=match):
            PseudospectralMPC.from_env(env, online_ssgp() if learner else None, **settings)


def test_settings_objects_check_their_values():
    with pytest.raises(ValueError, match="warm_start_duals"):
        Converged(solver="sqpmethod", warm_start_duals=True)
    with pytest.raises(ValueError, match="max_iterations"):
        Converged(max_iterations=0)
    with pytest.raises(ValueError, match="replan_every"):
        RecedingHorizon(replan_every=0)
    with pytest.raises(ValueError, match="levenberg_marquardt"):
        RTI(levenberg_marquardt=-1.0)
    with pytest.raises(TypeError, match="fallback"):
        RTI(fallback="ipopt")
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="recovery_iterations"):
            RTI(recovery_iterations=bad)


def test_an_ssgp_learning_online_needs_an_update():
    from gp_agents import ExactGP

    env = _env("pendulum")
    with pytest.raises(ValueError, match="no update"):
        PseudospectralMPC.from_env(env, ExactGP(), residual=Residual(learn_online=True))
    assert not PseudospectralMPC.from_env(env, ExactGP()).learn_online


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize("learner", [[1, 2], "ssgp", IncrementalSSGP, 3.0])
def test_a_learner_without_what_the_mpc_calls_is_a_type_error(learner):
    with pytest.raises(TypeError, match="learner"):
        PseudospectralMPC.from_env(_env("pendulum"), learner)


def test_data_given_as_learner_says_where_data_go():
    env = _env("pendulum")
    data = collect_initial_data(env, 5, seed=0)
    with pytest.raises(TypeError, match="pretrain"):
        PseudospectralMPC.from_env(env, data)


def test_pretrain_checks_its_data():
    env = _env("pendulum")
    agent = make_mpc(env, "paper")
    with pytest.raises(TypeError, match="Transitions"):
        agent.pretrain([1, 2, 3, 4])
    with pytest.raises(ValueError, match=r"shape \(N, 2\)"):
        agent.pretrain((np.zeros((4, 3)), np.zeros((4, 1)), np.zeros((4, 2))))
    with pytest.raises(ValueError, match="non-finite"):
        agent.pretrain((np.full((4, 2), np.nan), np.zeros((4, 1)), np.zeros((4, 2))))
    with pytest.raises(ValueError, match="as many rows"):
        agent.pretrain((np.zeros((4, 2)), np.zeros((3, 1)), np.zeros((4, 2))))


def test_parametric_learner_needs_the_sensitivities():
    env = _env("cartpole")
    with pytest.raises(TypeError, match="sensitivities=True"):
        PseudospectralMPC.from_env(env, parametric_ssgp())
    with pytest.raises(TypeError, match=r"input column\(s\) \[30\]"):
        PseudospectralMPC.from_env(env, parametric_ssgp([30]))
    with pytest.raises(ValueError, match="MPC fills in"):  # fitted alone, without an MPC
        parametric_ssgp().fit(np.zeros((5, 3)), np.zeros((5, 1)))


# ----------------------------------------------------------------------------- initial data
def _one_step_error(env: gym.Env, data: Transitions, seed: int) -> float:
    env.reset(seed=seed)
    truth = gp_envs.oracle_model(env)
    pred = np.array([truth.step(x, u) for x, u in zip(data.X, data.U, strict=True)])
    error = pred - data.X_next
    angles = list(truth.angle_indices)  # observations wrap the angles
    error[:, angles] = (error[:, angles] + np.pi) % (2 * np.pi) - np.pi
    return float(np.max(np.abs(error)))


def test_initial_data_come_from_the_system_of_the_seed():
    env = _env("cartpole", scenario="online", randomize=0.1)
    same = collect_initial_data(env, 60, seed=4)
    other = collect_initial_data(env, 60, seed=4, same_system=False)
    assert _one_step_error(env, same, 4) < 1e-5  # float32 observations
    assert _one_step_error(env, other, 4) > 1e-3  # other truth draws


def test_keep_system_reset_keeps_the_draw():
    env = _env("dubins", randomize=0.2)
    env.reset(seed=5)
    truth, nominal = gp_envs.oracle_model(env).params, env.unwrapped.nominal_model.params
    env.reset(options={"keep_system": True})
    assert gp_envs.oracle_model(env).params == truth
    assert env.unwrapped.nominal_model.params == nominal
    env.reset()
    assert gp_envs.oracle_model(env).params != truth
    with pytest.raises(ValueError, match="earlier reset"):
        _env("dubins").reset(options={"keep_system": True})


# ----------------------------------------------------------------------------- degradation
def test_degradation_warns_once_per_episode_and_is_counted():
    env = _env("pendulum")
    agent = PseudospectralMPC.from_env(env, scheme=Converged(max_iterations=1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rollout(env, agent, 0, max_steps=8)
        rollout(env, agent, 1, max_steps=8)
    degraded = [w for w in caught if issubclass(w.category, ControllerDegradedWarning)]
    assert len(degraded) == 2, [str(w.message) for w in caught]
    health = agent.health()
    assert health["degraded"] and health["replans"] == 8
    assert health["capped"] + health["failed"] >= 3
    quiet = PseudospectralMPC.from_env(env)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ControllerDegradedWarning)
        rollout(env, quiet, 0, max_steps=8)
    assert not quiet.health()["degraded"] and quiet.health()["degraded_replans"] == 0
