"""The named recipes (make_mpc), the settings objects, learner and data validation, and the
degradation warning."""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium as gym
import numpy as np
import pytest
from agent_parts import mesh_of, residual_of

import gp_envs
from gp_agents import (
    RECIPES,
    RTI,
    SQP,
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
from gp_agents.mpc import GPInNLP, LinearizedGP, MPCConfig, PatternLinearizedGP
from gp_agents.residual import ResidualModel


def _env(name: str = "cartpole", **kwargs) -> gym.Env:
    return gym.make(gp_envs.SYSTEMS[name].env_id, **kwargs)


# ----------------------------------------------------------------------------- recipes
def test_make_mpc_default_is_the_robust_recipe_with_its_own_columns():
    env = _env(scenario="online")
    agent = make_mpc(env)
    assert set(RECIPES) >= {"robust", "paper", "nominal", "oracle"}
    assert isinstance(agent.config.term, LinearizedGP) and agent.config.scheme.name == "converged"
    assert agent.config.residual.sensitivities
    # the learner's linear features sit on exactly this agent's sensitivity columns
    assert tuple(agent.learner.linear_features) == residual_of(agent).sensitivity_columns
    names = residual_of(agent).input_names
    assert all(names[c].startswith("d") for c in residual_of(agent).sensitivity_columns), names


@pytest.mark.parametrize("system", ["cartpole", "dubins"])
def test_robust_recipe_acts_as_the_hand_built_parametric_recipe(system):
    """make_mpc(env) against the four coupled settings a user had to write before."""
    env = _env(system)
    data = collect_initial_data(env, 60, seed=3)
    obs, _ = env.reset(seed=3)
    columns = ResidualModel(env.unwrapped.nominal_model, sensitivities=True).sensitivity_columns
    old = PseudospectralMPC.from_env(env, parametric_ssgp(columns),
                                     residual=Residual(sensitivities=True), term="linearized")
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
    assert rti.config.scheme.name == "rti-split"
    assert isinstance(rti.config.term, PatternLinearizedGP)
    assert rti.config.scheme.qp_solver == "active-set:proxqp"
    paper = make_mpc(env, "paper")
    assert isinstance(paper.config.term, GPInNLP) and not paper.config.residual.sensitivities
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


def test_a_recipe_takes_its_own_levenberg_marquardt_where_it_sets_one():
    """The robust recipe damps its Dubins RTI QP more than the system's tuning does for the
    other recipes (its own ``RECIPE_RTI`` entry); an explicit ``RTI(levenberg_marquardt=...)``
    wins; the converged scheme has none; a system without a recipe entry gives every recipe
    the system's value."""
    from gp_agents.mpc import rti_tuning
    from gp_agents.mpc.recipes import RECIPE_RTI

    tuning = rti_tuning("dubins")
    env = _env("dubins")
    mu = RECIPE_RTI["robust"]["dubins"]["levenberg_marquardt"]
    assert mu != tuning.levenberg_marquardt
    for scheme in ("rti", "rti-split", RTI(split=True)):
        assert make_mpc(env, "robust", scheme=scheme).config.scheme.levenberg_marquardt == mu
        assert make_mpc(env, "paper", scheme=scheme).config.scheme.levenberg_marquardt \
            == tuning.levenberg_marquardt
    assert make_mpc(env, "robust", scheme=RTI(levenberg_marquardt=0.5)) \
        .config.scheme.levenberg_marquardt == 0.5
    assert isinstance(make_mpc(env, "robust", scheme="converged").config.scheme, Converged)
    # the SQP iterates to convergence with a line search: undamped, whatever the RTI's tuning
    assert make_mpc(env, "robust", scheme="sqp").config.scheme.levenberg_marquardt == 0.0
    assert make_mpc(env, "robust", scheme=SQP(levenberg_marquardt=0.5)) \
        .config.scheme.levenberg_marquardt == 0.5
    cart = _env("cartpole")
    assert "cartpole" not in RECIPE_RTI["robust"]
    assert make_mpc(cart, "robust", scheme="rti").config.scheme.levenberg_marquardt \
        == rti_tuning("cartpole").levenberg_marquardt


@pytest.mark.parametrize("system", ["cartpole", "quadrotor", "dubins"])
def test_a_recipe_without_a_scheme_plans_with_its_own_scheme_on_the_system(system):
    """``make_mpc(env, recipe)`` without ``scheme``: the recipe's entry of ``RECIPE_SCHEMES``
    on the env's system (the robust recipe's SQP on the quadrotor and the Dubins vehicle),
    the converged IPOPT solve for every other recipe and system; ``scheme=`` overrides it."""
    from gp_agents.mpc.recipes import RECIPE_SCHEMES

    env = _env(system)
    own = RECIPE_SCHEMES["robust"].get(system, "converged")
    assert make_mpc(env).config.scheme.name == own
    assert (system == "cartpole") == (own == "converged")
    for recipe in ("paper", "nominal", "oracle", "blackbox", "parametric"):
        assert recipe not in RECIPE_SCHEMES
        assert make_mpc(env, recipe).config.scheme.name == "converged"
    assert make_mpc(env, scheme="converged").config.scheme.name == "converged"
    assert make_mpc(env, scheme="rti").config.scheme.name == "rti"


def test_a_recipe_takes_its_own_recovery_budget_where_it_sets_one():
    """On the Dubins vehicle only the robust recipe's RTI recovers rejected steps (its
    ``RECIPE_RTI`` entry), as the built controller resolved it; an explicit
    ``RTI(recovery_iterations=...)`` wins, a recipe ``mu`` does not disturb the budget, and
    the former flat keywords are refused."""
    from gp_agents.mpc import rti_tuning
    from gp_agents.mpc.recipes import RECIPE_RTI

    tuning = rti_tuning("dubins")
    env = _env("dubins")
    budget = RECIPE_RTI["robust"]["dubins"]["recovery_iterations"]
    assert budget > 0 == tuning.recovery_iterations

    def planned(agent: PseudospectralMPC) -> int:
        settings = agent.config.scheme
        assert isinstance(settings, RTI) and settings.recovery_iterations is not None
        return settings.recovery_iterations

    for scheme in ("rti", "rti-split"):
        assert planned(make_mpc(env, "robust", scheme=scheme)) == budget
        for recipe in ("paper", "nominal", "oracle", "blackbox"):
            assert planned(make_mpc(env, recipe, scheme=scheme)) == 0, recipe
    assert planned(make_mpc(env, "robust", scheme=RTI(recovery_iterations=1))) == 1
    robust = make_mpc(env, "robust", scheme=RTI(levenberg_marquardt=0.5))
    assert planned(robust) == budget and robust.config.scheme.levenberg_marquardt == 0.5
    osqp = make_mpc(env, "robust", scheme=RTI(split=True, qp_solver="osqp"))
    assert (planned(osqp), osqp.config.scheme.levenberg_marquardt,
            osqp.config.scheme.qp_solver) == (budget, RECIPE_RTI["robust"]["dubins"]
                                              ["levenberg_marquardt"], "osqp")
    for flat in ({"qp_solver": "osqp"}, {"levenberg_marquardt": 0.25}, {"n_nodes": 8}):
        with pytest.raises(TypeError, match="unexpected keyword"):
            make_mpc(env, "robust", scheme="rti", **flat)
    cart = _env("cartpole")
    assert planned(make_mpc(cart, "nominal", scheme="rti")) \
        == rti_tuning("cartpole").recovery_iterations > 0


def test_the_recipes_own_rti_entries_name_recipes_and_rti_settings():
    """Every per-recipe RTI entry names a recipe and fields of ``RTI`` that take its values
    (a misspelt one would otherwise be ignored)."""
    from gp_agents.mpc.recipes import RECIPE_RTI

    assert set(RECIPE_RTI) <= set(RECIPES)
    for recipe, systems in RECIPE_RTI.items():
        for system, values in systems.items():
            assert system in gp_envs.SYSTEMS, (recipe, system)
            RTI(**values)  # raises for an unknown field or a bad value


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
        "mesh": mesh_of(agent).describe(), "planner": type(planner).__name__,
        "qp": repr(getattr(planner, "qp_solver", None)),
        "mu": getattr(planner, "levenberg_marquardt", None),
        "recovery": getattr(planner, "recovery_iterations", None),
        "warm_duals": planner.warm_start_duals, "solver": planner.ocp.solver_name,
        "jit": planner.ocp.jit, "inputs": residual_of(agent).input_names,
        "outputs": residual_of(agent).uncertain_indices, "term": type(agent.config.term).__name__,
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
    # a threshold every learned plan exceeds: the nominal plans act
    "Converged.nominal_above": ("pendulum", True, {"term": "linearized"},
                                {"term": "linearized",
                                 "scheme": Converged(nominal_above=1e-9)}),
    "RTI.split": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(split=True)}),
    "RTI.qp_solver": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(qp_solver="osqp")}),
    "RTI.levenberg_marquardt": ("pendulum", False, {"scheme": RTI()},
                                {"scheme": RTI(levenberg_marquardt=0.5)}),
    "RTI.recovery_iterations": ("pendulum", False, {"scheme": RTI()},
                                {"scheme": RTI(recovery_iterations=0)}),
    "RTI.fallback": ("pendulum", False, {"scheme": RTI()},
                     {"scheme": RTI(fallback=Converged(max_iterations=2))}),
    # the converged settings as the RTI's fallback (the cold start and rejected steps)
    "RTI.fallback.solver": ("pendulum", False, {"scheme": RTI()},
                            {"scheme": RTI(fallback=Converged(solver="sqpmethod"))}),
    "RTI.fallback.solver_options": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(
        fallback=Converged(warm_start_duals=True, solver_options={"ipopt": {"tol": 1e-1}}))}),
    "RTI.fallback.max_iterations": ("pendulum", False, {"scheme": RTI()}, {"scheme": RTI(
        fallback=Converged(warm_start_duals=True, max_iterations=2))}),
    "RTI.fallback.warm_start_duals": ("pendulum", False, {"scheme": RTI()},
                                      {"scheme": RTI(fallback=Converged())}),
    # the RTI's settings in the split scheme
    "RTI.qp_solver[split]": ("pendulum", False, {"scheme": RTI(split=True)},
                             {"scheme": RTI(split=True, qp_solver="osqp")}),
    "RTI.levenberg_marquardt[split]": ("pendulum", False, {"scheme": RTI(split=True)},
                                       {"scheme": RTI(split=True, levenberg_marquardt=0.5)}),
    "RTI.recovery_iterations[split]": ("pendulum", False, {"scheme": RTI(split=True)},
                                       {"scheme": RTI(split=True, recovery_iterations=0)}),
    # the SQP scheme's settings
    "SQP.max_iterations": ("pendulum", False, {"scheme": SQP()},
                           {"scheme": SQP(max_iterations=1)}),
    "SQP.tolerance": ("pendulum", False, {"scheme": SQP()}, {"scheme": SQP(tolerance=1e-1)}),
    "SQP.qp_solver": ("pendulum", False, {"scheme": SQP()}, {"scheme": SQP(qp_solver="osqp")}),
    "SQP.levenberg_marquardt": ("pendulum", False, {"scheme": SQP()},
                                {"scheme": SQP(levenberg_marquardt=0.5)}),
    "SQP.fallback": ("pendulum", False, {"scheme": SQP()},
                     {"scheme": SQP(fallback=Converged(max_iterations=2))}),
    # another NLP plugin's own options (its iteration cap among them)
    "Converged.solver_options[sqpmethod]": (
        "pendulum", False, {"scheme": Converged(solver="sqpmethod")},
        {"scheme": Converged(solver="sqpmethod", solver_options={"max_iter": 1})}),
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
    for cls in (RecedingHorizon, Episodic, Converged, SQP, R, Residual, Constraints):
        out |= {f"{cls.__name__}.{f.name}" for f in dataclasses.fields(cls)}
    return out


def test_every_setting_is_covered():
    """Every field of every settings object, and each converged setting as the RTI's fallback
    and each RTI setting in the split scheme too (the qualified keys name their field)."""
    keys = {k.split("[")[0] for k in _SETTINGS}
    fields = _fields() - {"Converged.jit"}
    assert fields <= keys
    # the fallback solves one plan at a time: its nominal_above raises (tests/test_guard.py)
    assert {f"RTI.fallback.{f.split('.')[1]}" for f in fields if f.startswith("Converged.")
            and f != "Converged.nominal_above"} <= keys
    assert {f"{f}[split]" for f in fields if f.startswith("RTI.")} - {
        "RTI.split[split]", "RTI.fallback[split]"} <= set(_SETTINGS)
    assert keys - fields <= {f"RTI.fallback.{f.split('.')[1]}" for f in _fields()
                             if f.startswith("Converged.")}


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
    ("pendulum", False, {"scheme": RTI(), "qp_solver": "osqp"}, TypeError, "unexpected keyword"),
    ("pendulum", False, {"mode": "episodic"}, TypeError, "unexpected keyword"),
    ("pendulum", False, {"constraints": Constraints(state_margin=0.0, state_penalty=1.0)},
     ValueError, "nothing to act on"),
    ("pendulum", False, {"config": MPCConfig(), "scheme": "rti"}, TypeError, "not both"),
    ("pendulum", False, {"scheme": "fast"}, ValueError, "scheme must be one of"),
    ("pendulum", False, {"foo": 1}, TypeError, "unexpected keyword"),
])
def test_settings_that_do_not_apply_raise(system, learner, settings, error, match):
    env = _env(system)
    with pytest.raises(error, match=match):
        PseudospectralMPC.from_env(env, online_ssgp() if learner else None, **settings)


def test_the_formerly_ignored_settings_raise():
    """An iteration cap IPOPT's ``max_iterations`` cannot set on another plugin, IPOPT's cap
    given twice, and a state penalty with no soft band to act on (no obstacles, no margin) were
    once accepted and changed nothing; now each is an error."""
    with pytest.raises(ValueError, match=r"max_iterations is IPOPT's"):
        Converged(solver="sqpmethod", max_iterations=1)
    with pytest.raises(ValueError, match=r"max_iterations=\.\.\., not"):
        Converged(solver_options={"ipopt": {"max_iter": 3}})
    with pytest.raises(ValueError, match="nothing to act on"):
        PseudospectralMPC.from_env(_env("cartpole"), constraints=Constraints(
            state_margin=0.0, state_penalty=1e6))
    # where they apply, they are accepted: a margin, or the obstacle's soft margin
    PseudospectralMPC.from_env(_env("cartpole"), constraints=Constraints(state_penalty=1e6))
    PseudospectralMPC.from_env(_env("dubins"), constraints=Constraints(
        state_margin=0.0, state_penalty=1e6))


def test_a_config_is_resolved_once_and_given_whole_or_by_fields():
    """``MPCConfig.resolve`` fills every default for the model (the agent keeps it frozen);
    the same settings given whole or as keywords make equal configurations, and resolving a
    resolved one again changes nothing."""
    env = _env("dubins")
    model = env.unwrapped.nominal_model
    config = MPCConfig(scheme="rti-split", horizon=2.0)
    assert not config.resolved and config.scheme.qp_solver is None
    whole = PseudospectralMPC.from_env(env, online_ssgp(5), config=config)
    fields = PseudospectralMPC.from_env(env, online_ssgp(5), scheme="rti-split", horizon=2.0)

    def settings(config: MPCConfig) -> tuple[MPCConfig, type]:  # a term compares by its type
        return dataclasses.replace(config, term=None), type(config.term)

    assert whole.config.resolved and settings(whole.config) == settings(fields.config)
    resolved = whole.config
    assert resolved.scheme.qp_solver and resolved.horizon.n_nodes is not None
    assert resolved.residual.learn_online is True and resolved.term is not None
    assert settings(resolved.resolve(model, online_ssgp(5))) == settings(resolved)
    with pytest.raises(dataclasses.FrozenInstanceError):
        resolved.scheme = "rti"  # type: ignore[misc]


def test_the_agent_never_changes_the_learner_it_was_given():
    """The MPC learns on its own copy: the caller's learner keeps its (unbound) linear
    features and sees no data, whatever the agent does."""
    env = _env("cartpole", scenario="online")
    given = parametric_ssgp()
    agent = PseudospectralMPC.from_env(env, given, residual=Residual(sensitivities=True),
                                       term="linearized")
    agent.pretrain(collect_initial_data(env, 30, seed=0))
    obs, _ = env.reset(seed=0)
    nxt, *_ = env.step(agent.act(obs))
    agent.observe(obs, agent.diagnostics[-1].action, nxt)
    agent.act(nxt)
    assert agent.learner is not given
    assert given.linear_features == "sensitivities"
    assert getattr(given, "n_samples_seen_", 0) == 0
    assert agent.learner.n_samples_seen_ == 31


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
    assert not PseudospectralMPC.from_env(env, ExactGP()).config.learns_online


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
def test_degradation_warns_once_per_episode_after_a_share_of_the_task_and_is_counted():
    """A degraded episode warns once, and only after WARN_AFTER_FRACTION of the task's
    replans: a degraded start alone (the first few replans) is counted in ``health()`` but
    raises no warning."""
    from gp_agents.mpc.diagnostics import WARN_AFTER_FRACTION

    env = _env("pendulum")
    model = env.unwrapped.nominal_model
    share = int(np.ceil(WARN_AFTER_FRACTION * model.task.duration / model.dt))
    agent = PseudospectralMPC.from_env(env, scheme=Converged(max_iterations=1))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rollout(env, agent, 0, max_steps=share - 1)
    assert agent.health()["degraded"]
    assert not [w for w in caught if issubclass(w.category, ControllerDegradedWarning)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rollout(env, agent, 0, max_steps=share + 2)
        rollout(env, agent, 1, max_steps=share + 2)
    degraded = [w for w in caught if issubclass(w.category, ControllerDegradedWarning)]
    assert len(degraded) == 2, [str(w.message) for w in caught]
    health = agent.health()
    assert health["degraded"] and health["replans"] == share + 2
    assert health["capped"] + health["failed"] >= 3
    quiet = PseudospectralMPC.from_env(env)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ControllerDegradedWarning)
        rollout(env, quiet, 0, max_steps=8)
    assert not quiet.health()["degraded"] and quiet.health()["degraded_replans"] == 0
