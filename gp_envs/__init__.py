"""Gymnasium environments whose true physical parameters are hidden from the controller.

Importing this package registers (Gymnasium 1.x does not auto-load entry points):

- ``gp_envs/CartPoleSwingUp-v0``: :class:`gp_envs.cartpole_swingup.CartPoleSwingUpEnv`
- ``gp_envs/Quadrotor-v0``: :class:`gp_envs.quadrotor.QuadrotorEnv`
- ``gp_envs/DubinsObstacle-v0``: :class:`gp_envs.dubins_obstacle.DubinsObstacleEnv`

``gym.make("gp_envs:gp_envs/CartPoleSwingUp-v0")`` imports and registers in one go.

What a controller may know is ``env.unwrapped.nominal_model`` (a :class:`ControlModel`);
:func:`oracle_model` gives the truth, for upper-bound baselines only.
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.envs.registration import register, registry

from gp_envs.model import ControlModel, Obstacle, Task

__all__ = ["ENV_IDS", "ControlModel", "Obstacle", "Task", "oracle_model"]

__version__ = "0.1.0"

ENV_IDS = ("gp_envs/CartPoleSwingUp-v0", "gp_envs/Quadrotor-v0", "gp_envs/DubinsObstacle-v0")
"""The registered environment ids."""

_ENTRY_POINTS = {
    "gp_envs/CartPoleSwingUp-v0": ("gp_envs.cartpole_swingup:CartPoleSwingUpEnv", 120),
    "gp_envs/Quadrotor-v0": ("gp_envs.quadrotor:QuadrotorEnv", 120),
    "gp_envs/DubinsObstacle-v0": ("gp_envs.dubins_obstacle:DubinsObstacleEnv", 150),
}
for _env_id, (_entry, _steps) in _ENTRY_POINTS.items():
    if _env_id not in registry:
        register(id=_env_id, entry_point=_entry, max_episode_steps=_steps)


def oracle_model(env: gym.Env) -> ControlModel:
    """The *true* model of ``env``'s current episode, for an upper-bound (oracle) baseline.

    Ordinary controllers must use ``env.unwrapped.nominal_model`` instead: this function exists
    so that benchmarks can build the oracle explicitly and visibly. With per-episode
    randomization the truth changes at every ``reset``; call this after ``reset``.

    Raises:
        TypeError: ``env`` is not (a wrapper of) a ``gp_envs`` environment.
    """
    from gp_envs.base import GPEnv

    base = env.unwrapped
    if not isinstance(base, GPEnv):
        raise TypeError(f"oracle_model needs a gp_envs environment, got {type(base).__name__}")
    return base._oracle()
