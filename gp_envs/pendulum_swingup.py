"""Pendulum swing-up with unmodeled pivot friction and a mass error: a fourth, small system.

Physics: :mod:`gp_envs.physics.pendulum`. Everything the rest of the package needs to know about
this system is in this file and its physics module: the :func:`register_system` call at the end
gives the Gymnasium id, the MPC defaults, the initial-data controller and the benchmark entry
(``python -m benchmarks --envs pendulum``), with no other file naming the system.

## Observation (= full state), ``Box(2,)`` float32
| idx | name     | unit  | range                                   |
|-----|----------|-------|-----------------------------------------|
| 0   | theta    | rad   | ``[0, 2 pi)``; 0 hangs down, pi upright |
| 1   | thetadot | rad/s | ``|thetadot| <= 20`` (divergence guard) |

## Action, ``Box(1,)`` float32
Motor torque in N m, ``|tau| <= 2.5``; actions outside are clipped. Gravity's largest torque is
``m g l`` = 4.9 N m, so the pendulum must be pumped up over more than one swing.

## Scenario "damped" (true values hidden, nominal ones in ``nominal_model``)
| true m, l, b          | nominal m, l, b   |
|-----------------------|-------------------|
| 1.0, 0.5, 0.3         | 0.9, 0.5, 0       |

## Task, reward, episode
Swing up and balance: goal ``[pi, 0]``. Stage cost (per second) ``l = e' Q e + R tau^2`` with
the angle error wrapped to ``[-pi, pi]``, ``Q = diag(2, 0.05)``, ``R = 0.01``; reward per step
``-dt * l``. Success: ``|theta - pi| <= 0.1`` rad continuously for the last 1 s. 5 s episodes
(100 steps of 0.05 s); exceeding the rate guard terminates with the penalty of the remaining
time times a bound of the stage cost. Starts hanging at rest with ``U(-0.05, 0.05)`` noise on
both components.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from gp_envs.base import GPEnv, Scenario, wrap_to_circle
from gp_envs.model import Task, diag
from gp_envs.physics import pendulum
from gp_envs.systems import System, register_system

G = 9.81
TAU_MAX = 2.5
"""Torque bound, N m."""


class PendulumSwingUpEnv(GPEnv):
    """Damped pendulum swing-up; see the module docstring for spaces, scenario and task."""

    physics = pendulum
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "damped": Scenario(
            description="unmodeled pivot friction (b = 0.3) and a 10% mass error",
            true={"m": 1.0, "l": 0.5, "b": 0.3, "g": G},
            nominal={"m": 0.9, "l": 0.5, "b": 0.0, "g": G},
            u_lb=(-TAU_MAX,), u_ub=(TAU_MAX,)),
    }
    DEFAULT_SCENARIO = "damped"
    DT = 0.05
    SUBSTEPS = 5
    X_LB = np.array([-np.inf, -20.0])
    X_UB = np.array([np.inf, 20.0])
    ANGLE_INDICES = (0,)
    DYNAMIC_INDICES = (1,)

    def _task(self) -> Task:
        return Task(
            goal=np.array([np.pi, 0.0]), Q=diag([2.0, 0.05]), R=diag([1e-2]),
            Qf=diag([20.0, 1.0]), u_ref=np.zeros(1), goal_tolerance=np.array([0.1, np.inf]),
            hold_time=1.0, duration=5.0, periodic_indices=(0,),
        )

    def _observation_space(self) -> spaces.Box:
        low = np.array([0.0, -np.inf], np.float32)
        high = np.array([2 * np.pi, np.inf], np.float32)
        return spaces.Box(low, high, dtype=np.float32)

    def _observation_bounds_for_cost(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([0.0, self.X_LB[1]]), np.array([2 * np.pi, self.X_UB[1]])

    def _observe(self, state: np.ndarray) -> np.ndarray:
        obs = state.copy()
        obs[0] = wrap_to_circle(obs[0])
        return obs

    def _initial_state(self) -> np.ndarray:
        return self.np_random.uniform(-0.05, 0.05, size=2)

    def _render_frame(self, ax: Any) -> None:
        th = self._state[0]
        length = self.nominal_model.params["l"]  # drawn with the nominal length
        tip = (length * np.sin(th), -length * np.cos(th))
        ax.plot([0, tip[0]], [0, tip[1]], color="tab:orange", lw=4)
        ax.plot(*tip, "o", color="tab:red", ms=10)
        ax.plot(0, 0, "o", color="0.3", ms=6)
        ax.set_xlim(-0.8, 0.8)
        ax.set_ylim(-0.8, 0.8)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")


SYSTEM = register_system(System(
    name="pendulum", env_id="gp_envs/PendulumSwingUp-v0",
    entry_point="gp_envs.pendulum_swingup:PendulumSwingUpEnv", max_episode_steps=100))
"""The pendulum's registration (:mod:`gp_envs.systems`)."""
