"""Env robustness: copies and pickles of envs and models, and rejection of unphysical input."""

from __future__ import annotations

import copy
import os
import pickle
import re
import subprocess
import sys
from pathlib import Path

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest

import gp_envs

ENV_IDS = list(gp_envs.ENV_IDS)
REPO = Path(__file__).resolve().parents[1]


def make(env_id: str, **kwargs):
    return gym.make(env_id, disable_env_checker=True, **kwargs)


def _pickle_round_trip(obj):
    return pickle.loads(pickle.dumps(obj))


COPIERS = {"deepcopy": copy.deepcopy, "pickle": _pickle_round_trip}


# ------------------------------------------------------------------------ copies and pickles
def _random_actions(env, n: int, seed: int) -> np.ndarray:
    low, high = env.action_space.low, env.action_space.high
    return np.random.default_rng(seed).uniform(low, high, size=(n, low.size)).astype(np.float32)


def _episode_record(env) -> list:
    """What a run can observe of the episode's models: the truth and the nominal parameters."""
    return [dict(gp_envs.oracle_model(env).params), dict(env.unwrapped.nominal_model.params)]


def _trajectory(env, actions: np.ndarray) -> list:
    """Steps ``actions`` (resetting, unseeded, after an episode ends), then one more unseeded
    reset and the same actions again; everything observable, as exact values."""
    record = []
    for part in range(2):
        if part == 1:
            obs, info = env.reset()
            record += [obs.tobytes(), info, *_episode_record(env)]
        for a in actions:
            obs, reward, terminated, truncated, info = env.step(a)
            record.append((obs.tobytes(), reward, terminated, truncated, info))
            if terminated or truncated:
                obs, info = env.reset()
                record += [obs.tobytes(), info, *_episode_record(env)]
    return record


@pytest.mark.parametrize("copier", sorted(COPIERS))
@pytest.mark.parametrize("randomize", [0.0, 0.2])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_copied_env_steps_and_redraws_identically(env_id, randomize, copier):
    env = make(env_id, randomize=randomize)
    env.reset(seed=5)
    for a in _random_actions(env, 3, seed=1):
        env.step(a)
    before = _episode_record(env)
    env.action_space.seed(7)
    twin = COPIERS[copier](env)
    assert twin.unwrapped is not env.unwrapped
    np.testing.assert_array_equal(twin.action_space.sample(), env.action_space.sample())
    assert twin.unwrapped.nominal_model is not env.unwrapped.nominal_model
    actions = _random_actions(env, 20, seed=2)
    expected = _trajectory(env, actions)  # the original first: a shared RNG or state would
    got = _trajectory(twin, actions)      # make the twin's run differ
    assert got == expected
    success = [r[4]["success"] for r in expected if isinstance(r, tuple)]
    assert success == [r[4]["success"] for r in got if isinstance(r, tuple)]
    # the unseeded reset really redrew what is random per episode (so the RNG state mattered)
    after = _episode_record(env)
    if randomize > 0:
        assert after[0] != before[0]
    if env.unwrapped.SCENARIOS[env.unwrapped.scenario].nominal_spread:
        assert after[1] != before[1]


@pytest.mark.parametrize("copier", sorted(COPIERS))
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_copied_env_renders_the_same_frame(env_id, copier):
    env = make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    for a in _random_actions(env, 5, seed=0):
        env.step(a)
    frame = env.render()  # the original now holds a figure; the copy must build its own
    twin = COPIERS[copier](env)
    np.testing.assert_array_equal(twin.render(), frame)
    env.close()
    twin.close()


def _model_inputs(model, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, (6, model.n_states))
    U = rng.uniform(model.u_lb, model.u_ub, (6, model.n_controls))
    return X, U


def _evaluations(model, X, U) -> list[np.ndarray]:
    xs, us = ca.SX.sym("x", model.n_states), ca.SX.sym("u", model.n_controls)
    symbolic = ca.Function("f", [xs, us], [model.f(xs, us)])
    return [model.f(X, U), model.step(X, U), model.f(X[0], U[0]), model.step(X[0], U[0]),
            np.asarray(model.casadi_function()(X[0], U[0])).ravel(),
            np.asarray(symbolic(X[1], U[1])).ravel()]


@pytest.mark.parametrize("copier", sorted(COPIERS))
@pytest.mark.parametrize("which", ["nominal", "oracle"])
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_copied_control_model_evaluates_identically(env_id, which, copier):
    env = make(env_id, randomize=0.1)
    env.reset(seed=3)
    model = env.unwrapped.nominal_model if which == "nominal" else gp_envs.oracle_model(env)
    X, U = _model_inputs(model)
    expected = _evaluations(model, X, U)  # also fills the model's cache of CasADi functions
    clone = COPIERS[copier](model)
    assert clone is not model
    assert dict(clone.params) == dict(model.params)
    assert clone.param_names == model.param_names and clone.dt == model.dt
    for got, want in zip(_evaluations(clone, X, U), expected, strict=True):
        np.testing.assert_array_equal(got, want)
    with pytest.raises(TypeError):
        clone.params[model.param_names[0]] = 1.0


def test_params_are_read_only_and_a_private_copy():
    model = make("gp_envs/CartPoleSwingUp-v0").unwrapped.nominal_model
    source = dict(model.params)
    other = model.with_params(mc=2.0)
    source["mc"] = 5.0  # the mapping a model was built from is not shared with it
    assert other.params["mc"] == 2.0 and model.params["mc"] == 0.9
    with pytest.raises(TypeError):
        model.params["mc"] = 2.0
    with pytest.raises(TypeError):
        del model.params["mc"]
    assert not hasattr(model.params, "update") and not hasattr(model.params, "pop")
    assert dict(model.params) == {"mc": 0.9, "mp": 0.45, "l": 0.45, "b1": 0.0, "b2": 0.0,
                                  "g": 9.81}


_FRESH_PROCESS = """
import pickle, sys
import numpy as np
import gp_envs
models, envs, X, U, actions = pickle.loads(sys.stdin.buffer.read())
out = []
for (nominal, truth), env, x, u, acts in zip(models, envs, X, U, actions):
    out.append([m.f(x, u) for m in (nominal, truth)] + [m.step(x, u) for m in (nominal, truth)])
    out.append([env.step(a)[:2] for a in acts])
sys.stdout.buffer.write(pickle.dumps(out))
"""


def test_pickles_evaluate_identically_in_a_fresh_process():
    """Unpickled where nothing is cached: the CasADi functions are rebuilt from the physics."""
    models, envs, X, U, actions, expected = [], [], [], [], [], []
    for env_id in ENV_IDS:
        env = make(env_id, randomize=0.1)
        env.reset(seed=11)
        nominal, truth = env.unwrapped.nominal_model, gp_envs.oracle_model(env)
        x, u = _model_inputs(nominal, seed=4)
        acts = _random_actions(env, 10, seed=4)
        models.append((nominal, truth))
        envs.append(env)
        X.append(x)
        U.append(u)
        actions.append(acts)
    payload = pickle.dumps((models, envs, X, U, actions))
    for (nominal, truth), env, x, u, acts in zip(models, envs, X, U, actions, strict=True):
        expected.append([m.f(x, u) for m in (nominal, truth)]
                        + [m.step(x, u) for m in (nominal, truth)])
        expected.append([env.step(a)[:2] for a in acts])
    environ = {**os.environ, "PYTHONPATH": str(REPO), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", _FRESH_PROCESS], input=payload,
                          capture_output=True, env=environ, cwd=REPO, timeout=120, check=False)
    assert done.returncode == 0, done.stderr.decode()
    got = pickle.loads(done.stdout)
    assert len(got) == len(expected) == 2 * len(ENV_IDS)
    for g, e in zip(got, expected, strict=True):
        for a, b in zip(g, e, strict=True):
            if isinstance(b, tuple):  # (obs, reward)
                np.testing.assert_array_equal(a[0], b[0])
                assert a[1] == b[1]
            else:
                np.testing.assert_array_equal(a, b)


# ------------------------------------------------------------------------ unphysical parameters
# Invalid values stated here, from the physics (not read from the PARAM_RANGES tables): masses,
# lengths, inertias and gravity > 0; damping >= 0; Dubins loss factors < 1 (1 - b > 0).
_POSITIVE, _NONNEGATIVE, _LOSS = "(0, inf)", "[0, inf)", "(-inf, 1)"
_RANGES = {
    "gp_envs/CartPoleSwingUp-v0": {"mc": _POSITIVE, "mp": _POSITIVE, "l": _POSITIVE,
                                   "b1": _NONNEGATIVE, "b2": _NONNEGATIVE, "g": _POSITIVE},
    "gp_envs/Quadrotor-v0": {"m": _POSITIVE, "Jx": _POSITIVE, "Jy": _POSITIVE, "Jz": _POSITIVE,
                             "L": _POSITIVE, "g": _POSITIVE},
    "gp_envs/DubinsObstacle-v0": {"b1": _LOSS, "b2": _LOSS},
    "gp_envs/PendulumSwingUp-v0": {"m": _POSITIVE, "l": _POSITIVE, "b": _NONNEGATIVE,
                                   "g": _POSITIVE},
}
_OUTSIDE = {_POSITIVE: [0.0, -1.0, -1e-9], _NONNEGATIVE: [-1e-9, -0.3], _LOSS: [1.0, 1.5]}
_INSIDE = {_POSITIVE: [1e-6, 3.0], _NONNEGATIVE: [0.0, 2.0], _LOSS: [-0.5, 0.0, 0.999]}
_NOT_REAL = ["1.0", True, None, [1.0], np.array([1.0]), 1 + 0j]
_NOT_FINITE = [np.nan, np.inf, -np.inf]

_BAD_PARAMS = [(env_id, name, v) for env_id, table in _RANGES.items()
               for name, rng in table.items() for v in _OUTSIDE[rng] + _NOT_FINITE]
_GOOD_PARAMS = [(env_id, name, v) for env_id, table in _RANGES.items()
                for name, rng in table.items() for v in _INSIDE[rng]]


def _message(env_id: str, name: str, value: float) -> str:
    """The message must name the parameter, its value and its valid range."""
    rng = re.escape(_RANGES[env_id][name])
    return rf"parameter {name} = {re.escape(repr(float(value)))} .*{rng}"


def test_the_invalid_value_tables_cover_every_parameter():
    from gp_envs.physics import cartpole, dubins, pendulum, quadrotor

    for env_id, module in zip(ENV_IDS, (cartpole, quadrotor, dubins, pendulum), strict=True):
        assert set(_RANGES[env_id]) == set(module.PARAM_NAMES) == set(module.PARAM_RANGES)
        assert {k: str(r) for k, r in module.PARAM_RANGES.items()} == _RANGES[env_id]


@pytest.mark.parametrize(("env_id", "name", "value"), _BAD_PARAMS)
def test_unphysical_parameter_rejected_on_every_path(env_id, name, value):
    nominal = make(env_id).unwrapped.nominal_model
    match = _message(env_id, name, value)
    with pytest.raises(ValueError, match=match if np.isfinite(value) else f"{name}.*finite"):
        make(env_id, true_params={name: value})
    with pytest.raises(ValueError, match=match if np.isfinite(value) else f"{name}.*finite"):
        nominal.with_params(**{name: value})
    fields = {k: getattr(nominal, k) for k in (
        "name", "ode", "param_names", "state_names", "control_names", "dt", "x_lb", "x_ub",
        "u_lb", "u_ub", "task", "substeps", "angle_indices", "dynamic_indices")}
    with pytest.raises(ValueError, match=name):
        gp_envs.ControlModel(**fields, params={**nominal.params, name: value})


@pytest.mark.parametrize("value", _NOT_REAL, ids=repr)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_non_numeric_parameter_rejected(env_id, value):
    name = next(iter(_RANGES[env_id]))
    with pytest.raises(ValueError, match=f"parameter {name} must be a real number"):
        make(env_id, true_params={name: value})
    with pytest.raises(ValueError, match=f"parameter {name} must be a real number"):
        make(env_id).unwrapped.nominal_model.with_params(**{name: value})


@pytest.mark.parametrize(("env_id", "name", "value"), _GOOD_PARAMS)
def test_physical_parameter_at_the_edge_of_its_range_accepted(env_id, name, value):
    env = make(env_id, true_params={name: value})
    env.reset(seed=0)
    assert gp_envs.oracle_model(env).params[name] == value
    model = env.unwrapped.nominal_model.with_params(**{name: np.float32(value)})
    assert model.params[name] == float(np.float32(value))
    assert type(model.params[name]) is float


def test_zero_length_or_mass_fails_at_make_not_at_the_first_step():
    """These used to build and then diverge (division by zero) on the first step."""
    with pytest.raises(ValueError, match=r"parameter l = 0\.0 .*\(0, inf\)"):
        make("gp_envs/CartPoleSwingUp-v0", true_params={"l": 0})
    with pytest.raises(ValueError, match=r"parameter m = 0\.0 .*\(0, inf\)"):
        make("gp_envs/Quadrotor-v0", true_params={"m": 0})


@pytest.mark.parametrize("value", ["0.1", True, False, None, -0.1, 1.0, 1.5, np.nan, np.inf,
                                   [0.1], np.array([0.1]), 0.1j], ids=repr)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_randomize_rejected(env_id, value):
    with pytest.raises(ValueError, match="randomize"):
        make(env_id, randomize=value)


@pytest.mark.parametrize("value", [0, 0.0, np.float32(0.25), np.float64(0.5), np.array(0.1),
                                   0.999], ids=repr)
def test_good_randomize_accepted(value):
    env = make("gp_envs/CartPoleSwingUp-v0", randomize=value)
    assert env.unwrapped.randomize == float(value) and type(env.unwrapped.randomize) is float
    env.reset(seed=0)


@pytest.mark.parametrize(("env_id", "params", "randomize"), [
    ("gp_envs/DubinsObstacle-v0", {"b1": 0.95}, 0.1),     # 0.95 * 1.1 > 1
    ("gp_envs/DubinsObstacle-v0", {"b2": 0.6}, 0.999),    # 0.6 * 1.999 > 1
])
def test_randomize_that_could_draw_an_unphysical_truth_is_rejected_at_make(
        env_id, params, randomize):
    with pytest.raises(ValueError, match=r"randomize=.*valid range \(-inf, 1\)"):
        make(env_id, true_params=params, randomize=randomize)


def test_randomized_draws_stay_in_range_and_in_the_spread():
    """Near the edge of the range but inside it at both ends of the spread: never raises."""
    env = make("gp_envs/DubinsObstacle-v0", true_params={"b1": 0.9, "b2": 0.0}, randomize=0.1)
    draws = []
    for seed in range(200):
        env.reset(seed=seed)
        draws.append(gp_envs.oracle_model(env).params["b1"])
        assert gp_envs.oracle_model(env).params["b2"] == 0.0
    assert 0.81 <= min(draws) < 0.83 and 0.97 < max(draws) < 0.99


def test_dubins_nominal_draws_are_clipped_below_one():
    """N(0.3, 0.3) clipped above at 0.9: 1 - b stays positive; P(b < 0) = P(Z < -1) = 0.1587
    of the draws believe in an actuator stronger than its command."""
    env = make("gp_envs/DubinsObstacle-v0")
    draws = []
    for seed in range(600):
        env.reset(seed=seed)
        draws.append([env.unwrapped.nominal_model.params[k] for k in ("b1", "b2")])
    draws = np.array(draws)
    assert draws.max() == 0.9 and draws.min() < 0.0
    below = np.mean(draws < 0.0)
    assert abs(below - 0.1587) < 3 * np.sqrt(0.1587 * 0.8413 / draws.size)


def test_control_model_for_an_ode_without_a_range_table_takes_any_finite_value():
    from gp_envs.physics import ParamRange

    nominal = make("gp_envs/DubinsObstacle-v0").unwrapped.nominal_model
    fields = {k: getattr(nominal, k) for k in (
        "name", "param_names", "state_names", "control_names", "dt", "x_lb", "x_ub", "u_lb",
        "u_ub", "task", "substeps")}

    def ode(x, u, p):  # defined in this test module, which has no PARAM_RANGES
        return ca.vertcat(u[0], u[1], p[0] * p[1])

    # a user's ODE, no table: any finite real number, never NaN or inf
    free = gp_envs.ControlModel(**fields, ode=ode, params={"b1": -3.0, "b2": 0.2})
    np.testing.assert_allclose(free.f(np.zeros(3), [2.0, 3.0]), [2.0, 3.0, -0.6], rtol=1e-15)
    for bad in (np.nan, np.inf, "1.0"):
        with pytest.raises(ValueError, match="parameter b1"):
            free.with_params(b1=bad)
    unit = ParamRange(0.0, 1.0, True, True, "a test weight, dimensionless")
    ranges = {"b1": unit, "b2": unit}
    model = gp_envs.ControlModel(**fields, ode=ode, params={"b1": 1.0, "b2": 0.0},
                                 param_ranges=ranges)
    np.testing.assert_array_equal(model.f(np.zeros(3), [2.0, 3.0]), [2.0, 3.0, 0.0])
    with pytest.raises(ValueError, match=r"parameter b1 = 1\.5 .*\[0, 1\]"):
        model.with_params(b1=1.5)
    with pytest.raises(ValueError, match="cover exactly"):
        gp_envs.ControlModel(**fields, ode=ode, params={"b1": 1.0, "b2": 0.0},
                             param_ranges={"b1": unit})


# ------------------------------------------------------------------------ action shapes
def _wrong_shapes(m: int) -> list[tuple[int, ...]]:
    shapes = [(), (m, 1), (1, m), (m + 1,), (0,), (2, m)]
    if m > 1:
        shapes += [(m - 1,), (m // 2, 2)]
    return list(dict.fromkeys(shapes))  # without repeats


_SHAPE_CASES = [(env_id, shape) for env_id, m in zip(ENV_IDS, (1, 4, 2, 1), strict=True)
                for shape in _wrong_shapes(m)]


@pytest.mark.parametrize(("env_id", "shape"), _SHAPE_CASES, ids=str)
def test_wrong_action_shape_raises_and_leaves_the_env_unchanged(env_id, shape):
    env = make(env_id)
    env.reset(seed=0)
    twin = copy.deepcopy(env)
    mid = (env.action_space.low + env.action_space.high) / 2
    bad = np.full(shape, mid.flat[0], dtype=np.float32)
    with pytest.raises(ValueError, match=r"action must have shape \(\d\,\)"):
        env.step(bad)
    with pytest.raises(ValueError, match="shape"):
        env.step(bad.tolist())
    # the rejected calls did not advance the env: it steps on like an untouched copy
    a, b = env.step(mid.astype(np.float32)), twin.step(mid.astype(np.float32))
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1:] == b[1:]


def test_quadrotor_2x2_action_is_not_flattened():
    env = make("gp_envs/Quadrotor-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(4,\).*\(2, 2\)"):
        env.step(np.full((2, 2), 2.45, np.float32))


@pytest.mark.parametrize("action", [1.0, np.float32(1.0), np.array(1.0), [[1.0]]], ids=repr)
def test_cartpole_scalar_action_raises(action):
    env = make("gp_envs/CartPoleSwingUp-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(action)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_right_shape_as_list_or_float64_is_accepted_like_float32(env_id):
    env = make(env_id)
    env.reset(seed=0)
    twin = copy.deepcopy(env)
    a = _random_actions(env, 1, seed=3)[0]
    got = env.step([float(v) for v in a])
    want = twin.step(a)
    np.testing.assert_array_equal(got[0], want[0])
    assert got[1:] == want[1:]


@pytest.mark.parametrize("action", ["abc", {"f": 1.0}, [1.0, "x"], None, object()], ids=repr)
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_non_numeric_action_raises_value_error(env_id, action):
    env = make(env_id)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action must"):
        env.step(action)
