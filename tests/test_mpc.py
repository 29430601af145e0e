"""The MPC agent: residual targets, the semi-parametric model, robustness, closed-loop results."""

from __future__ import annotations

import dataclasses

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest
from agent_parts import mesh_of, residual_of

import gp_agents.mpc as mpc_module
import gp_agents.mpc.gp_in_nlp as gp_in_nlp_module
import gp_envs
from gp_agents.agent import rollout
from gp_agents.data import collect_initial_data
from gp_agents.learners import IncrementalSSGP
from gp_agents.mpc import (
    RTI,
    Constraints,
    Converged,
    Episodic,
    GPInNLP,
    LinearizedGP,
    PseudospectralMPC,
    RecedingHorizon,
    Residual,
    StepStatus,
    online_ssgp,
)
from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.gp_pattern import nominal_pattern
from gp_agents.residual import ResidualModel

CART = "gp_envs/CartPoleSwingUp-v0"
QUAD = "gp_envs/Quadrotor-v0"
DUBINS = "gp_envs/DubinsObstacle-v0"


def run_episode(env, agent, seed=0):
    episode = rollout(env, agent, seed)
    return episode.observations[-1], -episode.cost, episode.final_info


def oracle(env):
    """The benchmark's way of handing the truth to an upper-bound MPC."""
    return {"model_source": lambda: gp_envs.oracle_model(env)}


# ------------------------------------------------------------------------ residual targets
@pytest.mark.parametrize("env_id", list(gp_envs.ENV_IDS))
def test_residual_targets_match_the_true_residual(env_id):
    """Finite-difference targets against the oracle's f_true - f_nominal (module doc of
    gp_agents.residual: second-order accurate at the period's midpoint)."""
    env = gym.make(env_id)
    data = collect_initial_data(env, 200, seed=1)
    nominal, truth = env.unwrapped.nominal_model, gp_envs.oracle_model(env)
    res = ResidualModel(nominal)
    Z, Y = res.targets(data.X, data.U, data.X_next)
    mid = 0.5 * (data.X + res.unwrap_like(data.X_next, data.X))
    true = (truth.f(mid, data.U) - nominal.f(mid, data.U))[:, res.uncertain_indices]
    assert Z.shape == (200, res.n_inputs) and Y.shape == true.shape
    scale = np.sqrt(np.mean(true**2, axis=0)) + 1e-12
    rel_rms = np.sqrt(np.mean((Y - true) ** 2, axis=0)) / scale
    assert np.all(rel_rms < 0.05), rel_rms


def test_residual_targets_vanish_when_the_model_is_true():
    env = gym.make(CART)
    data = collect_initial_data(env, 50, seed=0)
    res = ResidualModel(gp_envs.oracle_model(env))
    _, Y = res.targets(data.X, data.U, data.X_next)
    # observations are float32: ~5e-7 rounding of a state divided by dt = 0.05 s
    np.testing.assert_allclose(Y, 0.0, atol=1e-4)
    _, Y64 = res.targets(data.X, data.U, gp_envs.oracle_model(env).step(data.X, data.U))
    np.testing.assert_allclose(Y64, 0.0, atol=1e-9)


def test_residual_targets_reject_bad_input():
    env = gym.make(CART)
    res = ResidualModel(env.unwrapped.nominal_model)
    with pytest.raises(ValueError, match="expected"):
        res.targets(np.zeros((3, 4)), np.zeros((3, 2)), np.zeros((3, 4)))
    with pytest.raises(ValueError, match="NaN"):
        res.targets(np.full((3, 4), np.nan), np.zeros((3, 1)), np.zeros((3, 4)))


def test_planning_model_adds_the_learner_mean_on_the_accelerations():
    """The dynamics the agent's OCP is built with: nominal physics plus S mean_GP(phi(x, u)),
    checked against the nominal model's numeric f and the learner's numeric predict."""
    env = gym.make(CART)
    model = env.unwrapped.nominal_model
    agent = PseudospectralMPC.from_env(env, IncrementalSSGP(20, random_state=0))
    rng = np.random.default_rng(0)
    Z = rng.normal(size=(60, residual_of(agent).n_inputs))
    agent.learner.fit(Z, np.column_stack([np.sin(Z[:, 0]), np.cos(Z[:, 1])]))
    planning = agent._planner().planning
    assert agent.planner.ocp.problem.dynamics == planning.dynamics  # the formula the NLP uses
    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 1)
    p = ca.SX.sym("p", planning.n_params)
    fn = ca.Function("f", [x, u, p], [planning.dynamics(x, u, p, ca.SX(0, 1))])
    xs, us = np.array([0.1, 2.0, -0.3, 1.0]), np.array([3.0])
    got = np.asarray(fn(xs, us, planning.param_values())).ravel()
    expected = model.f(xs, us)
    expected[[2, 3]] += agent.learner.predict(residual_of(agent).inputs(xs, us))[0]
    np.testing.assert_allclose(got, expected, rtol=1e-10)
    # the nominal agent's planning model is the physics alone
    nominal = PseudospectralMPC.from_env(env)._planner().planning
    fn = ca.Function("f", [x, u, p[:nominal.n_params]],
                     [nominal.dynamics(x, u, p[:nominal.n_params], ca.SX(0, 1))])
    np.testing.assert_allclose(np.asarray(fn(xs, us, nominal.param_values())).ravel(),
                               model.f(xs, us), rtol=1e-12)


def test_model_inputs_are_the_states_the_parametric_model_depends_on():
    """Quadrotor: the accelerations depend on the attitude, the body rates and the thrusts (with
    mass and inertia symbolic), not on position or velocity; Dubins' rates only on the heading."""
    quad = gym.make(QUAD).unwrapped.nominal_model
    assert ResidualModel.model_inputs(quad, quad.dynamic_indices) == (3, 4, 5, 9, 10, 11)
    res = ResidualModel(quad, input_indices="model")
    assert res.n_inputs == 3 + 6 + 4  # body rates, sin/cos of three angles, thrusts
    dubins = gym.make(DUBINS).unwrapped.nominal_model
    assert ResidualModel(dubins, input_indices="model").input_indices == (2,)
    with pytest.raises(ValueError, match="input_indices"):
        ResidualModel(quad, input_indices="everything")


def test_nominal_hessian_gives_the_exact_hessians_plan():
    """hessian='nominal' changes IPOPT's iterates, not the optimality conditions: its plan is
    a KKT point of the exact NLP, so the exact-Hessian IPOPT started there (with its
    multipliers) stays there. (Started from the same cold guess, the two may well end in
    different local optima of the swing-up: the iterates differ.)"""
    env = gym.make(CART, scenario="online")
    data = collect_initial_data(env, 200, seed=0)
    agents = {}
    for hessian in ("exact", "nominal"):
        agent = PseudospectralMPC.from_env(env, online_ssgp(),
                                           term=GPInNLP(hessian=hessian),
                                           residual=Residual(inputs="model"),
                                           scheme=Converged(warm_start_duals=True))
        agent.pretrain(data)
        obs, _ = env.reset(seed=0)
        agent.act(obs)
        assert agent.diagnostics[-1].success
        agents[hessian] = agent
    assert residual_of(agents["exact"]).n_inputs == 5
    nominal, ocp = agents["nominal"].plan.solution, agents["exact"].planner.ocp
    again = ocp.solve(p=agents["exact"].planner.planning.param_values(), x0=obs,
                      initial_guess=nominal, multipliers=(nominal.nlp_lam_x, nominal.nlp_lam_g))
    assert again.success and again.iterations <= 3
    np.testing.assert_allclose(again.nlp_x, nominal.nlp_x, atol=1e-6)


@pytest.mark.parametrize("env_id", [CART, QUAD])
def test_residual_linearization_matches_finite_differences(env_id):
    """ResidualModel.linearize: the learner's mean and its (x, u) Jacobian through the input
    map (sin/cos of angles), against central differences of predict(inputs(x, u))."""
    env = gym.make(env_id)
    data = collect_initial_data(env, 100, seed=0)
    res = ResidualModel(env.unwrapped.nominal_model)
    learner = online_ssgp(20).fit(*res.targets(data.X, data.U, data.X_next))
    X, U = data.X[::25], data.U[::25]
    mean, J, var = res.linearize(learner, X, U, variance=True)
    np.testing.assert_allclose(mean, learner.predict(res.inputs(X, U)), atol=1e-12)
    np.testing.assert_allclose(var, learner.predict(res.inputs(X, U), return_std=True)[1] ** 2,
                               rtol=1e-10)
    n, eps = X.shape[1], 1e-6
    for j in range(n + U.shape[1]):
        Xp, Xm, Up, Um = X.copy(), X.copy(), U.copy(), U.copy()
        if j < n:
            Xp[:, j] += eps
            Xm[:, j] -= eps
        else:
            Up[:, j - n] += eps
            Um[:, j - n] -= eps
        fd = (learner.predict(res.inputs(Xp, Up)) - learner.predict(res.inputs(Xm, Um))) / (2 * eps)
        np.testing.assert_allclose(J[:, :, j], fd, atol=1e-6 * (1 + np.abs(fd).max()))
    assert set(res.jacobian_columns) == set(range(n + U.shape[1]))
    with pytest.raises(ValueError, match="expected X"):
        res.linearize(learner, X[:, :-1], U)
    with pytest.raises(ValueError, match="non-finite"):
        res.linearize(learner, np.full_like(X, np.nan), U)
    quad = ResidualModel(gym.make(QUAD).unwrapped.nominal_model, input_indices="model")
    assert 0 not in quad.jacobian_columns  # the position is not a learner input


def test_relinearized_plan_is_the_exact_plan():
    """A fixed point of the re-linearization loop is a KKT point of the exact OCP: started
    from the exact plan, the linearized solve stays on it (learned_dynamics docstring)."""
    env = gym.make(CART, scenario="online")
    data = collect_initial_data(env, 200, seed=0)
    obs, _ = env.reset(seed=0)
    exact = PseudospectralMPC.from_env(env, online_ssgp()).pretrain(data)
    exact.act(obs)
    sol = exact.plan.solution
    assert sol.success
    lin = PseudospectralMPC.from_env(
        env, exact.learner, term=LinearizedGP(max_linearizations=5, tol=1e-9))
    planner = lin._planner()
    plan, info = planner._solve(planner.planning.param_values(), obs, sol, cold=False)
    assert plan.success and info["solves"] >= 1
    np.testing.assert_allclose(plan.x, sol.x, atol=1e-5)
    np.testing.assert_allclose(plan.u, sol.u, atol=1e-4)
    assert info["linearization_error"] < 1.0
    # from a cold start (a straight-line guess) the first expansion is far off: the agent
    # re-linearizes about each iterate until the plan is within tolerance or solves run out
    cold = PseudospectralMPC.from_env(env, exact.learner, term="linearized")
    cold.act(obs)
    first = cold.diagnostics[-1]
    assert first.success and 1 < first.solves <= mpc_module.COLD_START_LINEARIZATIONS


def test_linearized_nlp_has_no_learner_parameters_and_is_built_once():
    env = gym.make(DUBINS)
    data = collect_initial_data(env, 100, seed=0)
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, online_ssgp(20), term="linearized",
                                       constraints=Constraints(uncertainty_radius=1.0)
                                       ).pretrain(data)
    for _ in range(3):
        action = agent.act(obs)
        nxt, *_ = env.step(action)
        agent.observe(obs, action, nxt)
        obs = nxt
    assert agent.counts.builds == 1
    problem = agent.planner.ocp.problem
    assert problem.n_params == len(agent.model.param_names)
    d, cols = residual_of(agent).n_outputs, residual_of(agent).jacobian_columns
    assert problem.n_node_params == d * (1 + len(cols)) + 2  # + frozen variances of x, y
    diag = agent.diagnostics_arrays()
    assert np.all(diag["solves"][1:] == 1)  # warm steps: one solve (max_linearizations=1)
    assert np.all(np.isfinite(diag["linearization_error"]))
    with pytest.raises(ValueError, match="term must be one of"):
        PseudospectralMPC.from_env(env, online_ssgp(5), term="taylor")
    with pytest.raises(ValueError, match="max_linearizations"):
        LinearizedGP(max_linearizations=0)
    with pytest.raises(TypeError, match="term must be a name"):
        PseudospectralMPC.from_env(env, online_ssgp(5), term=3)



def test_without_a_learned_term_converged_puts_the_gp_in_the_nlp_and_rti_the_systems_term():
    """``term=None``: the paper's OCP (the GP inside the NLP) when converged; for
    the real-time iterations the system's tuned term (``gp_agents.mpc.tuning``: the quadrotor
    has the pattern term, the others the full linearization); an explicit name wins;
    a registered name that is no learned term is a named error."""
    from gp_agents.mpc import PatternLinearizedGP, RTITuning, register_rti_tuning
    from gp_agents.mpc.config import default_term
    from gp_agents.mpc.tuning import RTI_TUNING

    for env_id, rti_term in ((QUAD, PatternLinearizedGP), (CART, LinearizedGP),
                             (DUBINS, LinearizedGP)):
        env = gym.make(env_id)
        assert type(PseudospectralMPC.from_env(env, online_ssgp(5)).config.term) is GPInNLP
        for scheme in ("rti", "rti-split"):
            agent = PseudospectralMPC.from_env(env, online_ssgp(5), scheme=scheme)
            assert type(agent.config.term) is rti_term, (env_id, scheme)
        explicit = PseudospectralMPC.from_env(env, online_ssgp(5), scheme="rti",
                                              term="zero-order")
        assert explicit.config.term.name == "zero-order"
    assert default_term("rti", None) == "linearized"
    assert default_term("converged", None) == "exact"
    register_rti_tuning("tuning-test", RTITuning(learned_term="taylor"))
    try:
        with pytest.raises(ValueError, match="learned_term 'taylor'"):
            default_term("rti", "tuning-test")
    finally:
        del RTI_TUNING["tuning-test"]


# ------------------------------------------------------------------------ agent contract
def test_act_returns_float32_in_bounds_and_rejects_bad_observations():
    env = gym.make(CART)
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env)
    action = agent.act(obs)
    assert action.dtype == np.float32 and env.action_space.contains(action)
    with pytest.raises(ValueError, match="finite"):
        agent.act(np.full(4, np.nan))
    with pytest.raises(ValueError, match="shape"):
        agent.act(np.zeros(5))


def test_unfitted_learner_is_a_clear_error():
    env = gym.make(CART)
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, IncrementalSSGP(10))
    with pytest.raises(RuntimeError, match="pretrain"):
        agent.act(obs)


def test_bad_settings_raise():
    env = gym.make(CART)
    with pytest.raises(ValueError):
        PseudospectralMPC.from_env(env, horizon=-1.0)
    with pytest.raises(TypeError):
        PseudospectralMPC.from_env(env, mode="episodic")  # the former flat keywords are gone
    with pytest.raises(TypeError):
        PseudospectralMPC.from_env(gym.make("CartPole-v1"))


def test_a_learned_model_too_large_to_plan_with_is_a_clear_error(monkeypatch):
    """An exact GP over many nodes once exhausted 24 GB inside CasADi; now it is a ValueError."""
    from gp_agents.learners import ExactGP

    env = gym.make(CART)
    data = collect_initial_data(env, 40, seed=0)
    small = PseudospectralMPC.from_env(env, ExactGP(), horizon=RecedingHorizon(n_intervals=1)
                                       ).pretrain(data)
    large = PseudospectralMPC.from_env(env, ExactGP(), horizon=RecedingHorizon(n_intervals=3)
                                       ).pretrain(data)
    obs, _ = env.reset(seed=0)
    # the size proxy grows with the collocation nodes and with the GP's training points
    # (the agents' own attached terms, which know their learners)
    size = small._term.model_size(mesh_of(small).n_collocation)
    assert large._term.model_size(mesh_of(large).n_collocation) > 2.5 * size
    more = PseudospectralMPC.from_env(env, ExactGP(), horizon=RecedingHorizon(n_intervals=1)
                                      ).pretrain(collect_initial_data(env, 80, seed=0))
    assert 1.8 * size < more._term.model_size(mesh_of(more).n_collocation) < 2.2 * size
    monkeypatch.setattr(gp_in_nlp_module, "MAX_LEARNED_MODEL_SIZE", 2 * size)
    assert small.act(obs) in env.action_space
    with pytest.raises(ValueError, match="too large to plan with"):
        large.act(obs)


def test_solver_is_built_once_and_learning_updates_parameters_only():
    env = gym.make(CART)
    agent = PseudospectralMPC.from_env(env, IncrementalSSGP(20, forgetting_factor=0.99),
                                       horizon=RecedingHorizon(replan_every=2))
    agent.pretrain(collect_initial_data(env, 100, seed=0))
    obs, _ = env.reset(seed=0)
    for _ in range(10):
        a = agent.act(obs)
        nxt, *_ = env.step(a)
        agent.observe(obs, a, nxt)
        obs = nxt
    d = agent.diagnostics_arrays()
    assert agent.counts.builds == 1
    # a plan is used for at most p = 2 periods (a failed solve is retried at the next step)
    replans = np.flatnonzero(d["replanned"])
    assert replans[0] == 0 and np.all(np.diff(replans) <= 2) and len(replans) >= 5
    # every transition observed so far reaches the learner before a re-solve (Algorithm 1)
    assert d["learner_samples"][replans].tolist() == (100 + replans).tolist()


def test_applied_action_is_the_plans_held_first_period():
    """Errata note 5 settled: the action is the plan's held decision for the first period, and
    the plan's model under it reproduces the plan's own state one period later (the plant's
    zero-order hold), here with the oracle's model, so plan and plant agree."""
    env = gym.make(CART)
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, **oracle(env))
    for _ in range(15):  # into the swing, where the control is far from constant
        action = agent.act(obs)
        sol = agent.plan.solution
        held = sol.u[: sol.nodes_per_interval[0], 0]
        assert agent.plan.held[0] and np.ptp(held) < 1e-9
        assert action[0] == pytest.approx(np.float32(held[0]))
        truth = gp_envs.oracle_model(env)
        stepped = truth.step(sol.state(0.0), sol.u[0])
        np.testing.assert_allclose(stepped, sol.state(truth.dt), atol=1e-5)
        obs, *_ = env.step(action)
    assert np.ptp(agent.diagnostics_arrays()["action"]) > 5.0  # the swing-up is under way


def test_failed_solves_fall_back_without_crashing():
    env = gym.make(CART)
    agent = PseudospectralMPC.from_env(env, **oracle(env))
    obs, _ = env.reset(seed=0)
    for _ in range(3):  # good plans first
        obs, *_ = env.step(agent.act(obs))
    agent.config = dataclasses.replace(agent.config, scheme=Converged(max_iterations=1))
    agent.planner = None  # rebuild with a solver that cannot converge
    for _ in range(3):
        action = agent.act(obs)
        assert env.action_space.contains(action)
        obs, *_ = env.step(action)
    assert agent.counts.failures == 3 and agent.counts.fallbacks == 3
    assert agent.counts.capped == 6  # each failed solve and its retry hit the iteration cap


def test_episodic_mode_plans_once():
    env = gym.make(CART)
    agent = PseudospectralMPC.from_env(env, horizon=Episodic(), **oracle(env))
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(agent.act(obs))
    assert agent.counts.solves == 1 and agent.config.schedule.horizon == pytest.approx(6.0)
    assert mesh_of(agent).describe() == "120 held periods x 3 nodes"
    actions = agent.diagnostics_arrays()["action"][:, 0]
    u = agent.plan.solution.u[:, 0].reshape(120, 3)
    np.testing.assert_array_equal(actions, u[:5, 0].astype(np.float32))


def test_episodic_oracle_plan_is_what_the_quadrotor_plant_does():
    """Every period of the episodic plan is held, so the plan's states at the period
    boundaries are the plant's RK4 steps under the plan's actions (within 1e-6), and the plan
    keeps the attitude inside the box at every boundary."""
    env = gym.make(QUAD, scenario="gp")
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, horizon=Episodic(), **oracle(env))
    agent.act(obs)
    plan, truth = agent.plan, gp_envs.oracle_model(env)
    assert plan.solution.success
    t = np.arange(121) * truth.dt
    X = plan.solution.state(t)
    U = np.array([plan.action(k, truth.u_lb, truth.u_ub) for k in range(120)])
    stepped = np.array([truth.step(X[k], U[k]) for k in range(120)])
    assert np.max(np.abs(stepped - X[1:])) < 1e-6
    lb, ub = truth.x_lb - 1e-9, truth.x_ub + 1e-9
    assert np.all((lb <= X) & (ub >= X))


def test_agent_follows_a_redrawn_nominal_model_without_rebuilding():
    env = gym.make(DUBINS)
    agent = PseudospectralMPC.from_env(env)
    seen = []
    for seed in (0, 1):
        obs, _ = env.reset(seed=seed)
        agent.reset()
        agent.act(obs)
        seen.append(agent.model.params["b1"])
        assert agent.model is env.unwrapped.nominal_model
    assert seen[0] != seen[1] and agent.counts.builds == 1


# ------------------------------------------------------------------------ closed loop
def test_cartpole_online_table_oracle_swings_up_and_nominal_does_not():
    """The paper's table 2 setting: the damping-free nominal model cannot swing up the true
    (heavily damped) cart pole within the force bound; the true model can."""
    env = gym.make(CART, scenario="online")
    _obs, _, info = run_episode(env, PseudospectralMPC.from_env(env, **oracle(env)))
    assert info["success"]
    _, _, info = run_episode(env, PseudospectralMPC.from_env(env))
    assert not info["success"]


def test_quadrotor_nominal_mass_error_leaves_a_height_offset():
    env = gym.make(QUAD, scenario="gp")
    obs, _, _ = run_episode(env, PseudospectralMPC.from_env(env))
    goal = env.unwrapped.nominal_model.task.goal
    assert obs[2] - goal[2] > 0.02  # sags (NED: +z is down): thrust planned for 0.9 kg
    obs, _, _ = run_episode(env, PseudospectralMPC.from_env(env, **oracle(env)))
    assert np.max(np.abs(obs[:3] - goal[:3])) < 0.01


@pytest.mark.slow
@pytest.mark.parametrize("recipe", ["ssgp-mpc", "ssgp-mpc-linearized"])
def test_ssgp_mpc_swings_up_the_damped_cart_pole(recipe):
    """The README's claim, through the benchmark's own recipes (the GP in the NLP, and
    linearized per node), on the README's first seeds 0-3: at least 3 of 4 swing up (the
    nominal MPC: none).

    A single episode is not a robust test: the swing-up is marginal, and the last bits of the
    learner's linear algebra flip seed 0 between a swing-up and leaving the track (measured:
    BLAS thread counts, hosts, and a change of the SSGP code that only reordered floating-point
    operations; seed 0 of the linearized recipe was a strict expected failure until that
    change). Each host and code version is deterministic; the rate over seeds is what holds."""
    from benchmarks.trial import TrialSpec, execute

    records = [execute(TrialSpec("episode", "cartpole", "online", recipe, s))
               for s in range(4)]
    assert all(r["status"] == "ok" for r in records), [r.get("error") for r in records]
    successes = [bool(r["metrics"]["success"]) for r in records]
    assert sum(successes) >= 3, [r["metrics"]["cost"] for r in records]


@pytest.mark.slow
def test_ssgp_mpc_removes_the_quadrotor_height_offset():
    env = gym.make(QUAD, scenario="gp")
    agent = PseudospectralMPC.from_env(env, online_ssgp())
    agent.pretrain(collect_initial_data(env, 200, seed=0))
    obs, _, _ = run_episode(env, agent, seed=0)
    goal = env.unwrapped.nominal_model.task.goal
    assert np.max(np.abs(obs[:3] - goal[:3])) < 0.01


def test_learner_trained_against_one_nominal_model_is_not_silently_reused_with_another():
    env = gym.make(DUBINS)
    data = collect_initial_data(env, 60, seed=0)
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, IncrementalSSGP(10)).pretrain(data)
    assert residual_of(agent).model is env.unwrapped.nominal_model  # targets use the current one
    agent.act(obs)
    obs, _ = env.reset(seed=1)  # redraws the nominal model
    with pytest.raises(RuntimeError, match="pretrain"):
        agent.act(obs)


# ------------------------------------------------------------------------ real-time iteration
@pytest.mark.parametrize("mu", [0.0, 0.1], ids=["gauss-newton", "levenberg-marquardt"])
def test_a_kkt_point_is_a_fixed_point_of_the_rti_step(mu):
    """The Gauss-Newton QP step from a converged plan (no shift) does not move it: dw = 0 at a
    KKT point, so RTI tracks the converged solution; a Levenberg-Marquardt term does not
    change that."""
    env = gym.make(CART, scenario="gp")
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, scheme=RTI(levenberg_marquardt=mu))
    agent.act(obs)  # the cold start: a converged solve
    sol, planner = agent.plan.solution, agent.planner
    assert sol.success and sol.status == "Solve_Succeeded"
    w, _, violation, *_ = planner._qp_step(sol.nlp_x, planner.planning.param_values(),
                                           np.zeros(sol.nlp_x.size))
    np.testing.assert_allclose(np.asarray(w).ravel(), sol.nlp_x, atol=1e-5)
    assert float(violation) < 1e-6


def test_the_levenberg_marquardt_term_is_mu_on_the_rti_hessians_diagonal():
    """``levenberg_marquardt=mu``: the QP's Hessian is the objective's plus ``mu I`` (the
    same point, the same parameters), the Dubins vehicle's registered default reaches its
    planner, and a negative or non-finite ``mu`` is refused."""
    env = gym.make(DUBINS)
    env.reset(seed=0)
    plain = PseudospectralMPC.from_env(env, scheme=RTI(levenberg_marquardt=0.0))._planner()
    damped = PseudospectralMPC.from_env(env, scheme=RTI(levenberg_marquardt=0.25))._planner()
    w = np.random.default_rng(0).normal(size=plain.ocp.n_variables)
    p = plain.planning.param_values()
    H0, H1 = (np.asarray(ca.DM(pl._derivatives(w, p)[3])) for pl in (plain, damped))
    np.testing.assert_allclose(H1 - H0, 0.25 * np.eye(w.size), atol=1e-12)
    from gp_agents.mpc import rti_tuning

    default = rti_tuning("dubins").levenberg_marquardt
    assert default > 0 and PseudospectralMPC.from_env(env, scheme="rti-split")._planner() \
        .levenberg_marquardt == default
    for bad in (-1e-3, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="levenberg_marquardt"):
            PseudospectralMPC.from_env(env, scheme=RTI(levenberg_marquardt=bad))


@pytest.mark.parametrize("term", ["linearized", "linearized-pattern", "zero-order"])
def test_the_exact_ocps_kkt_point_is_a_fixed_point_of_the_learned_rti_step(term):
    """From the plan of the GP inside the NLP solved by IPOPT and its multipliers, one
    Gauss-Newton SQP step (``RTIPlanner.iterate``, no time shift) with the GP linearized per
    node, or frozen per node with the adjoint-corrected gradient, does not move: the same
    OCP's KKT point. The frozen values without the correction (zero multipliers) move away.
    (Repeating the step is no test of convergence: Gauss-Newton SQP on the swing-up drifts
    away from this KKT point with either term: seen ad hoc, not asserted.)"""
    env = gym.make(CART, scenario="online")
    data = collect_initial_data(env, 200, seed=0)
    obs, _ = env.reset(seed=0)
    exact = PseudospectralMPC.from_env(env, online_ssgp(20)).pretrain(data)
    exact.act(obs)
    sol = exact.plan.solution
    assert sol.success
    agent = PseudospectralMPC.from_env(env, exact.learner, term=term,
                                       scheme="rti")
    planner = agent._planner()
    w, lam, violation = planner.iterate(obs, sol.nlp_x, sol.nlp_lam_g)
    np.testing.assert_allclose(w, sol.nlp_x, atol=1e-5)
    np.testing.assert_allclose(lam, sol.nlp_lam_g, atol=1e-4 * np.max(np.abs(sol.nlp_lam_g)))
    assert violation < 1e-6
    if term != "linearized":
        w0, _, _ = planner.iterate(obs, sol.nlp_x, np.zeros(sol.nlp_lam_g.size))
        assert np.max(np.abs(w0 - sol.nlp_x)) > 1e-2


def test_zero_order_and_pattern_rti_keep_the_nominal_qp_structure_and_swing_up():
    """The frozen GP value and the expansion on the nominal pattern add no constraint-Jacobian
    entries to the RTI's QP (the linearized one adds a block per node), and their closed
    loops on the cart pole ``gp`` scenario are the linearized RTI's."""
    env = gym.make(CART, scenario="gp")
    data = collect_initial_data(env, 100, seed=0)
    plans = {}
    for term in ("none", "linearized", "linearized-pattern", "zero-order"):
        learner = None if term == "none" else online_ssgp(20)
        agent = PseudospectralMPC.from_env(env, learner, scheme="rti",
                                           **({} if learner is None else
                                              {"term": term}))
        if learner is not None:
            agent.pretrain(data)
        ep = rollout(env, agent, 0)
        nnz = ca.jacobian(agent.planner.ocp.nlp["g"], agent.planner.ocp.nlp["x"]).nnz()
        plans[term] = (ep, nnz, agent)
    assert plans["zero-order"][1] == plans["none"][1] < plans["linearized"][1]
    assert plans["linearized-pattern"][1] == plans["none"][1]
    lin = plans["linearized"][0]
    assert lin.success
    for term in ("zero-order", "linearized-pattern"):
        ep, _, agent = plans[term]
        assert ep.success and ep.cost == pytest.approx(lin.cost, rel=0.01)
        assert agent.planner.counts.rti_steps > 100


def test_the_nominal_pattern_is_the_dubins_kinematics():
    """Dubins vehicle: x' = (1 - b1) u1 cos(psi), y' = (1 - b1) u1 sin(psi), psi' = (1 - b2)
    u2 (the env's docstring), so the x and y rates depend on psi and u1, the heading rate on
    u2 only; the learner's dependence on the position is dropped. As (output, column of
    [x, y, psi, u1, u2]) pairs in column-major order."""
    env = gym.make(DUBINS)
    pattern = nominal_pattern(ResidualModel(env.unwrapped.nominal_model))
    assert pattern == ((0, 2), (1, 2), (0, 3), (1, 3), (2, 4))


@pytest.mark.parametrize("term", ["none", "linearized", "linearized-pattern", "zero-order"])
def test_the_split_rtis_feedback_at_the_predicted_state_is_the_one_call_step(term):
    """Preparation (shift with the predicted X(t0), expansion, QP data) then feedback with the
    measured state equal to the prediction gives the one-call RTI's step from the same plan
    and state (its QP solution, multipliers and constraint violation); from another state the
    feedback's plan starts at that state."""
    env = gym.make(CART, scenario="gp")
    learner = None if term == "none" else online_ssgp(10)
    kwargs = {} if learner is None else {"term": term}
    agent = PseudospectralMPC.from_env(env, learner, scheme="rti-split", **kwargs)
    if learner is not None:
        agent.pretrain(collect_initial_data(env, 60, seed=0))
    obs, _ = env.reset(seed=0)
    for _ in range(30):  # closed-loop steps (no learning) into the RTI's accepted steps
        u = agent.act(obs)
        obs, *_ = env.step(u)
    planner, previous = agent.planner, agent.plan
    # the one-call RTI on the same episode's nominal model and the same fitted learner
    reference = PseudospectralMPC.from_env(env, agent.learner, scheme="rti",
                                           **kwargs)._planner()
    step = previous.step + mesh_of(agent).held_periods
    planner.prepare(previous, step)
    prep = planner._prepared
    x_pred = prep["w_s"][:obs.size].copy()
    fed = planner._feedback(prep["w_s"], x_pred, prep["h"], prep["grad"], prep["a"], prep["g"],
                            prep["p"], *prep["guess"])
    args = [previous.solution.nlp_x, x_pred, planner.planning.param_values()]
    if learner is None:
        one_call = reference._step(*args)
    else:
        theta = reference.planning.term.expansion_param_values()
        fn = reference._learned_step(theta.size)
        lam = [previous.solution.nlp_lam_g] if fn.fn.n_in() == 5 else []
        one_call = fn(*args, theta, *lam)
    for a, b in zip(fed[:5], one_call[:5], strict=True):  # w, u, violation, lam_g, lam_x
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-9)
    x = x_pred + 0.01
    plan, _ = planner.plan(x, previous, step)
    assert planner.counts.prepared == 29 + 1  # steps 1-29 and this one
    np.testing.assert_allclose(plan.solution.x[0], x, atol=1e-10)


def test_the_split_rtis_predicted_active_set_is_that_of_the_qp_at_the_predicted_state():
    """The preparation predicts the feedback's active set by solving the QP at the predicted
    state: fed that very state, the feedback settles in one active-set iteration, at the same
    solution as from the shifted plan's set (the one-call step's guess), which needed more
    iterations wherever the plan reached or left a bound (the swing-up's saturated force)."""
    env = gym.make(CART, scenario="gp")
    agent = PseudospectralMPC.from_env(env, scheme="rti-split")
    planner = agent._planner()
    assert isinstance(planner.qp_solver, ActiveSetQP)
    reference = PseudospectralMPC.from_env(env, scheme="rti")._planner()
    obs, _ = env.reset(seed=0)
    shifted_set_iterations = []
    for _ in range(60):
        u = agent.act(obs)
        obs, *_ = env.step(u)
        prep, previous = planner._prepared, agent.plan
        if prep is None or previous.solution.status != "RTI":
            continue
        x_pred = prep["w_s"][:obs.size].copy()
        fed = planner._feedback(prep["w_s"], x_pred, prep["h"], prep["grad"], prep["a"],
                                prep["g"], prep["p"], *prep["guess"])
        one_call = reference._step(previous.solution.nlp_x, x_pred,
                                   planner.planning.param_values())
        if one_call[5][0] >= 1:  # the active-set iterations settled (0: the fallback)
            np.testing.assert_allclose(fed[0], one_call[0], rtol=1e-8, atol=1e-9)
            assert fed[5][0] == 1
            shifted_set_iterations.append(int(one_call[5][0]))
    assert len(shifted_set_iterations) > 30 and max(shifted_set_iterations) > 1


def test_split_rti_closed_loop_records_latency_and_preparation():
    env = gym.make(CART, scenario="gp")
    one_call = PseudospectralMPC.from_env(env, scheme="rti")
    reference = rollout(env, one_call, 0)
    agent = PseudospectralMPC.from_env(env, scheme="rti-split")
    split = rollout(env, agent, 0)
    d = agent.diagnostics_arrays()
    assert split.success and split.cost == pytest.approx(reference.cost, rel=0.01)
    assert agent.planner.counts.prepared > 100 and agent.planner.counts.unprepared < 5
    assert np.all(d["preparation_time"][1:] > 0) and d["preparation_time"][0] > 0
    assert np.all(d["preparation_time"] < d["act_time"])


def test_rti_tracks_the_converged_mpc_and_its_safety_net_falls_back_to_it():
    env = gym.make(CART, scenario="gp")
    converged = rollout(env, PseudospectralMPC.from_env(env), 0)
    agent = PseudospectralMPC.from_env(env, scheme="rti")
    rti = rollout(env, agent, 0)
    d = agent.diagnostics_arrays()
    steps = d["status"] == "RTI"
    assert rti.success and steps.sum() > 100 and agent.planner.counts.rti_rejected < 15
    assert np.all(d["iterations"][steps] == 1)
    assert rti.cost == pytest.approx(converged.cost, rel=0.02)
    # every step rejected (a tolerance no step meets): the converged solve from the same
    # shifted plan, warm-started with the multipliers
    strict = PseudospectralMPC.from_env(env, scheme="rti")
    strict._planner().max_violation = -1.0
    fallback = rollout(env, strict, 0)
    assert strict.planner.counts.rti_rejected == strict.planner.counts.rti_steps == 119
    assert fallback.cost == pytest.approx(converged.cost, rel=1e-3)
    with pytest.raises(ValueError, match="scheme must be one of"):
        PseudospectralMPC.from_env(env, scheme="sometimes")


@pytest.mark.parametrize(("term_name", "kappa"), [("linearized", 0.0), ("linearized", 1.0),
                                                   ("linearized-pattern", 1.0)],
                         ids=["mean", "with-variance", "pattern-with-variance"])
def test_the_rti_steps_compiled_expansion_is_the_numeric_one(term_name, kappa):
    """The SSGP RTI linearizes inside its one compiled step (the learner's exported
    parameters in, matrix operations over the nodes): its node parameters, the plan it gives
    and its recorded expansion error equal the numeric path's (``node_param_values`` at the
    shifted plan, the same QP step, ``plan_error`` at the new plan), with the uncertainty
    radius's variances too. (The pattern term's QP step has the adjoint correction, tested
    by the fixed-point test; here its expansion and error.)"""
    env = gym.make(DUBINS)
    # without the recovery: the steps compared are the plain ones (a recovered step's plan is
    # the recovery's, tested below)
    agent = PseudospectralMPC.from_env(env, online_ssgp(10),
                                       scheme=mpc_module.RTI(recovery_iterations=0),
                                       term=term_name,
                                       constraints=Constraints(uncertainty_radius=kappa))
    agent.pretrain(collect_initial_data(env, 60, seed=0))
    obs, _ = env.reset(seed=0)
    accepted = 0
    for k in range(40):
        if k >= 2:  # compare at the steps the RTI accepts
            agent._learn()
            planner, term = agent.planner, agent.planner.planning.term
            previous, p = agent.plan, planner.planning.param_values()
            ws = np.asarray(planner._shift(previous.solution.nlp_x, obs)).ravel()
            shifted = planner.ocp.solution_from_primal(ws, p, status="shifted", success=True)
            q = term.node_param_values(shifted.x_nodes, shifted.u)
            theta = term.expansion_param_values()
            X, U = ca.MX.sym("X", *shifted.x_nodes.T.shape), ca.MX.sym("U", *shifted.u.T.shape)
            T = ca.MX.sym("theta", theta.size)
            expansion = ca.Function("q", [X, U, T], [term.node_param_expr(X, U, T)])
            np.testing.assert_allclose(
                np.asarray(expansion(shifted.x_nodes.T, shifted.u.T, theta)).T, q,
                rtol=1e-10, atol=1e-12)
            plan, record = planner.plan(obs, previous, agent._step)
            if record["status"] == "RTI":
                accepted += 1
                if term_name == "linearized":
                    w_ref = np.asarray(planner._qp_step(ws, np.concatenate([p, q.ravel()]),
                                                        np.zeros(ws.size))[0])
                    np.testing.assert_allclose(plan.solution.nlp_x, w_ref.ravel(),
                                               rtol=1e-9, atol=1e-9)
                assert record["linearization_error"] == pytest.approx(
                    term.plan_error(plan.solution), rel=1e-9)
                assert record["linearization_error"] > 0
                if accepted == 3:
                    break
        u = agent.act(obs)
        nxt, *_ = env.step(u)
        agent.observe(obs, u, nxt)
        obs = nxt
    assert accepted == 3


@pytest.mark.parametrize("learner", ["ssgp", "linear"])
def test_the_pattern_terms_gap_from_the_expansion_is_the_ads(learner):
    """The pattern term's adjoint correction inside the compiled step comes from the
    expansion's own Jacobians (``jacobian_gap_nodes_expr``, no second pass through the
    learner): equal to the gradient of ``jacobian_gap_expr`` by AD at the same point, with
    the full and the mean-only parameter vectors."""
    env = gym.make(DUBINS)
    model = (online_ssgp(10) if learner == "ssgp"
             else online_ssgp(10, linear_features=True, input_saturation=30.0))
    agent = PseudospectralMPC.from_env(env, model, scheme="rti",
                                       term="linearized-pattern")
    agent.pretrain(collect_initial_data(env, 60, seed=0))
    obs, _ = env.reset(seed=0)
    agent.act(obs)
    planner, term = agent.planner, agent.planner.planning.term
    p = planner.planning.param_values()
    ws = agent.plan.solution.nlp_x
    sol = planner.ocp.solution_from_primal(ws, p, status="s", success=True)
    q = term.node_param_values(sol.x_nodes, sol.u)
    lam = np.random.default_rng(0).standard_normal(planner.ocp.nlp["g"].numel())
    for theta in (agent.learner.casadi_param_values(), term.expansion_param_values()):
        W, T = ca.MX.sym("w", ws.size), ca.MX.sym("theta", theta.size)
        P = ca.MX.sym("p", p.size + q.size)
        expansion = term.node_expansion_expr(*planner._nodes(W), T)
        values = []
        for given in (expansion, None):
            offset, lam_sym = planner._gap_offset(W, P, T, theta.size, given)
            fn = ca.Function("gap", [W, P, T, lam_sym], [offset])
            values.append(np.asarray(fn(ws, np.concatenate([p, q.ravel()]), theta, lam)))
        assert np.max(np.abs(values[1])) > 0
        np.testing.assert_allclose(values[0], values[1], rtol=1e-10, atol=1e-12)


def test_a_qp_plugin_that_raises_is_a_rejected_step_not_a_crash():
    env = gym.make(CART, scenario="gp")
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, scheme="rti")
    obs, *_ = env.step(agent.act(obs))
    planner = agent.planner

    def raising(*args):
        raise RuntimeError("Problem in osqp_update_P_A")

    planner._step = raising
    action = agent.act(obs)
    assert planner.counts.rti_rejected == planner.counts.rti_steps == 1
    assert np.all(np.isfinite(action))
    assert agent.diagnostics_arrays()["status"][-1] == StepStatus.RTI_REJECTED


def test_warm_started_multipliers_cut_ipopt_iterations_at_the_same_closed_loop():
    """``warm_start_duals=True``: the converged solves start from the previous multipliers
    with IPOPT's warm-start options (the RTI's fallback does so by default)."""
    env = gym.make(CART, scenario="gp")
    cold = PseudospectralMPC.from_env(env)
    warm = PseudospectralMPC.from_env(env, scheme=Converged(warm_start_duals=True))
    episodes = [rollout(env, agent, 0, max_steps=40) for agent in (cold, warm)]
    assert not cold.planner.warm_start_duals and warm.planner.warm_start_duals
    assert PseudospectralMPC.from_env(env, scheme="rti")._planner().warm_start_duals
    iterations = [np.median(a.diagnostics_arrays()["iterations"][1:]) for a in (cold, warm)]
    assert iterations[1] < iterations[0]
    assert episodes[1].cost == pytest.approx(episodes[0].cost, rel=0.05)
    assert warm.counts.failures == cold.counts.failures == 0


# ------------------------------------------------------------------------ copies
@pytest.mark.parametrize("scheme", ["converged", "rti"])
def test_a_pickled_agent_acts_identically_after_loading(scheme):
    """Learner state, plan and env travel with the agent; the NLP is rebuilt on the next act."""
    import pickle

    env = gym.make(CART, scenario="online")
    agent = PseudospectralMPC.from_env(env, online_ssgp(20), scheme=scheme,
                                       term="linearized")
    agent.pretrain(collect_initial_data(env, 100, seed=0))
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        action = agent.act(obs)
        nxt, *_ = env.step(action)
        agent.observe(obs, action, nxt)
        obs = nxt
    clone = pickle.loads(pickle.dumps(agent))
    assert clone.planner is None and clone.learner.n_samples_seen_ == agent.learner.n_samples_seen_
    runs = []
    for a in (agent, clone):
        e = a._model_source.env  # the clone follows its own copy of the env
        o, actions = obs, []
        for _ in range(8):
            u = a.act(o)
            nxt, *_ = e.step(u)
            a.observe(o, u, nxt)
            o = nxt
            actions.append(u)
        runs.append(np.array(actions))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert clone.counts.builds == agent.counts.builds + 1
    if scheme == "rti":  # the clone's plan warm-starts its rebuilt NLP's real-time iteration
        assert all(r.status.startswith("RTI") for r in clone.diagnostics[-8:])


def test_sensitivity_inputs_explain_a_parameter_error():
    """With ``sensitivities=True`` the learner's extra inputs are ``d f_p[I] / d p`` at the
    nominal values: a least-squares fit of the true residual of other parameter values on them
    leaves a small fraction of it (first-order Taylor), checked against the physics directly."""
    env = gym.make(CART, scenario="online")
    env.reset(seed=0)
    nominal = env.unwrapped.nominal_model
    truth = gp_envs.oracle_model(env)
    res = ResidualModel(nominal, sensitivities=True)
    base = ResidualModel(nominal)
    n_sens = res.n_inputs - base.n_inputs
    assert n_sens == len(res.input_names) - len(base.input_names) > 0
    assert res.sensitivity_columns == tuple(range(base.n_inputs, res.n_inputs))
    assert base.sensitivity_columns == ()
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-1, 1, 300), rng.uniform(0, 2 * np.pi, 300),
                         rng.uniform(-3, 3, 300), rng.uniform(-8, 8, 300)])
    U = rng.uniform(-20, 20, (300, 1))
    Z = res.inputs(X, U)
    np.testing.assert_array_equal(Z[:, :base.n_inputs], base.inputs(X, U))
    Y = (truth.f(X, U) - nominal.f(X, U))[:, list(res.uncertain_indices)]
    for j in range(Y.shape[1]):
        cols = [base.n_inputs + i for i, name in enumerate(res.input_names[base.n_inputs:])
                if name.startswith(f"d({nominal.state_names[res.uncertain_indices[j]]})")]
        w, *_ = np.linalg.lstsq(Z[:, cols], Y[:, j], rcond=None)
        assert np.sqrt(np.mean((Y[:, j] - Z[:, cols] @ w) ** 2)) < 0.1 * np.sqrt(
            np.mean(Y[:, j] ** 2))


# ------------------------------------------------------------------------ RTI recovery
def _violation(planner, w, P) -> float:
    """The NLP's constraint violation at ``w`` (infinity norm), from the OCP's own constraint
    expression (not the RTI's compiled functions)."""
    nlp = planner.ocp.nlp
    g = np.asarray(ca.Function("g", [nlp["x"], nlp["p"]], [nlp["g"]])(w, P)).ravel()
    lbg, ubg = (np.asarray(b, float) for b in planner.ocp.bounds()[2:])
    return float(max(np.max(lbg - g, initial=0.0), np.max(g - ubg, initial=0.0)))


def test_the_recovery_projection_reaches_a_feasible_point_and_leaves_a_kkt_point_alone():
    """The recovery's feasibility projection (minimum-norm Newton steps on the linearized
    constraints): from a converged plan it does not move; from that plan perturbed far off
    feasibility it contracts the violation (measured by the OCP's own constraint expression)
    quadratically to within 1e-8 in a few projections and stays near the perturbed point."""
    env = gym.make(CART, scenario="gp")
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, scheme="rti")
    agent.act(obs)
    sol, planner = agent.plan.solution, agent.planner
    P = planner.planning.param_values()
    w, *_ = planner._project_outputs(obs, sol.nlp_x)
    np.testing.assert_allclose(np.asarray(w).ravel(), sol.nlp_x, atol=1e-5)
    rng = np.random.default_rng(0)
    ix = planner.ocp.node_indices()[0][1:].ravel()  # node states after X(t0)
    w0 = sol.nlp_x.copy()
    w0[ix] += 0.2 * rng.standard_normal(ix.size)
    history = [_violation(planner, w0, P)]
    w = w0
    for _ in range(4):
        w = np.asarray(planner._project_outputs(obs, w)[0]).ravel()
        history.append(_violation(planner, w, P))
    assert history[0] > 0.1 and history[-1] < 1e-8, history
    assert history[2] < history[1] ** 1.5 or history[2] < 1e-10, history  # superlinear
    assert np.max(np.abs(w - w0)) < 2.0


def _perturbed_rti_step(budget: int, scale: float = 0.05, patch=None):
    """The RTI step of a cart pole ``gp`` closed loop 40 periods in (the pole up, the plan
    settled), from that plan perturbed at its node states by ``scale`` x a fixed normal draw
    (a plan the model no longer fits) at the plan's own X(t0); ``patch(planner)`` may wrap
    its functions first. Returns the plan, the record, the planner and the counters'
    increments over this one step."""
    env = gym.make(CART, scenario="gp")
    obs, _ = env.reset(seed=0)
    agent = PseudospectralMPC.from_env(env, scheme=mpc_module.RTI(recovery_iterations=budget))
    for _ in range(40):
        obs, *_ = env.step(agent.act(obs))
    agent.act(obs)
    planner, previous = agent.planner, agent.plan
    w_prev = previous.solution.nlp_x.copy()
    ix = planner.ocp.node_indices()[0][1:].ravel()
    w_prev[ix] += scale * np.random.default_rng(1).standard_normal(ix.size)
    previous = dataclasses.replace(previous, solution=dataclasses.replace(
        previous.solution, nlp_x=w_prev))
    x1 = w_prev[:obs.size].copy()
    if patch is not None:
        patch(planner)
    c = planner.counts
    before = (c.rti_recovered, c.rti_rejected, c.recovery_iterations)
    plan, record = planner.plan(x1, previous, previous.step + planner.mesh.held_periods)
    after = (c.rti_recovered, c.rti_rejected, c.recovery_iterations)
    counts = dict(zip(("recovered", "rejected", "iterations"),
                      (b - a for a, b in zip(before, after, strict=True)), strict=True))
    return plan, record, planner, counts, x1


def test_a_rejected_step_is_recovered_within_the_budget_and_counted():
    """A step whose violation is too large: with ``recovery_iterations`` its plan is the
    recovered point (within tolerance by the OCP's own constraints), counted as recovered
    and not rejected; without a budget the same step is rejected (a converged solve)."""
    _, rec0, _, counts0, _ = _perturbed_rti_step(0)
    assert rec0["status"].startswith("RTI rejected") and counts0["rejected"] == 1
    plan3, rec3, planner, counts3, x1 = _perturbed_rti_step(3)
    assert rec3["status"].startswith("RTI recovered"), rec3["status"]
    assert counts3["recovered"] == 1 and counts3["rejected"] == 0
    assert counts3["iterations"] == rec3["iterations"] - 1 >= 1
    P = planner.planning.param_values()
    assert _violation(planner, plan3.solution.nlp_x, P) <= planner.max_violation
    np.testing.assert_allclose(plan3.solution.nlp_x[:x1.size], x1)


def test_a_feasible_point_that_no_sqp_iteration_preceded_is_rejected_not_recovered():
    """The recovery's feasible point alone is never the plan: with a budget of one QP solve
    the projection reaches feasibility (by the OCP's own constraints) but no SQP iteration
    (the objective's share) follows, and the step is rejected (a converged solve); with two,
    the SQP iteration from that point recovers the same step."""
    projected: list[float] = []

    def patch(planner):
        real_project = planner._project_outputs

        def project(x, w):
            out = real_project(x, w)
            projected.append(_violation(planner, np.asarray(out[0]).ravel(),
                                        planner.planning.param_values()))
            return out

        planner._project_outputs = project

    _, record, planner, counts, _ = _perturbed_rti_step(1, patch=patch)
    assert len(projected) == 1 and projected[0] <= planner.max_violation
    assert record["status"] == StepStatus.RTI_REJECTED, record["status"]
    assert counts == {"recovered": 0, "rejected": 1, "iterations": 0}
    _, record, _, counts, _ = _perturbed_rti_step(2)
    assert record["status"] == StepStatus.RTI_RECOVERED and record["iterations"] == 3, record
    assert counts == {"recovered": 1, "rejected": 0, "iterations": 2}
