"""Dubins vehicle going around a circular obstacle, with unknown actuator losses.

Physics: :mod:`gp_envs.physics.dubins` (paper, "Obstacle Avoidance using SSGP"; errata note 2).

## Observation (= full state), ``Box(3,)`` float32
``[x, y, psi]``: position in metres and heading in radians, observed wrapped to ``[-pi, pi]``.
The arena is ``|x|, |y| <= 10`` m; leaving it terminates the episode.

## Action, ``Box(2,)`` float32
Commanded speed ``u1`` in ``[0, 2]`` m/s and turn rate ``u2`` in ``[-2, 2]`` rad/s; the vehicle
delivers ``(1 - b1) u1`` and ``(1 - b2) u2``. Actions outside are clipped.

## Scenario "paper"
True ``b1 = b2 = 0.3`` (hidden). The nominal values are drawn anew at every reset from
``N(0.3, 0.3)`` (0.3 read as a standard deviation) and clipped above at 0.9, so that ``1 - b``
stays positive (errata note 2; about 16% of the draws fall below 0, an actuator believed
stronger than its command): ``env.unwrapped.nominal_model`` changes at every reset, so build
or refresh a controller after ``reset``.

## Scenario "paper-wear" (time-varying)
As "paper", and the true losses grow during the episode (:class:`~gp_envs.base.ParamChange`):
``b1 = b2 = 0.45`` from 5 s, ``0.6`` from 10 s (actuator wear; the nominal draw is as "paper").

## Task, reward, episode
From ``(5, 5)``, heading at the goal, to ``(2, -2)``; the obstacle of radius 2 is centred at
``(3.5, 1.5)``, the midpoint of the straight path, and the vehicle's body radius is 0.2 m.
Touching the obstacle (centre distance below 2.2 m) terminates the episode, counts as a
constraint violation, and costs the penalty of the remaining time times a bound of the stage cost.
Stage cost (per second) ``l = (p - p_goal)' (p - p_goal) + 0.05 |u|^2`` (heading free); reward
per step ``-dt * l``. Success: within 0.1 m of the goal (each axis) continuously for the last 0.5 s.
15 s episodes (150 steps of 0.1 s). Starts exactly at ``(5, 5)`` with ``U(-0.05, 0.05)`` rad
noise on the heading.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from gp_envs.base import GPEnv, ParamChange, Scenario
from gp_envs.model import Obstacle, Task, diag
from gp_envs.physics import dubins
from gp_envs.systems import System, register_system

START = np.array([5.0, 5.0])
GOAL = np.array([2.0, -2.0])
OBSTACLE = Obstacle(center=(3.5, 1.5), radius=2.0)
BODY_RADIUS = 0.2


class DubinsObstacleEnv(GPEnv):
    """Dubins obstacle avoidance; see the module docstring for spaces, scenario and task."""

    physics = dubins
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "paper": Scenario(
            description="paper, obstacle avoidance: true b = 0.3, nominal b ~ N(0.3, 0.3)",
            true={"b1": 0.3, "b2": 0.3}, nominal={"b1": 0.3, "b2": 0.3},
            u_lb=(0.0, -2.0), u_ub=(2.0, 2.0),
            nominal_spread={"b1": 0.3, "b2": 0.3}, nominal_max=0.9),
    }
    SCENARIOS["paper-wear"] = dataclasses.replace(
        SCENARIOS["paper"],
        changes=(ParamChange(5.0, {"b1": 1.5, "b2": 1.5}),
                 ParamChange(10.0, {"b1": 2.0, "b2": 2.0})),
        description="paper's setting; the actuator losses grow to 1.5x at 5 s, 2x at 10 s")
    DEFAULT_SCENARIO = "paper"
    DT = 0.1
    metadata: ClassVar[dict[str, Any]] = {**GPEnv.metadata, "render_fps": round(1 / DT)}
    SUBSTEPS = 5
    X_LB = np.array([-10.0, -10.0, -np.inf])
    X_UB = np.array([10.0, 10.0, np.inf])
    ANGLE_INDICES = (2,)
    DYNAMIC_INDICES = (0, 1, 2)

    def _task(self) -> Task:
        return Task(
            goal=np.array([GOAL[0], GOAL[1], 0.0]),
            Q=diag([1.0, 1.0, 0.0]), R=diag([0.05, 0.05]), Qf=diag([10.0, 10.0, 0.0]),
            u_ref=np.zeros(2), goal_tolerance=np.array([0.1, 0.1, np.inf]),
            hold_time=0.5, duration=15.0, obstacles=(OBSTACLE,), body_radius=BODY_RADIUS,
            periodic_indices=(2,),
        )

    def _observation_space(self) -> spaces.Box:
        low = np.array([-np.inf, -np.inf, -np.pi], np.float32)
        high = np.array([np.inf, np.inf, np.pi], np.float32)
        return spaces.Box(low, high, dtype=np.float32)

    def _observe(self, state: np.ndarray) -> np.ndarray:
        obs = state.copy()
        obs[2] = np.arctan2(np.sin(obs[2]), np.cos(obs[2]))
        return obs

    def _violation(self, state: np.ndarray) -> str | None:
        for ob in self.nominal_model.task.obstacles:
            if ob.clearance(state[:2], BODY_RADIUS) < 0:
                return "obstacle contact"
        return None

    def _initial_state(self) -> np.ndarray:
        heading = np.arctan2(GOAL[1] - START[1], GOAL[0] - START[0])
        return np.array([START[0], START[1], heading + self.np_random.uniform(-0.05, 0.05)])

    def _info(self, obs: np.ndarray, violation: str | None, reason: str | None, clipped: bool
              ) -> dict[str, Any]:
        info = super()._info(obs, violation, reason, clipped)
        info["clearance"] = float(OBSTACLE.clearance(obs[:2], BODY_RADIUS))
        return info

    def _render_frame(self, ax: Any) -> None:
        from matplotlib.patches import Circle

        ax.add_patch(Circle(OBSTACLE.center, OBSTACLE.radius, color="0.6"))
        ax.plot(*START, "s", color="0.4")
        ax.plot(*GOAL, "*", color="tab:green", ms=14)
        x, y, psi = self._state
        ax.add_patch(Circle((x, y), BODY_RADIUS, color="tab:blue"))
        ax.arrow(x, y, 0.5 * np.cos(psi), 0.5 * np.sin(psi), width=0.05, color="tab:red")
        ax.set_xlim(-1, 8)
        ax.set_ylim(-4, 7)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")


SYSTEM = register_system(System(
    name="dubins", env_id="gp_envs/DubinsObstacle-v0",
    entry_point="gp_envs.dubins_obstacle:DubinsObstacleEnv", max_episode_steps=150))
"""The Dubins vehicle's registration (:mod:`gp_envs.systems`)."""
