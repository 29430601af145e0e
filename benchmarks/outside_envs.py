"""Benchmark envs whose truth is not this package's ODE: outside simulators given a nominal model
with :func:`gp_envs.wrap`.

Each entry makes its env per scenario; the truth is the simulator's own and hidden from the
controllers like any other. What a ``gp_envs`` env offers and an outside simulator cannot --
randomizing, overriding or changing its true parameters, observation noise, a perturbed start --
raises when asked for (:func:`benchmarks.controllers.make_env`), never silently does nothing.

- ``pendulum-v1``: Gymnasium's ``Pendulum-v1`` (its semi-implicit Euler step, speed clip and
  reward untouched) with the nominal model of ``docs/guide/own-env.md``: the pendulum's
  equations with the mass 60% low (scenario ``light``; the ``oracle`` recipe plans with the
  correct mass, the same equations).
- ``dmc-cartpole``: DeepMind Control Suite's ``cartpole``/``swingup`` (MuJoCo; its reward is the
  return reported) with :func:`gp_envs.dmc.cartpole_nominal_model`, the package's point-mass
  cart pole with ``cartpole.xml``'s numbers. Scenarios: ``swingup`` at a 0.05 s control period
  (action repeat 5), ``swingup-0.01`` at DMC's own 0.01 s, and ``swingup-friction``, the
  declared out-of-family case (:data:`gp_envs.dmc.CARTPOLE_FRICTION`: Coulomb friction on the
  slider and the hinge, which the model's viscous damping cannot represent). No true model
  exists (the truth is MuJoCo's), so the oracle recipe is unavailable.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import casadi as ca
import gymnasium as gym
import numpy as np

import gp_envs
from gp_envs import ControlModel, Task
from gp_envs.systems import load_system_plugins

__all__ = ["OUTSIDE_ENVS", "OutsideEnv", "pendulum_v1_model", "pendulum_v1_state",
           "register_outside_env"]


@dataclass(frozen=True)
class OutsideEnv:
    """A benchmark env made outside ``gp_envs``'s registry.

    Attributes:
        name: the benchmark's env name (``--envs``).
        scenarios: scenario name -> a function making the wrapped env.
        default_scenario: a key of :attr:`scenarios`.
        description: one line for listings and reports.
        requires: the module the env needs (an optional extra), or None.
    """

    name: str
    scenarios: Mapping[str, Callable[[], gym.Env]]
    default_scenario: str
    description: str
    requires: str | None = None

    def make(self, scenario: str) -> gym.Env:
        """The env of ``scenario`` (its own truth, its own reward).

        Raises:
            ValueError: an unknown scenario.
            ImportError: the optional dependency is not installed.
        """
        if scenario not in self.scenarios:
            raise ValueError(f"unknown scenario {scenario!r} of env {self.name}; valid "
                             f"scenarios: {', '.join(self.scenarios)}")
        return self.scenarios[scenario]()


# ----------------------------------------------------------------------- Pendulum-v1
def _pendulum_ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Pendulum-v1's equations of motion, theta = 0 upright:
    ``thetaddot = 3 g / (2 l) sin(theta) + 3 u / (m l^2)``."""
    m, length, g = p[0], p[1], p[2]
    return ca.vertcat(x[1], 3 * g / (2 * length) * ca.sin(x[0]) + 3 / (m * length**2) * u[0])


def pendulum_v1_model(mass: float) -> ControlModel:
    """The nominal model of ``Pendulum-v1`` of the own-env guide, with pendulum mass ``mass``
    (kg; the env's is 1): state ``[theta (rad, 0 upright), thetadot (rad/s)]``, torque within
    2 N m, the env's reward weights as the task's cost, success: within 0.1 rad of upright for
    1 s."""
    task = Task(goal=[0.0, 0.0], Q=np.diag([1.0, 0.1]), R=[[0.001]], Qf=np.diag([10.0, 1.0]),
                goal_tolerance=[0.1, np.inf], hold_time=1.0, duration=10.0,
                periodic_indices=(0,))
    return ControlModel(
        name="pendulum_v1", ode=_pendulum_ode, params={"m": mass, "l": 1.0, "g": 10.0},
        task=task, state_names=("theta", "thetadot"), control_names=("torque",), dt=0.05,
        u_lb=[-2.0], u_ub=[2.0], x_lb=[-np.inf, -8.0], x_ub=[np.inf, 8.0], angle_indices=(0,),
        dynamic_indices=(1,))


def pendulum_v1_state(obs: np.ndarray) -> np.ndarray:
    """``[cos theta, sin theta, thetadot]`` -> ``[theta, thetadot]``."""
    return np.array([np.arctan2(obs[1], obs[0]), obs[2]])


def _pendulum_light() -> gym.Env:
    return gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_v1_model(0.4), state=pendulum_v1_state,
                        true_model=pendulum_v1_model(1.0))


# ----------------------------------------------------------------------- DMC cart-pole
def _dmc_cartpole(action_repeat: int, friction: bool = False) -> Callable[[], gym.Env]:
    def make() -> gym.Env:
        from gp_envs import dmc

        simulator = dmc.DMCEnv("cartpole", "swingup", action_repeat=action_repeat,
                               dof_frictionloss=dmc.CARTPOLE_FRICTION if friction else None)
        return gp_envs.wrap(simulator, dmc.cartpole_nominal_model(action_repeat),
                            state=dmc.cartpole_state, action=dmc.cartpole_action)

    return make


OUTSIDE_ENVS: dict[str, OutsideEnv] = {
    "pendulum-v1": OutsideEnv(
        "pendulum-v1", {"light": _pendulum_light}, "light",
        "Gymnasium's Pendulum-v1 with a nominal model 60% light (gp_envs.wrap)"),
    "dmc-cartpole": OutsideEnv(
        "dmc-cartpole", {"swingup": _dmc_cartpole(5), "swingup-0.01": _dmc_cartpole(1),
                         "swingup-friction": _dmc_cartpole(5, friction=True)}, "swingup",
        "DeepMind Control's cartpole/swingup (MuJoCo), the package's cart-pole physics as the "
        "nominal model", requires="dm_control"),
}
"""The outside benchmark envs by name (:func:`register_outside_env` adds yours)."""


def register_outside_env(env: OutsideEnv) -> OutsideEnv:
    """Make ``env`` a benchmark env (``gp-bench --envs NAME``); returns it. For the benchmark's
    worker processes to know it too, register it in a module declared in the entry-point group
    :data:`PLUGIN_GROUP` of your package.

    Raises:
        TypeError: not an :class:`OutsideEnv`.
        ValueError: its name is a registered ``gp_envs`` system's, or its default scenario is
            none of its scenarios.
    """
    from gp_envs.systems import SYSTEMS

    if not isinstance(env, OutsideEnv):
        raise TypeError(f"env must be an OutsideEnv, got {type(env).__name__}")
    if env.name in SYSTEMS:
        raise ValueError(f"{env.name!r} is a registered gp_envs system; choose another name")
    if env.default_scenario not in env.scenarios:
        raise ValueError(f"{env.name}: default scenario {env.default_scenario!r} is not one of "
                         f"{list(env.scenarios)}")
    OUTSIDE_ENVS[env.name] = env
    return env


PLUGIN_GROUP = "benchmarks.outside_envs"
"""Entry-point group of installed packages' modules that register outside envs; loaded when
this module is imported."""
load_system_plugins(PLUGIN_GROUP)

