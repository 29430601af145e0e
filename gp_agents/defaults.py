"""What the controllers know of a system beyond its model: time scales and a data controller.

An env knows its physics and task (:mod:`gp_envs`); how far ahead an MPC should look, how finely,
and which crude controller collects its first data are the controllers' business, kept here by
the model's name (:attr:`gp_envs.ControlModel.name`). The built-in systems' entries are below;
:func:`register_defaults` adds yours (``docs/guide/own-system.md``). A model with no entry --
an env given its model by :func:`gp_envs.wrap`, say -- gets :func:`default_planning` and
uniform random data actions (:func:`gp_agents.data.collect_initial_data`).

The real-time iteration's solver tuning is kept the same way, in :mod:`gp_agents.mpc.tuning`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gp_agents.data_policies import (
    DataPolicy,
    cartpole_data_policy,
    dubins_data_policy,
    pendulum_data_policy,
    pilco_cartpole_data_policy,
    quadrotor_data_policy,
)
from gp_envs.model import ControlModel

__all__ = ["PlanningDefaults", "SystemDefaults", "default_planning", "register_defaults",
           "system_defaults", "unregister_defaults"]


@dataclass(frozen=True)
class PlanningDefaults:
    """A system's time scales for a model-based controller: how far ahead to look and how finely
    (what the system's author measured works).

    Attributes:
        horizon: receding horizon, seconds.
        n_nodes: Legendre-Gauss nodes per interval of the polynomial part of the horizon.
        n_intervals: intervals of the polynomial part (after the held control periods).
        nodes_per_period: LG nodes in each held control period of an episodic plan.
    """

    horizon: float
    n_nodes: int
    n_intervals: int = 1
    nodes_per_period: int = 3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.horizon) and self.horizon > 0):
            raise ValueError(f"PlanningDefaults: horizon must be a positive number of seconds, "
                             f"got {self.horizon!r}")
        for name in ("n_nodes", "n_intervals", "nodes_per_period"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"PlanningDefaults: {name} must be an integer >= 1, "
                                 f"got {value!r}")


@dataclass(frozen=True)
class SystemDefaults:
    """The controllers' defaults for one system.

    Attributes:
        planning: time scales (None: :func:`default_planning` of the model).
        data_policy: the crude feedback controller that collects initial learning data,
            ``data_policy(nominal_model, rng) -> policy(obs, t)``; it may use the nominal model
            only (None: uniform random controls within the model's bounds).
        data_start: (n,) state the data episodes start from (None: the env's own reset; a
            ``gp_envs`` env's ``reset(options={"state": ...})`` sets it).
    """

    planning: PlanningDefaults | None = None
    data_policy: DataPolicy | None = None
    data_start: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.planning is not None and not isinstance(self.planning, PlanningDefaults):
            raise TypeError(f"SystemDefaults: planning must be a PlanningDefaults, got "
                            f"{type(self.planning).__name__}")
        if self.data_policy is not None and not callable(self.data_policy):
            raise TypeError("SystemDefaults: data_policy must be a function "
                            "data_policy(model, rng) -> policy(obs, t)")
        if self.data_start is not None:
            start = tuple(float(v) for v in self.data_start)
            if not np.all(np.isfinite(start)):
                raise ValueError(f"SystemDefaults: data_start must be finite, got {start}")
            object.__setattr__(self, "data_start", start)


_DEFAULTS: dict[str, SystemDefaults] = {
    "cartpole": SystemDefaults(PlanningDefaults(horizon=1.5, n_nodes=16, n_intervals=1),
                               cartpole_data_policy),
    "quadrotor": SystemDefaults(PlanningDefaults(horizon=1.5, n_nodes=10, n_intervals=1),
                                quadrotor_data_policy),
    # data are gathered away from the obstacle: the actuator losses do not depend on position
    "dubins": SystemDefaults(PlanningDefaults(horizon=4.0, n_nodes=12, n_intervals=2),
                             dubins_data_policy, data_start=(-8.0, 6.0, 0.0)),
    # horizon chosen on seed 0 with the oracle: 1.5 s is upright at 4.0 s, 2.5 s at 2.65 s
    "pendulum": SystemDefaults(PlanningDefaults(horizon=2.5, n_nodes=12, n_intervals=2),
                               pendulum_data_policy),
    # horizon measured with the nominal MPC (n_nodes 16), env seeds 0-9: 2.5 s succeeds on
    # 10/10 (final stretch at the goal from 1.1-1.7 s); 1.5 s on 2/4 (seeds 0-3), 2.0 s on 2/3
    # (seeds 0-2), 3.0 s on 3/4 (seeds 0-3); 2.0 s or 2.5 s with two intervals on 9/10
    "pilco_cartpole": SystemDefaults(PlanningDefaults(horizon=2.5, n_nodes=16, n_intervals=1),
                                     pilco_cartpole_data_policy),
    # DeepMind Control's cart-pole (gp_envs.dmc): the cart pole's time scales and tracking
    # controller; uniform random forces keep the pole near hanging, where the data say little
    # about the upright pole
    "dmc_cartpole": SystemDefaults(PlanningDefaults(horizon=1.5, n_nodes=16, n_intervals=1),
                                   cartpole_data_policy),
}
_DEFAULTS["mujoco_cartpole"] = _DEFAULTS["dmc_cartpole"]  # the same cart pole as a gp_envs env


def register_defaults(name: str, defaults: SystemDefaults) -> SystemDefaults:
    """Register (or replace) the controllers' defaults of the system (model name) ``name``;
    returns them.

    Raises:
        TypeError: ``defaults`` is not a :class:`SystemDefaults`.
    """
    if not isinstance(defaults, SystemDefaults):
        raise TypeError(f"defaults must be a SystemDefaults, got {type(defaults).__name__}")
    _DEFAULTS[str(name)] = defaults
    return defaults


def unregister_defaults(name: str) -> SystemDefaults | None:
    """Remove the defaults of ``name`` (e.g. after a test); returns them (None: there were
    none)."""
    return _DEFAULTS.pop(name, None)


def system_defaults(model: ControlModel | str) -> SystemDefaults:
    """The registered defaults of ``model``'s system (a model or a model name); empty
    :class:`SystemDefaults` for a system without an entry."""
    name = model if isinstance(model, str) else model.name
    return _DEFAULTS.get(name, SystemDefaults())


def is_registered(model: ControlModel | str) -> bool:
    """Whether ``model``'s system (a model or a model name) has registered defaults."""
    return (model if isinstance(model, str) else model.name) in _DEFAULTS


DEFAULT_HORIZON_PERIODS = 50
"""The default horizon of a system without planning defaults, in control periods, at most."""
DEFAULT_HORIZON_FRACTION = 0.25
"""... and at most this fraction of the task's duration (and never less than 10 periods or
the whole task, whichever is shorter)."""


def default_planning(model: ControlModel) -> PlanningDefaults:
    """The planning of ``model``: its system's registered :class:`PlanningDefaults`, else a
    horizon of ``min(50 periods, duration / 4)`` (at least ``min(10 periods, duration)``) on
    one interval of 12 LG nodes: a swing-up or a reach at a usual control rate sees its goal
    within that, and the nodes resolve a few oscillations of it."""
    planning = system_defaults(model).planning
    if planning is not None:
        return planning
    dt, duration = model.dt, model.task.duration
    horizon = min(DEFAULT_HORIZON_PERIODS * dt, DEFAULT_HORIZON_FRACTION * duration)
    return PlanningDefaults(horizon=max(horizon, min(10 * dt, duration)), n_nodes=12)
