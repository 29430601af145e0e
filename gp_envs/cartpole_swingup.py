"""Cart-pole swing-up with unmodeled ground and pivot damping.

Physics: :mod:`gp_envs.physics.cartpole` (paper, Results, "Cart Pole"; errata note 1).

## Observation (= full state), ``Box(4,)`` float32
| idx | name     | unit  | range                                   |
|-----|----------|-------|-----------------------------------------|
| 0   | x        | m     | cart position, track is ``|x| <= 2.5``  |
| 1   | theta    | rad   | ``[0, 2 pi)``; 0 hangs down, pi upright |
| 2   | xdot     | m/s   | ``|xdot| <= 10`` (divergence guard)     |
| 3   | thetadot | rad/s | ``|thetadot| <= 25`` (divergence guard) |

The pole angle is observed wrapped to ``[0, 2 pi)`` so that upright (pi) lies inside the range and
the quadratic cost in ``theta - pi`` is continuous around the circle (0 and 2 pi cost the same).

## Action, ``Box(1,)`` float32
Horizontal force on the cart in newtons, ``|f| <= f_max`` with ``f_max`` set per scenario (below);
actions outside are clipped.

## Scenarios (the paper's tables; true values are hidden, nominal ones are ``nominal_model``)
| name     | table | true mc, mp, l, b1, b2        | nominal mc, mp, l, b1, b2 | f_max |
|----------|-------|-------------------------------|---------------------------|-------|
| "gp"     | 1     | 0.5, 0.5, 0.6, 0.01, 0.01     | 0.5, 0.5, 0.6, 0, 0       | 20 N  |
| "online" | 2     | 1.0, 0.5, 0.5, 0.3, 0.3       | 0.9, 0.45, 0.45, 0, 0     | 35 N  |
| "online-wear" | - | as "online"; b1, b2 double at t = 3 s | as "online"        | 35 N  |

"online-wear" is time-varying (:class:`~gp_envs.base.ParamChange`): the truth changes during the
episode, after the swing-up, while the pole is balanced; the nominal model stays the same.

With the dissipative damping of the "online" table no swing-up exists within 20 N; the bound of
35 N is chosen so that the true system can swing up within the episode (the smallest feasible
bound for the true and the nominal model).

## Task, reward, episode
Swing up and balance at the track centre: goal ``[0, pi, 0, 0]``. Stage cost (per second)
``l = e' Q e + R f^2``, ``e = obs - goal`` with the angle error wrapped to ``[-pi, pi]`` (the
same for either direction of swing-up), ``Q = diag(2, 2, 0.05, 0.05)``, ``R = 1e-3``; reward per
step ``-dt * l``. Success: ``|x| <= 0.1`` m and ``|theta - pi| <= 0.1`` rad continuously for the
last 1 s. The episode lasts 6 s (120 steps of 0.05 s, truncation). Leaving the track (or the
velocity guards) terminates with a penalty of the remaining time times an upper bound of the
stage cost, so that ending early never pays. Starts hanging at rest with ``U(-0.05, 0.05)`` noise
on every component.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from gp_envs.base import GPEnv, ParamChange, Scenario, wrap_to_circle
from gp_envs.model import Task, diag
from gp_envs.physics import cartpole
from gp_envs.systems import System, register_system

G = 9.81


class CartPoleSwingUpEnv(GPEnv):
    """Cart-pole swing-up; see the module docstring for spaces, scenarios and task."""

    physics = cartpole
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "gp": Scenario(
            description="paper table 1 (GP example): small unmodeled damping",
            true={"mc": 0.5, "mp": 0.5, "l": 0.6, "b1": 0.01, "b2": 0.01, "g": G},
            nominal={"mc": 0.5, "mp": 0.5, "l": 0.6, "b1": 0.0, "b2": 0.0, "g": G},
            u_lb=(-20.0,), u_ub=(20.0,)),
        "online": Scenario(
            description="paper table 2 (online learning): mass/length errors, large damping",
            true={"mc": 1.0, "mp": 0.5, "l": 0.5, "b1": 0.3, "b2": 0.3, "g": G},
            nominal={"mc": 0.9, "mp": 0.45, "l": 0.45, "b1": 0.0, "b2": 0.0, "g": G},
            u_lb=(-35.0,), u_ub=(35.0,)),

    }
    SCENARIOS["online-wear"] = dataclasses.replace(
        SCENARIOS["online"], changes=(ParamChange(3.0, {"b1": 2.0, "b2": 2.0}),),
        description="table 2's setting with the ground and pivot damping doubling at 3 s")
    DEFAULT_SCENARIO = "online"
    DT = 0.05
    SUBSTEPS = 10
    TRACK = 2.5
    X_LB = np.array([-TRACK, -np.inf, -10.0, -25.0])
    X_UB = np.array([TRACK, np.inf, 10.0, 25.0])
    ANGLE_INDICES = (1,)
    DYNAMIC_INDICES = (2, 3)

    def _task(self) -> Task:
        return Task(
            goal=np.array([0.0, np.pi, 0.0, 0.0]),
            Q=diag([2.0, 2.0, 0.05, 0.05]), R=diag([1e-3]), Qf=diag([20.0, 20.0, 1.0, 1.0]),
            u_ref=np.zeros(1), goal_tolerance=np.array([0.1, 0.1, np.inf, np.inf]),
            hold_time=1.0, duration=6.0, periodic_indices=(1,),
        )

    def _observation_space(self) -> spaces.Box:
        low = np.array([-self.TRACK, 0.0, self.X_LB[2], self.X_LB[3]], np.float32)
        high = np.array([self.TRACK, 2 * np.pi, self.X_UB[2], self.X_UB[3]], np.float32)
        # positions/velocities may overshoot the box on the step that terminates the episode
        low[[0, 2, 3]] = -np.inf
        high[[0, 2, 3]] = np.inf
        return spaces.Box(low, high, dtype=np.float32)

    def _observation_bounds_for_cost(self) -> tuple[np.ndarray, np.ndarray]:
        lb, ub = self.X_LB.copy(), self.X_UB.copy()
        lb[1], ub[1] = 0.0, 2 * np.pi
        return lb, ub

    def _observe(self, state: np.ndarray) -> np.ndarray:
        obs = state.copy()
        obs[1] = wrap_to_circle(obs[1])
        return obs

    def _initial_state(self) -> np.ndarray:
        return self.np_random.uniform(-0.05, 0.05, size=4)

    def _render_frame(self, ax: Any) -> None:
        x, th = self._state[0], self._state[1]
        length = self.nominal_model.params["l"]  # drawn with the nominal length
        ax.plot([-self.TRACK, self.TRACK], [0, 0], color="0.4", lw=2)
        ax.add_patch(_rect(x - 0.2, -0.1, 0.4, 0.2))
        tip = (x + length * np.sin(th), -length * np.cos(th))
        ax.plot([x, tip[0]], [0, tip[1]], color="tab:orange", lw=4)
        ax.plot(*tip, "o", color="tab:red", ms=8)
        ax.set_xlim(-self.TRACK - 0.3, self.TRACK + 0.3)
        ax.set_ylim(-1.0, 1.0)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")


def _rect(x: float, y: float, w: float, h: float) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), w, h, color="tab:blue")


SYSTEM = register_system(System(
    name="cartpole", env_id="gp_envs/CartPoleSwingUp-v0",
    entry_point="gp_envs.cartpole_swingup:CartPoleSwingUpEnv", max_episode_steps=120))
"""The cart pole's registration (:mod:`gp_envs.systems`)."""
