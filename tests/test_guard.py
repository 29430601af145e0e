"""The plan-level nominal fallback (``Converged(nominal_above=...)``,
:class:`gp_agents.mpc.guard.NominalGuardPlanner`): its two chains checked against the agents
they must reproduce, and every combination it does not apply to refused."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import gp_envs  # noqa: F401  (registers the envs)
from gp_agents import collect_initial_data, make_mpc, rollout
from gp_agents.mpc.guard import NominalGuardPlanner
from gp_agents.mpc.settings import RTI, SQP, Converged

STEPS = 12


@pytest.fixture(scope="module")
def setup():
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    data = collect_initial_data(env, 60, seed=3)
    return env, data


def _run(env, agent):
    episode = rollout(env, agent, seed=3, max_steps=STEPS)
    return episode.actions, agent.diagnostics_arrays()


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), True, "1"])
def test_bad_threshold_raises(bad):
    with pytest.raises(ValueError, match="nominal_above"):
        Converged(nominal_above=bad)


def test_does_not_apply_raises(setup):
    env, _ = setup
    with pytest.raises(ValueError, match="nominal_above does not apply"):
        RTI(fallback=Converged(nominal_above=1.0))
    with pytest.raises(ValueError, match="nominal_above does not apply"):
        SQP(fallback=Converged(nominal_above=1.0))
    with pytest.raises(ValueError, match="needs a learner and term='linearized'"):
        make_mpc(env, "nominal", scheme=Converged(nominal_above=1.0))
    with pytest.raises(ValueError, match="needs a learner and term='linearized'"):
        make_mpc(env, "robust", scheme=Converged(nominal_above=1.0), term="exact")


def test_never_above_is_the_learned_agent(setup):
    """A threshold no plan reaches: the learned chain alone acts, exactly as without the
    guard (the nominal solves beside it change nothing)."""
    env, data = setup
    plain = make_mpc(env).pretrain(data)
    guarded = make_mpc(env, scheme=Converged(nominal_above=1e12)).pretrain(data)
    a, _ = _run(env, plain)
    b, diag = _run(env, guarded)
    assert isinstance(guarded.planner, NominalGuardPlanner)
    np.testing.assert_array_equal(a, b)
    assert not diag["nominal_plan"].any() and guarded.counts.nominal_plans == 0


def test_always_above_is_the_nominal_agent(setup):
    """A threshold every learned plan exceeds: the actions are the nominal MPC's, whose chain
    of warm starts the guard's nominal chain reproduces; the steps say so and the residual is
    reported off."""
    env, data = setup
    nominal = make_mpc(env, "nominal")
    guarded = make_mpc(env, scheme=Converged(nominal_above=1e-12)).pretrain(data)
    a, nominal_diag = _run(env, nominal)
    b, diag = _run(env, guarded)
    errors = diag["linearization_error"]
    assert np.all(errors > 1e-12)  # the premise: every learned plan is "too far"
    # the nominal plan is taken while its solve succeeds; where it fails the learned plan
    # stays (the nominal agent keeps an older plan there), so the two agents part there
    used = diag["nominal_plan"]
    first = int(np.argmin(used)) if not used.all() else STEPS
    assert first >= 5
    np.testing.assert_allclose(a[:first], b[:first], rtol=0, atol=1e-9)
    if first < STEPS:
        assert not nominal_diag["success"][first] or nominal_diag["fallback"][first]
    assert not diag["residual_on"][used].any() and diag["residual_on"][~used].all()
    assert guarded.counts.nominal_plans == int(used.sum())
    assert np.all(diag["solves"] >= 2)  # both chains solved at every replan
