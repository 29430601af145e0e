"""The SQP scheme: SQP iterations to convergence on the real-time iteration's QP machinery,
checked against IPOPT's converged solve of the same OCP (the same KKT point)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gp_envs
from gp_agents import SQP, Converged, PseudospectralMPC, make_mpc
from gp_agents.mpc import StepStatus

QUAD = "gp_envs/Quadrotor-v0"


def _oracle(env: gym.Env, scheme) -> PseudospectralMPC:
    return PseudospectralMPC.from_env(env, scheme=scheme,
                                      model_source=lambda: gp_envs.oracle_model(env))


def test_a_converged_sqp_plan_is_ipopts_kkt_point():
    """From the same shifted plan and state, the SQP's converged plan and IPOPT's converged
    plan of the same OCP agree (a KKT point is one, whichever the path to it); the step is
    counted as SQP iterations and not as a fallback."""
    env = gym.make(QUAD, scenario="online")
    obs, _ = env.reset(seed=0)
    sqp = _oracle(env, SQP(max_iterations=100))
    obs1, *_ = env.step(sqp.act(obs))  # the cold start: IPOPT
    planner, previous = sqp.planner, sqp.plan
    plan, record = planner.plan(obs1, previous, previous.step + planner.mesh.held_periods)
    assert record["status"] == StepStatus.SOLVED and record["solver_status"] == "SQP converged"
    assert sqp.counts.sqp_fallbacks == 0 and record["iterations"] == sqp.counts.sqp_iterations
    ipopt = planner.ocp.solve(p=planner.planning.param_values(), x0=obs1,
                              initial_guess=plan.solution)
    assert ipopt.success
    # the Gauss-Newton iteration converges linearly: within a few tolerances of the point
    scale = 10 * sqp.config.scheme.tolerance
    np.testing.assert_allclose(plan.solution.u, ipopt.u, atol=scale * np.max(np.abs(ipopt.u)))
    np.testing.assert_allclose(plan.solution.x, ipopt.x, atol=scale * np.max(np.abs(ipopt.x)))


def test_a_plan_that_does_not_converge_within_the_budget_is_ipopts():
    """A budget of one iteration does not converge from a shifted plan: the plan is IPOPT's
    converged solve, counted as an SQP fallback, never the unconverged iterate."""
    env = gym.make(QUAD, scenario="online")
    obs, _ = env.reset(seed=0)
    agent = _oracle(env, SQP(max_iterations=1, tolerance=1e-12))
    obs, *_ = env.step(agent.act(obs))
    agent.act(obs)
    record = agent.diagnostics[-1]
    assert agent.counts.sqp_fallbacks == 1 and agent.counts.sqp_iterations == 1
    assert record.status == StepStatus.SOLVED and record.solver_status != "SQP converged"


def test_the_sqp_scheme_resolves_the_systems_qp_and_checks_its_settings():
    env = gym.make(QUAD)
    agent = make_mpc(env, "nominal", scheme="sqp")
    assert agent.config.scheme.qp_solver is not None
    assert agent.config.scheme.levenberg_marquardt is not None
    assert isinstance(agent.config.scheme.fallback, Converged)
    for bad in ({"max_iterations": 0}, {"tolerance": 0.0}, {"levenberg_marquardt": -1.0}):
        with pytest.raises(ValueError):
            SQP(**bad)
    with pytest.raises(TypeError, match="fallback"):
        SQP(fallback="ipopt")
    from gp_agents import Episodic
    with pytest.raises(ValueError, match="episodic"):
        PseudospectralMPC.from_env(env, scheme="sqp", horizon=Episodic())
