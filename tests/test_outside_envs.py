"""Outside simulators in the benchmark (benchmarks.outside_envs): made through gp_envs.wrap, run
by the engine, refusing what cannot apply, and the guide's model the benchmark's."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import gp_envs
from benchmarks.controllers import ENVS, make_env, scenario_changes
from benchmarks.outside_envs import OUTSIDE_ENVS, pendulum_v1_model
from benchmarks.trial import Cell, TrialSpec, execute

REPO = Path(__file__).resolve().parents[1]
GUIDE = REPO / "docs" / "guide" / "own-env.md"


def test_outside_envs_are_benchmark_envs_with_their_scenarios():
    for name, outside in OUTSIDE_ENVS.items():
        info = ENVS[name]
        assert info.outside is outside and info.env_id is None
        assert info.default_scenario in info.scenarios
        assert scenario_changes(name, info.default_scenario) == ()
    env = make_env("pendulum-v1", "light")
    assert gp_envs.nominal_model(env).params["m"] == 0.4
    assert gp_envs.oracle_model(env).params["m"] == 1.0


@pytest.mark.parametrize("option", [{"randomize": 0.1}, {"observation_noise": 0.01},
                                    {"true_params": {"m": 1.0}}])
def test_what_cannot_apply_to_an_outside_simulator_raises(option):
    with pytest.raises(ValueError, match="cannot apply"):
        make_env("pendulum-v1", "light", **option)
    make_env("pendulum-v1", "light", randomize=0.0, observation_noise=0.0)  # the defaults


def test_a_perturbed_start_on_an_outside_env_raises():
    record = execute(TrialSpec("episode", "pendulum-v1", "light", "nominal-mpc", 0,
                               max_steps=2, cell=Cell(start="perturbed")))
    assert record["status"] == "error" and "perturbation widths" in record["message"]


def test_the_engine_runs_an_outside_env_and_records_its_return():
    record = execute(TrialSpec("episode", "pendulum-v1", "light", "robust-mpc", 3, max_steps=4,
                               n_init=30, cell=Cell(data="own")))
    assert record["status"] == "ok", record.get("message")
    m = record["metrics"]
    assert m["steps"] == 4 and m["data_steps"] == 34
    assert m["return"] == pytest.approx(-m["cost"])  # Pendulum-v1's reward, summed
    assert 0 <= m["residual_off_steps"] <= 4
    nominal = execute(TrialSpec("episode", "pendulum-v1", "light", "nominal-mpc", 3,
                                max_steps=4))["metrics"]
    assert np.isnan(nominal["residual_off_steps"])


def test_the_guides_model_is_the_benchmarks():
    """The own-env guide's code block defines the model the benchmark's pendulum-v1 uses: same
    parameters, bounds, task and dynamics (checked by evaluating both)."""
    block = re.search(r"```python\n(.*?)```", GUIDE.read_text(), re.S).group(1)
    namespace: dict = {}
    exec(block.split("env = gp_envs.wrap")[0], namespace)  # the model, not the run
    guide, ours = namespace["model"], pendulum_v1_model(0.4)
    for field in ("name", "param_names", "state_names", "control_names", "dt", "substeps",
                  "angle_indices", "dynamic_indices"):
        assert getattr(guide, field) == getattr(ours, field), field
    assert dict(guide.params) == dict(ours.params)
    for field in ("x_lb", "x_ub", "u_lb", "u_ub"):
        np.testing.assert_array_equal(getattr(guide, field), getattr(ours, field))
    for field in ("goal", "Q", "R", "Qf", "u_ref", "goal_tolerance"):
        np.testing.assert_array_equal(getattr(guide.task, field), getattr(ours.task, field))
    rng = np.random.default_rng(0)
    x, u = rng.normal(size=(20, 2)), rng.uniform(-2, 2, size=(20, 1))
    np.testing.assert_allclose(guide.step(x, u), ours.step(x, u), rtol=1e-12)


def test_a_users_outside_env_is_a_benchmark_env():
    import gymnasium as gym

    from benchmarks.outside_envs import OutsideEnv, register_outside_env

    def make():
        return gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_v1_model(1.0),
                            state=lambda o: np.array([np.arctan2(o[1], o[0]), o[2]]))

    mine = OutsideEnv("my-pendulum", {"exact": make}, "exact", "a user's env")
    try:
        register_outside_env(mine)
        assert ENVS["my-pendulum"].outside is mine
        record = execute(TrialSpec("episode", "my-pendulum", "exact", "nominal-mpc", 0,
                                   max_steps=3))
        assert record["status"] == "ok", record.get("message")
    finally:
        OUTSIDE_ENVS.pop("my-pendulum", None)
    with pytest.raises(ValueError, match="registered gp_envs system"):
        register_outside_env(OutsideEnv("cartpole", {"a": make}, "a", "clash"))
    with pytest.raises(ValueError, match="default scenario"):
        register_outside_env(OutsideEnv("x", {"a": make}, "b", "typo"))
    with pytest.raises(TypeError, match="OutsideEnv"):
        register_outside_env("pendulum")
