"""The puck's env and its registration (the module the ``gp_envs.systems`` entry point names)."""

from typing import ClassVar

import numpy as np

from gp_envs.base import GPEnv, Scenario
from gp_envs.model import Task, diag
from gp_envs.systems import System, register_system
from gp_puck import puck


class PuckEnv(GPEnv):
    """Push the puck from rest at 0 to 1 m and hold it there."""

    physics = puck
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "friction": Scenario(description="unmodeled friction, 20% mass error",
                             true={"m": 1.2, "c": 0.5}, nominal={"m": 1.0, "c": 0.0},
                             u_lb=(-2.0,), u_ub=(2.0,))}
    DEFAULT_SCENARIO = "friction"
    DT = 0.1
    SUBSTEPS = 2
    X_LB = np.array([-3.0, -5.0])
    X_UB = np.array([3.0, 5.0])
    DYNAMIC_INDICES = (1,)

    def _task(self):
        return Task(goal=np.array([1.0, 0.0]), Q=diag([10.0, 1.0]), R=diag([0.01]),
                    Qf=diag([100.0, 10.0]), u_ref=np.zeros(1),
                    goal_tolerance=np.array([0.05, np.inf]), hold_time=0.5, duration=3.0)

    def _initial_state(self):
        return self.np_random.uniform(-0.05, 0.05, size=2)


register_system(System(name="puck", env_id="gp_puck/Puck-v0", entry_point="gp_puck.env:PuckEnv",
                       max_episode_steps=30))
