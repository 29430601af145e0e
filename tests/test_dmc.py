"""The DeepMind Control Suite adapter (:mod:`gp_envs.dmc`) and DMC cart-pole's nominal model."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dm_control")

from dm_control import suite
from gymnasium.utils.env_checker import check_env

from gp_envs.dmc import (
    CARTPOLE_CONTROL_TIMESTEP,
    CARTPOLE_FRICTION,
    CARTPOLE_TIME_LIMIT,
    CARTPOLE_XML_PARAMS,
    DMCEnv,
    cartpole_action,
    cartpole_nominal_model,
    cartpole_state,
)

pytestmark = pytest.mark.filterwarnings("ignore:.*infinity.*:UserWarning")


def _cartpole(action_repeat: int = 5, **kwargs: object) -> DMCEnv:
    return DMCEnv("cartpole", "swingup", action_repeat=action_repeat, **kwargs)


def _state_from_physics(env: DMCEnv) -> np.ndarray:
    """The package's cart-pole state from the true qpos/qvel: theta = pi - hinge angle."""
    x, a, xd, ad = env.physics_state()
    return np.array([x, np.mod(np.pi - a, 2 * np.pi), xd, -ad])


def _rollout(env: DMCEnv, seed: int, actions: np.ndarray) -> tuple[np.ndarray, list[float]]:
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    for a in actions:
        obs, r, *_ = env.step(a)
        observations.append(obs)
        rewards.append(r)
    return np.array(observations), rewards


# --------------------------------------------------------------------- the gym API
@pytest.mark.parametrize(("domain", "task", "repeat"),
                         [("cartpole", "swingup", 5), ("pendulum", "swingup", 2)])
def test_env_checker_passes(domain: str, task: str, repeat: int) -> None:
    check_env(DMCEnv(domain, task, action_repeat=repeat), skip_render_check=True)


def test_spaces_and_observation_layout_follow_dmc() -> None:
    env = _cartpole()
    assert env.observation_space.shape == (5,) and env.observation_space.dtype == np.float32
    assert env.action_space.shape == (1,) and env.action_space.dtype == np.float32
    np.testing.assert_array_equal(env.action_space.low, [-1.0])
    np.testing.assert_array_equal(env.action_space.high, [1.0])
    assert dict(env.observation_layout) == {"position": slice(0, 3), "velocity": slice(3, 5)}
    assert env.dt == pytest.approx(0.05)
    obs, _ = env.reset(seed=4)
    x, a, xd, ad = env.physics_state()
    np.testing.assert_allclose(obs, [x, np.cos(a), np.sin(a), xd, ad], rtol=1e-6, atol=1e-7)


def test_same_seed_same_start_and_trajectory_other_seed_differs() -> None:
    actions = np.random.default_rng(0).uniform(-1, 1, (8, 1)).astype(np.float32)
    obs_a, rew_a = _rollout(_cartpole(), 7, actions)
    obs_b, rew_b = _rollout(_cartpole(), 7, actions)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert rew_a == rew_b
    obs_c, _ = _rollout(_cartpole(), 8, actions)
    assert not np.array_equal(obs_a[0], obs_c[0])
    # a seeded reset reproduces dm_control's own suite.load(random=seed), an independent source
    ts = suite.load("cartpole", "swingup", task_kwargs={"random": 7}).reset()
    expected = np.concatenate([ts.observation["position"], ts.observation["velocity"]])
    np.testing.assert_array_equal(obs_a[0], expected.astype(np.float32))


def test_unseeded_resets_continue_the_seeded_stream() -> None:
    env_a, env_b = _cartpole(), _cartpole()
    env_a.reset(seed=3)
    env_b.reset(seed=3)
    first_a, first_b = env_a.reset()[0], env_b.reset()[0]
    np.testing.assert_array_equal(first_a, first_b)
    assert not np.array_equal(first_a, env_a.reset(seed=3)[0])


def test_reward_is_the_sum_of_the_repeated_dmc_steps() -> None:
    actions = np.random.default_rng(1).uniform(-1, 1, (6, 1)).astype(np.float32)
    coarse = _cartpole(5)
    coarse.reset(seed=11)
    fine = _cartpole(1)
    fine.reset(seed=11)
    raw = suite.load("cartpole", "swingup", task_kwargs={"random": 11})
    raw.reset()
    for a in actions:
        _, reward, terminated, truncated, info = coarse.step(a)
        fine_rewards = [fine.step(a)[1] for _ in range(5)]
        raw_rewards = [raw.step(a.astype(np.float64)).reward for _ in range(5)]
        assert reward == pytest.approx(sum(fine_rewards), rel=1e-12, abs=1e-15)
        assert reward == pytest.approx(sum(raw_rewards), rel=1e-12, abs=1e-15)
        assert info["dmc_reward"] == reward
        assert 0.0 <= reward <= 5.0
        assert not terminated and not truncated
    np.testing.assert_array_equal(coarse.physics_state(), fine.physics_state())
    assert info["time"] == pytest.approx(6 * 5 * CARTPOLE_CONTROL_TIMESTEP)


@pytest.mark.parametrize(("repeat", "n_steps"), [(5, 200), (3, 334)])
def test_episode_is_truncated_at_dmc_time_limit(repeat: int, n_steps: int) -> None:
    env = _cartpole(repeat)
    env.reset(seed=0)
    env.action_space.seed(0)
    flags = [env.step(env.action_space.sample())[2:4] for _ in range(n_steps)]
    assert all(not term for term, _ in flags)
    assert [trunc for _, trunc in flags] == [False] * (n_steps - 1) + [True]
    # 1000 DMC steps; with repeat 3 the last gym step stops after one of its three
    assert env.physics.data.time == pytest.approx(CARTPOLE_TIME_LIMIT)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())


def test_out_of_bounds_actions_are_clipped() -> None:
    a, b = _cartpole(), _cartpole()
    a.reset(seed=2)
    b.reset(seed=2)
    obs_a = a.step(np.array([7.0], np.float32))[0]
    obs_b = b.step(np.array([1.0], np.float32))[0]
    np.testing.assert_array_equal(obs_a, obs_b)


@pytest.mark.parametrize("repeat", [0, -1, True, 1.5, "5"])
def test_bad_action_repeat_raises(repeat: object) -> None:
    with pytest.raises(ValueError, match="action_repeat"):
        DMCEnv("cartpole", "swingup", action_repeat=repeat)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="action_repeat"):
        cartpole_nominal_model(repeat)  # type: ignore[arg-type]


def test_unknown_domain_or_task_raises_listing_the_names() -> None:
    with pytest.raises(ValueError, match=r"unknown DMC domain 'cartpol'.*cartpole"):
        DMCEnv("cartpol", "swingup")
    with pytest.raises(ValueError, match=r"unknown task 'swing'.*swingup_sparse"):
        DMCEnv("cartpole", "swing")
    with pytest.raises(ValueError, match="render_mode"):
        DMCEnv("cartpole", "swingup", render_mode="human")


def test_bad_actions_and_options_raise() -> None:
    env = _cartpole()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(1, np.float32))
    env.reset(seed=0)
    for bad in (np.zeros(2), np.zeros((1, 1)), np.float32(0.0)):
        with pytest.raises(ValueError, match="shape"):
            env.step(bad)
    for bad in (np.array([np.nan]), np.array([np.inf])):
        with pytest.raises(ValueError, match="finite"):
            env.step(bad)
    with pytest.raises(ValueError, match="options"):
        env.reset(options={"init_state": 0})
    env.reset(options={})


@pytest.mark.parametrize(("friction", "match"), [
    ({"rail": 1.0}, r"unknown joint 'rail'.*slider.*hinge_1"),
    ({"slider": -0.1}, ">= 0"),
    ({"hinge_1": float("nan")}, ">= 0"),
    ({"slider": True}, "real number"),
])
def test_bad_frictionloss_raises(friction: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _cartpole(dof_frictionloss=friction)


def test_frictionloss_holds_after_every_reset() -> None:
    env = _cartpole(dof_frictionloss=CARTPOLE_FRICTION)
    names = [env.physics.model.id2name(j, "joint") for j in range(env.physics.model.njnt)]
    expected = [CARTPOLE_FRICTION[n] for n in names]
    assert expected == [1.0, 0.05]
    np.testing.assert_array_equal(env.physics.model.dof_frictionloss, expected)
    for seed in (None, 5, None, None, 6, 5):
        env.reset(seed=seed)
        np.testing.assert_array_equal(env.physics.model.dof_frictionloss, expected)
        env.step(np.zeros(1, np.float32))
    only_slider = _cartpole(dof_frictionloss={"slider": 0.5})
    only_slider.reset()
    np.testing.assert_array_equal(only_slider.physics.model.dof_frictionloss, [0.5, 0.0])
    # the friction acts: a half push (5 N) barely beats 1 N of Coulomb friction on the slider
    plain = _cartpole()
    plain.reset(seed=5)
    env.reset(seed=5)
    for _ in range(4):
        plain.step(np.array([0.5], np.float32))
        env.step(np.array([0.5], np.float32))
    assert env.physics_state()[2] < plain.physics_state()[2]


def test_render_none_and_headless_rgb_array() -> None:
    env = _cartpole()
    env.reset(seed=0)
    assert env.render() is None
    # in a fresh process (the GL backend is chosen when dm_control is imported): a frame with
    # EGL, or the adapter's RuntimeError where MuJoCo cannot render
    code = textwrap.dedent("""
        from gp_envs.dmc import DMCEnv
        env = DMCEnv("cartpole", "swingup", render_mode="rgb_array")
        env.reset(seed=0)
        try:
            frame = env.render()
        except RuntimeError as exc:
            print("RuntimeError", "MUJOCO_GL" in str(exc))
        else:
            print("frame", frame.shape, frame.dtype, int(frame.std() > 0))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "MUJOCO_GL": "egl"}, timeout=120, check=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert out.stdout.strip().splitlines()[-1] in ("frame (240, 320, 3) uint8 1",
                                                   "RuntimeError True")


def test_missing_dm_control_raises_import_error_with_the_extra(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "dm_control", None)
    with pytest.raises(ImportError, match=r'pip install "gp-pseudospectral-mpc\[mujoco\]"'):
        _cartpole()


# --------------------------------------------------------------------- DMC's cart-pole
def test_xml_params_match_the_compiled_model() -> None:
    env = _cartpole()
    m = env.physics.model
    p = CARTPOLE_XML_PARAMS
    np.testing.assert_allclose(m.body_mass[1:], [p["cart_mass"], p["pole_mass"]])
    np.testing.assert_allclose(m.dof_damping, [p["slider_damping"], p["hinge_damping"]])
    np.testing.assert_allclose(m.actuator_gear[0, 0], p["gear"])
    np.testing.assert_allclose(m.actuator_ctrlrange[0], [p["ctrl_min"], p["ctrl_max"]])
    np.testing.assert_allclose(m.jnt_range[0], [p["slider_min"], p["slider_max"]])
    assert list(m.jnt_limited) == [1, 0]  # slider limited, hinge free
    np.testing.assert_allclose(m.body_ipos[2], [0.0, 0.0, p["pole_com"]])
    np.testing.assert_allclose(m.geom_size[m.name2id("pole_1", "geom"), :2],
                               [p["pole_radius"], p["pole_length"] / 2])
    assert m.opt.timestep == p["timestep"]
    np.testing.assert_allclose(m.opt.gravity, [0.0, 0.0, -p["gravity"]])
    assert env.dt / env.action_repeat == CARTPOLE_CONTROL_TIMESTEP
    np.testing.assert_array_equal(m.dof_frictionloss, [0.0, 0.0])


def test_cartpole_state_matches_the_physics() -> None:
    env = _cartpole(1)
    obs, _ = env.reset(seed=1)
    angles = []
    for k in range(500):
        state = cartpole_state(obs)
        np.testing.assert_allclose(state, _state_from_physics(env), atol=2e-6, rtol=1e-6)
        # geometry, independent of the angle formula: the pole's centre of mass sits at
        # (x + l sin(theta), -l cos(theta)) from the hinge, 0 hanging down
        com = env.physics.named.data.xipos["pole_1"]
        hinge = env.physics.named.data.xpos["cart"]
        l_com = CARTPOLE_XML_PARAMS["pole_com"]
        np.testing.assert_allclose(com[[0, 2]] - hinge[[0, 2]],
                                   [l_com * np.sin(state[1]), -l_com * np.cos(state[1])],
                                   atol=1e-5)
        angles.append(state[1])
        obs, *_ = env.step(np.array([1.0 if (k // 80) % 2 else -1.0], np.float32))
    assert np.all((np.array(angles) >= 0) & (np.array(angles) < 2 * np.pi))
    assert np.ptp(np.cos(angles)) > 1.0  # the pole swung past horizontal: a range is covered
    batch = cartpole_state(np.stack([obs, obs]))
    assert batch.shape == (2, 4)
    with pytest.raises(ValueError, match="5"):
        cartpole_state(np.zeros(4))


def test_cartpole_action_inverts_the_gear() -> None:
    gear = float(_cartpole().physics.model.actuator_gear[0, 0])
    u = np.array([[-10.0], [2.5], [0.0], [10.0]])
    np.testing.assert_allclose(gear * cartpole_action(u), u)
    np.testing.assert_allclose(cartpole_action(np.array([5.0])), [0.5])
    model = cartpole_nominal_model()
    np.testing.assert_allclose(cartpole_action(model.u_ub), [1.0])
    np.testing.assert_allclose(cartpole_action(model.u_lb), [-1.0])


def test_nominal_model_fields() -> None:
    model = cartpole_nominal_model(4)
    assert model.name == "dmc_cartpole"
    assert model.dt == pytest.approx(0.04) and model.substeps == 20
    assert dict(model.params) == {"mc": 1.0, "mp": 0.1, "l": 0.5, "b1": 5e-4, "b2": 2e-6,
                                  "g": 9.81}
    assert cartpole_nominal_model(length="rod").params["l"] == pytest.approx(2 / 3)
    np.testing.assert_allclose(model.x_ub, [1.8, np.inf, 10.0, 25.0])
    assert model.task.duration == CARTPOLE_TIME_LIMIT
    assert model.task.at_goal(np.array([0.2, np.pi + 0.09, 3.0, 5.0]))
    assert not model.task.at_goal(np.array([0.3, np.pi, 0.0, 0.0]))
    with pytest.raises(ValueError, match="length"):
        cartpole_nominal_model(length="pendulum")


@pytest.mark.parametrize(("theta0", "force"), [
    (0.3, 0.0), (0.0, 10.0), (0.0, -10.0), (np.pi - 0.2, 0.0), (2.0, -10.0), (4.0, 6.0)])
def test_nominal_model_moves_like_dmc_from_a_set_state(theta0: float, force: float) -> None:
    """From rest at package angle ``theta0``, one 0.05 s step under ``force`` (N)."""
    env = _cartpole(5)
    env.reset(seed=0)
    with env.physics.reset_context():
        env.physics.named.data.qpos[:] = [0.1, np.pi - theta0]
        env.physics.named.data.qvel[:] = 0.0
    x0 = _state_from_physics(env)
    predicted = cartpole_nominal_model(5).step(x0, np.array([force]))
    env.step(cartpole_action(np.array([force])).astype(np.float32))
    actual = _state_from_physics(env)
    d_pred, d_true = predicted - x0, actual - x0
    d_pred[1], d_true[1] = (np.arctan2(np.sin(d[1]), np.cos(d[1])) for d in (d_pred, d_true))
    # the same direction of every rate, and the angle moves the same way
    np.testing.assert_array_equal(np.sign(d_pred[1:]), np.sign(d_true[1:]))
    # the point mass has 0.025 kg m^2 about the hinge where the capsule has 0.0344: angular
    # accelerations are up to ~40% too large
    np.testing.assert_allclose(d_pred[[1, 3]], d_true[[1, 3]], rtol=0.5)


def test_nominal_model_one_step_prediction_is_close() -> None:
    """One 0.05 s step (action_repeat 5) from the true state, away from the slider's limit.

    Measured over 600 random-force steps (|x| < 1.7 m): max errors 0.4 mm, 0.010 rad,
    0.017 m/s, 0.41 rad/s, from the point-mass pole (the capsule's hinge inertia is 38% larger,
    so angular accelerations of up to ~20 rad/s^2 are ~40% off over 0.05 s). The bounds below
    leave ~2x margin; a mirrored angle convention (theta = a + pi) errs by ~0.04 rad and
    ~1.7 rad/s under a 10 N push, and fails them.
    """
    model = cartpole_nominal_model(5)
    env = _cartpole(5)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(40):
        force = rng.choice([-10.0, -5.0, 0.0, 5.0, 10.0], size=1)
        x = _state_from_physics(env)
        predicted = model.step(x, force)
        env.step(cartpole_action(force).astype(np.float32))
        e = predicted - _state_from_physics(env)
        e[1] = np.arctan2(np.sin(e[1]), np.cos(e[1]))
        errors.append(np.abs(e))
    worst = np.max(errors, axis=0)
    assert np.all(worst < [1e-3, 0.02, 0.04, 0.8]), worst
    assert worst[3] > 1e-3  # the model is not the truth (a rod is not a point mass)


# ------------------------------------------------------------------ a gp_envs env in MuJoCo
def test_the_mujoco_cartpole_is_a_gp_envs_env_with_an_outside_plant() -> None:
    import gymnasium as gym

    import gp_envs
    from gp_envs.dmc import CARTPOLE_FRICTION, MuJoCoCartPoleEnv

    env = gym.make("gp_envs/MuJoCoCartPole-v0")
    check_env(env.unwrapped, skip_render_check=True)
    assert gp_envs.nominal_model(env).name == "mujoco_cartpole"
    with pytest.raises(ValueError, match="randomize cannot apply"):
        MuJoCoCartPoleEnv(randomize=0.1)
    with pytest.raises(ValueError, match="true_params cannot apply"):
        MuJoCoCartPoleEnv(true_params={"mc": 2.0})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no true model"):
        gp_envs.oracle_model(env)
    plant = MuJoCoCartPoleEnv(scenario="friction")._plant
    friction = plant._dmc.physics.model.dof_frictionloss
    np.testing.assert_allclose(friction, [CARTPOLE_FRICTION["slider"],
                                          CARTPOLE_FRICTION["hinge_1"]])


def test_the_mujoco_plant_steps_like_dmc_itself() -> None:
    """From DMC's own seeded start, the plant's step (state in the package's coordinates, a
    force in N) gives DMCEnv's next physics state (an independent path: DMC's own stepping)."""
    from gp_envs.dmc import MuJoCoCartPole

    dmc = DMCEnv("cartpole", "swingup", action_repeat=5)
    plant = MuJoCoCartPole(5)
    dmc.reset(seed=3)
    for action in (0.7, -1.0, 0.2):
        qpos, qvel = dmc.physics_state()[:2], dmc.physics_state()[2:]
        x = np.array([qpos[0], np.pi - qpos[1], qvel[0], -qvel[1]])
        dmc.step(np.array([action], np.float32))
        nxt = dmc.physics_state()
        expected = np.array([nxt[0], np.pi - nxt[1], nxt[2], -nxt[3]])
        # MuJoCo's warm start is the only difference (the plant clears it): round-off level
        np.testing.assert_allclose(plant.step(x, np.array([10.0 * np.float32(action)])),
                                   expected, atol=1e-8)
