"""Quadrotor point-to-point flight with a mass (and arm-length) mismatch.

Physics: :mod:`gp_envs.physics.quadrotor` (paper, Results, "Quadrotor"; errata note 3), a
12-state small-attitude model in a north-east-down frame (positive ``z`` is down).

## Observation (= full state), ``Box(12,)`` float32
``[x, y, z, phi, theta, psi, xdot, ydot, zdot, phidot, thetadot, psidot]`` in m, rad, m/s, rad/s.
The episode terminates when the state leaves the flight box ``|x|, |y| <= 3``, ``-2 <= z <= 4``,
the attitude limits ``|phi|, |theta| <= 1`` rad, ``|psi| <= pi``, or the divergence guards
``|v| <= 10`` m/s, ``|rates| <= 20`` rad/s.

## Action, ``Box(4,)`` float32
Rotor thrusts ``F1..F4`` in newtons, each in ``[0, 5]`` (hover needs ``m g / 4`` = 2.45 N each at
1 kg); actions outside are clipped.

## Scenarios (the paper's tables; true values hidden, nominal ones in ``nominal_model``)
| name     | table | true m, Jx, Jy, Jz, L                  | nominal m, L (inertias as true) |
|----------|-------|----------------------------------------|---------------------------------|
| "gp"     | 1     | 1, 8.1e-3, 8.1e-3, 14.2e-3, 0.24       | 0.9, 0.24                       |
| "online" | 2     | 1, 8.1e-3, 8.1e-3, 14.2e-3, 0.24       | 0.99, 0.2376                    |
| "online-payload" | - | as "online"; m = 1.2 from t = 3 s    | 0.99, 0.2376                    |

"online-payload" is time-varying (:class:`~gp_envs.base.ParamChange`): a point payload at the
centre of mass (inertias unchanged) is picked up at 3 s, while the vehicle holds the goal.

## Task, reward, episode
Fly from ``[-1, 1, 0.5]`` to ``[0.5, -1, 1.5]`` (m, NED) and hold there, level. Stage cost (per
second) ``l = e' Q e + (F - F_ref)' R (F - F_ref)`` with ``e = obs - goal``,
``Q = diag(10, 10, 10, 1, 1, 1, 0.5, 0.5, 0.5, 0.05, 0.05, 0.05)`` (the attitude terms keep the
small-attitude model valid, as in the paper), ``R = 0.05 I`` and ``F_ref`` the *nominal* hover
thrust ``m_nominal g / 4``; reward per step ``-dt * l``. Success: position within 0.05 m of the
goal on every axis continuously for the last 1 s. 6 s episodes (120 steps of 0.05 s); leaving the
box terminates with a penalty (remaining time times a bound of the stage cost). Starts at rest at
``[-1, 1, 0.5]`` with ``U(-0.01, 0.01)`` noise on position and attitude.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np

from gp_envs.base import GPEnv, ParamChange, Scenario
from gp_envs.model import Task, diag
from gp_envs.physics import quadrotor
from gp_envs.systems import System, register_system

G = 9.81
START = np.array([-1.0, 1.0, 0.5])
GOAL = np.array([0.5, -1.0, 1.5])
_INERTIA = {"Jx": 8.1e-3, "Jy": 8.1e-3, "Jz": 14.2e-3}


class QuadrotorEnv(GPEnv):
    """Quadrotor point-to-point; see the module docstring for spaces, scenarios and task."""

    physics = quadrotor
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "gp": Scenario(
            description="paper table 1 (GP example): 10% mass error",
            true={"m": 1.0, **_INERTIA, "L": 0.24, "g": G},
            nominal={"m": 0.9, **_INERTIA, "L": 0.24, "g": G},
            u_lb=(0.0,) * 4, u_ub=(5.0,) * 4),
        "online": Scenario(
            description="paper table 2 (online learning): 1% mass and 1% arm-length error",
            true={"m": 1.0, **_INERTIA, "L": 0.24, "g": G},
            nominal={"m": 0.99, **_INERTIA, "L": 0.2376, "g": G},
            u_lb=(0.0,) * 4, u_ub=(5.0,) * 4),

    }
    SCENARIOS["online-payload"] = dataclasses.replace(
        SCENARIOS["online"], changes=(ParamChange(3.0, {"m": 1.2}),),
        description="table 2's setting; picks up a payload at 3 s (+20% mass)")
    DEFAULT_SCENARIO = "online"
    DT = 0.05
    SUBSTEPS = 5
    X_LB = np.array([-3.0, -3.0, -2.0, -1.0, -1.0, -np.pi] + [-10.0] * 3 + [-20.0] * 3)
    X_UB = np.array([3.0, 3.0, 4.0, 1.0, 1.0, np.pi] + [10.0] * 3 + [20.0] * 3)
    ANGLE_INDICES = (3, 4, 5)
    DYNAMIC_INDICES = (6, 7, 8, 9, 10, 11)

    def _task(self) -> Task:
        hover = self.SCENARIOS[self.scenario].nominal["m"] * G / 4
        return Task(
            goal=np.concatenate([GOAL, np.zeros(9)]),
            Q=diag([10.0] * 3 + [1.0] * 3 + [0.5] * 3 + [0.05] * 3),
            R=diag([0.05] * 4), Qf=diag([100.0] * 3 + [10.0] * 3 + [5.0] * 3 + [0.5] * 3),
            u_ref=np.full(4, hover),
            goal_tolerance=np.array([0.05] * 3 + [np.inf] * 9),
            hold_time=1.0, duration=6.0,
        )

    def _initial_state(self) -> np.ndarray:
        state = np.zeros(12)
        state[:3] = START
        state[:6] += self.np_random.uniform(-0.01, 0.01, size=6)
        return state

    def _render_frame(self, ax: Any) -> None:
        s = self._state
        ax.plot(*START[:2], "s", color="0.5", label="start")
        ax.plot(*GOAL[:2], "*", color="tab:green", ms=14, label="goal")
        arm = self.nominal_model.params["L"] * 2
        for ang, color in ((s[5], "tab:blue"), (s[5] + np.pi / 2, "tab:orange")):
            dx, dy = arm * np.cos(ang), arm * np.sin(ang)
            ax.plot([s[0] - dx, s[0] + dx], [s[1] - dy, s[1] + dy], color=color, lw=3)
        ax.text(s[0], s[1] + 0.4, f"z = {s[2]:.2f} m (down)\nroll {s[3]:.2f}, pitch {s[4]:.2f}",
                ha="center", fontsize=8)
        ax.set_xlim(-3, 3)
        ax.set_ylim(-3, 3)
        ax.set_aspect("equal")
        ax.set_xlabel("x north (m)")
        ax.set_ylabel("y east (m)")
        ax.legend(loc="lower left", fontsize=7)


SYSTEM = register_system(System(
    name="quadrotor", env_id="gp_envs/Quadrotor-v0",
    entry_point="gp_envs.quadrotor:QuadrotorEnv", max_episode_steps=120))
"""The quadrotor's registration (:mod:`gp_envs.systems`)."""
