"""Gymnasium environments whose true physical parameters are hidden from the controller.

Importing this package registers these systems (:mod:`gp_envs.systems`: one
:func:`register_system` call each, at the end of its env module, gives the Gymnasium id under
the system's name):

- ``gp_envs/CartPoleSwingUp-v0``: :class:`gp_envs.cartpole_swingup.CartPoleSwingUpEnv`
- ``gp_envs/Quadrotor-v0``: :class:`gp_envs.quadrotor.QuadrotorEnv`
- ``gp_envs/DubinsObstacle-v0``: :class:`gp_envs.dubins_obstacle.DubinsObstacleEnv`
- ``gp_envs/PendulumSwingUp-v0``: :class:`gp_envs.pendulum_swingup.PendulumSwingUpEnv` (a
  fourth, small system, the example of adding one)
- ``gp_envs/PilcoCartPole-v0``: :class:`gp_envs.pilco_cartpole.PilcoCartPoleEnv` (PILCO's cart
  pole, its published numbers; not in :data:`ENV_IDS`, whose tests cover the four above)

``gym.make("gp_envs:gp_envs/CartPoleSwingUp-v0")`` imports and registers in one go.

What a controller may know is the env's nominal model (a :class:`ControlModel`:
:func:`nominal_model` finds it, ``env.unwrapped.nominal_model`` for these envs); :func:`wrap`
gives any other Gymnasium env one (:mod:`gp_envs.dmc`: DeepMind Control's tasks, MuJoCo
physics). :func:`oracle_model` gives the truth, for upper-bound baselines only.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from gp_envs import (  # noqa: F401  (each module registers its system)
    cartpole_swingup,
    dmc,
    dubins_obstacle,
    pendulum_swingup,
    pilco_cartpole,
    quadrotor,
)
from gp_envs.model import ControlModel, Obstacle, Task
from gp_envs.systems import (
    SYSTEMS,
    System,
    get_system,
    load_system_plugins,
    register_system,
    unregister_system,
)
from gp_envs.wrapper import ModelWrapper, model_wrapper, nominal_model, wrap

__all__ = ["ENV_IDS", "SYSTEMS", "ControlModel", "ModelWrapper", "Obstacle", "System", "Task",
           "get_system", "nominal_model", "oracle_model", "oracle_state", "outside_truth",
           "register_system",
           "unregister_system", "wrap"]

__version__ = "0.1.0"

ENV_IDS = tuple(SYSTEMS[name].env_id for name in ("cartpole", "quadrotor", "dubins", "pendulum"))
"""The ids of the built-in systems' envs (registered on import; :data:`SYSTEMS` also lists
installed packages' systems and those registered later)."""

load_system_plugins()


def oracle_model(env: gym.Env) -> ControlModel:
    """The *true* model of ``env``'s current episode, for an upper-bound (oracle) baseline.

    Ordinary controllers must use :func:`nominal_model` instead: this function exists so that
    benchmarks can build the oracle explicitly and visibly. With per-episode randomization the
    truth changes at every ``reset``; call this after ``reset``. For an env given its model by
    :func:`wrap`, the ``true_model`` passed there.

    Raises:
        TypeError: ``env`` is neither (a wrapper of) a ``gp_envs`` environment nor wrapped by
            :func:`wrap`.
        ValueError: a wrapped env without a ``true_model``.
    """
    from gp_envs.base import GPEnv

    wrapper = model_wrapper(env)
    if wrapper is not None:
        return wrapper.oracle_model()
    base = env.unwrapped
    if not isinstance(base, GPEnv):
        raise TypeError(f"oracle_model needs a gp_envs environment, got {type(base).__name__}")
    return base._oracle()


def outside_truth(env: gym.Env) -> bool:
    """Whether ``env``'s truth is outside its nominal model's family as far as the package can
    tell: True for an env given its model by :func:`wrap` (its own simulator, whatever the
    model) and for a ``gp_envs`` env whose plant is an outside simulator
    (:attr:`~gp_envs.base.GPEnv.OUTSIDE_PLANT`, e.g. :mod:`gp_envs.dmc`'s MuJoCo truths);
    False for a ``gp_envs`` env whose truth is its model's own ODE with hidden parameter
    values. It says nothing about the truth's parameters, which a controller never sees.

    Raises:
        TypeError: ``env`` is neither (a wrapper of) a ``gp_envs`` environment nor wrapped by
            :func:`wrap`.
    """
    from gp_envs.base import GPEnv

    if model_wrapper(env) is not None:
        return True
    base = env.unwrapped
    if not isinstance(base, GPEnv):
        raise TypeError(f"outside_truth needs a gp_envs environment or one given a model by "
                        f"gp_envs.wrap, got {type(base).__name__}")
    return bool(base.OUTSIDE_PLANT)


def oracle_state(env: gym.Env) -> np.ndarray:
    """The *true* current state of ``env`` (n,), as the env would observe it without sensor
    noise (angles wrapped): for scoring an episode run with ``observation_noise``, never for a
    controller, which sees only the (noisy) observations.

    Raises:
        TypeError: ``env`` is not (a wrapper of) a ``gp_envs`` environment.
    """
    from gp_envs.base import GPEnv

    base = env.unwrapped
    if not isinstance(base, GPEnv):
        raise TypeError(f"oracle_state needs a gp_envs environment, got {type(base).__name__}")
    return base._observe(base._state)
