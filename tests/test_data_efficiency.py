"""Issue 44: the black-box recipe's model, learning from no initial data, refits on the first
samples, the interaction-time metric, the multi-trial protocol and the data-efficiency preset."""

from __future__ import annotations

import math

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest
from agent_parts import residual_of

import gp_envs
from gp_agents import (
    RECIPES,
    Residual,
    collect_initial_data,
    make_mpc,
    online_ssgp,
    rollout,
)
from gp_agents.mpc.blackbox import KinematicOde, blackbox_model

PILCO = "gp_envs/PilcoCartPole-v0"


def _env(name: str, **kwargs) -> gym.Env:
    return gym.make(gp_envs.SYSTEMS[name].env_id, **kwargs)


# ----------------------------------------------------------------------------- the model
@pytest.mark.parametrize("system", sorted(gp_envs.SYSTEMS))
def test_blackbox_model_keeps_the_kinematics_and_zeroes_every_acceleration(system):
    nominal = _env(system).unwrapped.nominal_model
    box = blackbox_model(nominal)
    rng = np.random.default_rng(0)
    X = rng.normal(size=(20, nominal.n_states))
    U = rng.uniform(nominal.u_lb, nominal.u_ub, size=(20, nominal.n_controls))
    f_nom, f_box = nominal.f(X, U), box.f(X, U)
    kinematic = [i for i in range(nominal.n_states) if i not in nominal.dynamic_indices]
    np.testing.assert_array_equal(f_box[:, kinematic], f_nom[:, kinematic])
    np.testing.assert_array_equal(f_box[:, list(nominal.dynamic_indices)], 0.0)
    # the cart poles' kinematic rows are the velocities themselves
    if system in ("cartpole", "pilco_cartpole"):
        np.testing.assert_array_equal(f_box[:, :2], X[:, 2:])
    # everything but the physics is the nominal model's
    for name in ("dt", "param_names", "state_names", "dynamic_indices", "angle_indices"):
        assert getattr(box, name) == getattr(nominal, name)
    assert box.task is nominal.task


def test_blackbox_model_refuses_a_kinematic_row_with_parameters():
    nominal = _env("pendulum").unwrapped.nominal_model

    def ode(x, u, p):  # a "kinematic" row that depends on a parameter is not an identity
        return ca.vertcat(p[0] * x[1], -x[0] + u[0])

    import dataclasses

    bad = dataclasses.replace(nominal, ode=ode, param_ranges=nominal.param_ranges)
    with pytest.raises(ValueError, match="depends on the model's parameters"):
        blackbox_model(bad)
    assert KinematicOde(nominal.ode, (0,)) == KinematicOde(nominal.ode, (0,))  # shared caches


def test_blackbox_recipe_learns_the_whole_acceleration():
    env = gym.make(PILCO)
    assert "blackbox" in RECIPES
    data = collect_initial_data(env, 30, seed=0)
    agent = make_mpc(env, "blackbox").pretrain(data)
    truth = gp_envs.oracle_model(env)
    assert agent.model.f(np.ones(4), np.ones(1))[2:].tolist() == [0.0, 0.0]
    # the learner's targets are the true accelerations (at the period's midpoint), not a
    # correction of the nominal ones
    _, Y = residual_of(agent).targets(data.X, data.U, data.X_next)
    mid = 0.5 * (data.X + residual_of(agent).unwrap_like(data.X_next, data.X))
    true_acc = truth.f(mid, data.U)[:, 2:]
    err = np.abs(Y - true_acc).max(axis=0) / np.abs(true_acc).max(axis=0)
    assert np.all(err < 0.1), err
    env.reset(seed=0)
    obs, _ = env.reset(seed=0)
    assert agent.act(obs).shape == (1,)


# ----------------------------------------------------------------------------- no data
def test_pretrain_none_plans_with_the_model_alone_then_fits_on_the_first_transition():
    env = gym.make(PILCO)
    obs, _ = env.reset(seed=0)
    nominal = make_mpc(env, "nominal")
    learner = make_mpc(env, "robust").pretrain(None)
    np.testing.assert_array_equal(learner.act(obs), nominal.act(obs))  # step 0: nominal plan
    assert getattr(learner.learner, "n_samples_seen_", 0) == 0
    with pytest.raises(RuntimeError, match="pretrain"):  # forgetting pretrain still raises
        make_mpc(env, "robust").act(obs)
    action = learner.act(obs)
    next_obs, *_ = env.step(action)
    learner.observe(obs, action, next_obs)
    learner.act(next_obs)  # learns the transition first: fitted on it
    assert learner.learner.n_samples_seen_ == 1
    # the learned term is in the plan now
    assert type(learner.planner.planning.term) is type(learner.config.term)
    assert learner.counts.solves == 3  # the first planner's solves are counted too


def test_refit_until_refits_on_every_transition_as_their_number_doubles():
    env = gym.make(PILCO)
    data = collect_initial_data(env, 3, seed=0)
    agent = make_mpc(env, "paper", residual=Residual(refit_until=10)).pretrain(data)
    episode = rollout(env, agent, 0, max_steps=5)
    # at the 4th act the learner has 3 + 3 transitions: refitted on all six, so its input
    # standardization is theirs (an update keeps the first fit's)
    X = np.concatenate([data.X, episode.observations[:3]])
    Xn = np.concatenate([data.X_next, episode.observations[1:4]])
    U = np.concatenate([data.U, episode.actions[:3]])
    Z, _ = residual_of(agent).targets(X, U, Xn)
    np.testing.assert_allclose(agent.learner.standardizer_.z_mean, Z.mean(axis=0))
    frozen = make_mpc(env, "paper").pretrain(data)
    rollout(env, frozen, 0, max_steps=5)
    Z0, _ = residual_of(frozen).targets(data.X, data.U, data.X_next)
    np.testing.assert_allclose(frozen.learner.standardizer_.z_mean, Z0.mean(axis=0))


# ----------------------------------------------------------------------------- metrics
def test_interaction_time_of_a_constructed_episode():
    from benchmarks.trial import interaction_time

    info = {"success": True, "at_goal_since": 1.3}
    assert interaction_time(10, 0.1, info) == pytest.approx(2.3)
    assert interaction_time(10, 0.1, info, earlier_steps=40) == pytest.approx(6.3)
    assert math.isnan(interaction_time(10, 0.1, {"success": False, "at_goal_since": 1.3}))
    assert math.isnan(interaction_time(10, 0.1, {"success": True, "at_goal_since": None}))


def test_episode_metric_is_the_start_of_the_final_stretch_at_the_goal():
    from benchmarks.trial import TrialSpec, execute

    rec = execute(TrialSpec("episode", "pilco_cartpole", "pilco", "robust-mpc", 0, n_init=10))
    assert rec["status"] == "ok", rec["message"]
    m, a = rec["metrics"], rec["arrays"]
    assert m["success"]
    # independently: the first step of the last unbroken run of steps at the goal (the tip
    # within 8 cm, judged from the observations)
    task = gym.make(PILCO).unwrapped.nominal_model.task
    at = np.array([task.at_goal(x) for x in a["obs"][1:]])
    last_out = np.flatnonzero(~at)
    first_in = (last_out[-1] + 1) if last_out.size else 0
    assert m["at_goal_since_s"] == pytest.approx(a["time"][first_in])
    assert m["interaction_s"] == pytest.approx(10 * 0.1 + a["time"][first_in])


def test_trials_run_until_success_on_every_earlier_transition():
    from benchmarks.trial import MAX_TRIALS, TrialSpec, execute

    # five steps never succeed: every trial runs, each learning from all before it
    rec = execute(TrialSpec("trials", "pilco_cartpole", "pilco", "blackbox-mpc", 0, n_init=7,
                            max_steps=5))
    assert rec["status"] == "ok", rec["message"]
    m = rec["metrics"]
    assert m["trials"] == MAX_TRIALS and math.isnan(m["trials_to_success"])
    assert m["trial_successes"] == "0" * MAX_TRIALS
    assert m["data_steps_trials"] == 7 + 5 * MAX_TRIALS
    assert math.isnan(m["interaction_trials_s"])
    # later trials start elsewhere on the same system
    assert not np.array_equal(rec["arrays"]["trial2_obs"][0], rec["arrays"]["obs"][0])
    nominal = execute(TrialSpec("trials", "pilco_cartpole", "pilco", "nominal-mpc", 0,
                                n_init=0, max_steps=5))
    assert nominal["metrics"]["trials"] == 1  # learns nothing: one trial


def test_data_efficiency_preset_covers_the_grid_on_evaluation_seeds():
    from benchmarks.presets import DATA_EFFICIENCY_N_INIT, get_preset
    from benchmarks.studies.data_efficiency import TUNING_SEEDS

    specs = get_preset("data-efficiency").specs
    # every system of the package's own ODEs (the MuJoCo cart pole is the own-env preset's)
    assert {s.env for s in specs} == set(gp_envs.SYSTEMS) - {"mujoco_cartpole"}
    for env in {s.env for s in specs}:
        for c in ("robust-mpc", "paper-mpc", "blackbox-mpc"):
            for n in DATA_EFFICIENCY_N_INIT:
                seeds = {s.seed for s in specs if (s.env, s.controller, s.n_init) == (env, c, n)}
                assert len(seeds) >= 10 and not seeds & set(TUNING_SEEDS)
        for c in ("nominal-mpc", "oracle-mpc"):
            assert len({s.seed for s in specs if (s.env, s.controller) == (env, c)}) >= 10
    assert 0 in DATA_EFFICIENCY_N_INIT and all(s.kind == "trials" for s in specs)


def test_blackbox_controller_has_a_style_and_a_label():
    from benchmarks.controllers import CONTROLLERS
    from benchmarks.styles import style

    assert CONTROLLERS["blackbox-mpc"].label == "black-box MPC"
    assert style("blackbox-mpc") != style("robust-mpc")
    assert online_ssgp(linear_features=True).linear_features is True


@pytest.mark.parametrize(("rate", "says"), [(1.0, "the prior."), (0.9, "the prior."),
                                            (0.5, "the prior and learning together."),
                                            (0.1, "learning."), (0.0, "learning.")])
def test_the_report_says_what_a_table_measures_from_its_nominal_row(rate, says):
    from benchmarks.report.sections_data import what_it_measures

    rows = [{"controller": "robust-mpc", "episodes": 10, "success_rate": 1.0},
            {"controller": "nominal-mpc", "episodes": 10, "success_rate": rate}]
    text = what_it_measures(rows)
    assert text.startswith(f"**What this table measures: {says}**")
    assert f"succeeds on {round(10 * rate)} of 10 seeds" in text
    assert what_it_measures(rows[:1]) == ""  # no nominal row: nothing said
