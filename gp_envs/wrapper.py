"""Any Gymnasium env with a nominal model: :func:`wrap`, and finding an env's model.

A controller of this package needs two things of an env: the model it may know (a
:class:`~gp_envs.model.ControlModel`: dynamics, bounds, the task it plans for) and observations
in that model's state coordinates. The built-in envs (:class:`gp_envs.base.GPEnv`) carry both;
:func:`wrap` gives them to any other env with ``Box`` spaces -- Gymnasium's ``Pendulum-v1``, a
MuJoCo env, DeepMind Control's tasks (:mod:`gp_envs.dmc`) -- without touching its physics or
its reward::

    env = gp_envs.wrap(gym.make("Pendulum-v1"), my_model,
                       state=lambda o: np.array([np.arctan2(o[1], o[0]), o[2]]))

The wrapper's observations are the model's state, its actions the model's controls, its reward
the env's own; ``info`` gains the task's ``at_goal``, ``success`` (held at the goal for the
task's ``hold_time``), ``at_goal_since``, ``distance_to_goal`` and ``time``.

:func:`nominal_model` finds the model of any env: through the wrapper chain, so an env wrapped
again (a recorder, a time limit) still has it.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gp_envs.base import GPEnv, checked_action, task_info
from gp_envs.model import ControlModel

__all__ = ["ModelWrapper", "nominal_model", "wrap"]

StateMap = Callable[[np.ndarray], np.ndarray]
"""``state(obs) -> x``: the env's observation to the model's state (n,), model units."""
ActionMap = Callable[[np.ndarray], np.ndarray]
"""``action(u) -> a``: the model's control (m,) to the env's action (its action space's shape)."""

BOUND_TOLERANCE = 1e-6
"""Relative slack (of the env's action range, at least 1e-6 absolute) allowed when the model's
control bounds, mapped by ``action``, are checked against the env's action space: float32
rounding of the space's bounds, never a real contradiction."""

GP_ENV_OPTIONS = frozenset({"keep_system", "state"})
"""The reset options of :class:`gp_envs.base.GPEnv`, refused for any other wrapped env."""

MAX_CORNERS = 10
"""Up to this many controls, every corner of the model's control box is checked against the
env's action space; above it, the two extreme corners (``u_lb`` and ``u_ub``)."""


class ModelWrapper(gym.Wrapper[np.ndarray, np.ndarray, Any, Any],
                   gym.utils.RecordConstructorArgs):
    """An env seen through a nominal model: see :func:`wrap` (which builds it)."""

    def __init__(self, env: gym.Env, model: ControlModel, *, state: StateMap | None = None,
                 action: ActionMap | None = None, true_model: ControlModel | None = None
                 ) -> None:
        if not isinstance(env, gym.Env):
            raise TypeError(f"wrap needs a Gymnasium env, got {type(env).__name__}")
        if not isinstance(model, ControlModel):
            raise TypeError(f"wrap needs a gp_envs ControlModel as the nominal model, got "
                            f"{type(model).__name__}")
        for name, space in (("observation", env.observation_space),
                            ("action", env.action_space)):
            if not isinstance(space, spaces.Box):
                raise TypeError(f"wrap needs an env with a Box {name} space, got "
                                f"{type(space).__name__}")
        for name, fn in (("state", state), ("action", action)):
            if fn is not None and not callable(fn):
                raise TypeError(f"{name} must be a function or None, got {type(fn).__name__}")
        n, m = model.n_states, model.n_controls
        if state is None and env.observation_space.shape != (n,):
            raise ValueError(f"the env's observations have shape {env.observation_space.shape} "
                             f"but the model {model.name!r} has {n} states: pass state=, the "
                             f"map from an observation to the model's state")
        if action is None and env.action_space.shape != (m,):
            raise ValueError(f"the env's actions have shape {env.action_space.shape} but the "
                             f"model {model.name!r} has {m} controls: pass action=, the map "
                             f"from the model's control to the env's action")
        if not (np.all(np.isfinite(model.u_lb)) and np.all(np.isfinite(model.u_ub))):
            raise ValueError(f"the model {model.name!r} needs finite control bounds u_lb, u_ub "
                             f"(they are the wrapped env's action space), got {model.u_lb}, "
                             f"{model.u_ub}")
        if true_model is not None:
            if not isinstance(true_model, ControlModel):
                raise TypeError(f"true_model must be a ControlModel or None, got "
                                f"{type(true_model).__name__}")
            if (true_model.n_states, true_model.n_controls) != (n, m) or \
                    true_model.dt != model.dt:
                raise ValueError(f"true_model must have the nominal model's {n} states, {m} "
                                 f"controls and dt {model.dt} s, got {true_model.n_states}, "
                                 f"{true_model.n_controls} and {true_model.dt} s")
        gym.utils.RecordConstructorArgs.__init__(self, model=model, state=state, action=action,
                                                 true_model=true_model)
        gym.Wrapper.__init__(self, env)
        self.nominal_model: ControlModel = model
        """What a controller may know: the model it plans with and the task."""
        self._state_map, self._action_map = state, action
        self._true_model = true_model
        self._check_period(env, model)
        self._check_action_bounds()
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)
        self.action_space = spaces.Box(model.u_lb.astype(np.float32),
                                       model.u_ub.astype(np.float32), dtype=np.float32)
        self._held = 0
        self._steps = 0

    # ----------------------------------------------------------------- checks
    @staticmethod
    def _check_period(env: gym.Env, model: ControlModel) -> None:
        """The env's own period (an attribute ``dt``, as Gymnasium's MuJoCo and classic-control
        envs have) must be the model's: the model predicts one env step."""
        try:
            dt = env.get_wrapper_attr("dt")
        except AttributeError:
            return
        if isinstance(dt, (int, float, np.floating)) and not isinstance(dt, bool) \
                and not np.isclose(float(dt), model.dt, rtol=1e-9, atol=1e-12):
            raise ValueError(f"the env steps {float(dt)} s per step but the model "
                             f"{model.name!r} has dt {model.dt} s: a model predicts one env "
                             f"step (build it with the env's period)")

    def _check_action_bounds(self) -> None:
        """Every corner of the model's control box, mapped by ``action``, must be an action
        the env's action space allows (else the model plans with forces the env clips)."""
        model, space = self.nominal_model, self.env.action_space
        lb, ub = model.u_lb, model.u_ub
        if model.n_controls <= MAX_CORNERS:
            corners = [np.array(c, float) for c in itertools.product(*zip(lb, ub, strict=True))]
        else:
            corners = [np.asarray(lb, float), np.asarray(ub, float)]
        low, high = space.low.astype(float), space.high.astype(float)
        slack = np.maximum(BOUND_TOLERANCE * np.where(np.isfinite(high - low), high - low, 0),
                           1e-6)
        for u in corners:
            a = self._env_action(u)
            if np.any(a < low - slack) or np.any(a > high + slack):
                raise ValueError(f"the model's control bounds contradict the env's action "
                                 f"space: the control {u} maps to the action {a}, outside "
                                 f"[{space.low}, {space.high}] (narrow the model's u_lb/u_ub "
                                 f"or fix action=)")

    def _env_action(self, u: np.ndarray) -> np.ndarray:
        space = self.env.action_space
        raw = u if self._action_map is None else self._action_map(np.array(u, float))
        try:
            a = np.asarray(raw, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"action(u) must return numbers, got {raw!r}") from None
        if a.shape != space.shape:
            raise ValueError(f"action(u) must return the env's action shape {space.shape}, got "
                             f"{a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action(u) returned a non-finite action {a} for the control {u}")
        return a

    def state(self, obs: np.ndarray) -> np.ndarray:
        """The model's state (n,) of an observation of the env (``state=`` of :func:`wrap`).

        Raises:
            ValueError: ``state(obs)`` is not (n,) numbers, or not finite.
        """
        raw = np.asarray(obs) if self._state_map is None else self._state_map(obs)
        try:
            x = np.asarray(raw, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"state(obs) must return numbers, got {raw!r}") from None
        n = self.nominal_model.n_states
        if x.shape != (n,):
            raise ValueError(f"state(obs) must return the model's state of shape ({n},), got "
                             f"{x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"state(obs) returned a non-finite state {x} for the observation "
                             f"{obs}")
        return x

    # ----------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the env (``seed`` and ``options`` passed on); the observation is the model's
        state.

        Raises:
            ValueError: a ``gp_envs`` env's own option (``keep_system``, ``state``) for an env
                that is not one (it would ignore it or mean something else).
        """
        own = sorted(set(options or {}) & GP_ENV_OPTIONS)
        if own and not isinstance(self.env.unwrapped, GPEnv):
            raise ValueError(f"reset option(s) {own} are gp_envs envs' own; "
                             f"{type(self.env.unwrapped).__name__} is not one (its truth and "
                             f"start are its own)")
        obs, info = self.env.reset(seed=seed, options=options)
        self._held = self._steps = 0
        x = self.state(obs)
        return x.astype(np.float32), self._task_info(dict(info), x, terminated=False,
                                                     clipped=False)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool,
                                                 dict[str, Any]]:
        """One env step with the model's control ``action`` (m,), clipped to the model's
        bounds (``info["action_clipped"]`` says so); the reward is the env's own.

        Raises:
            ValueError: a control that is not (m,) finite numbers.
        """
        u = checked_action(action, self.action_space.shape)
        model = self.nominal_model
        clipped_u = np.clip(u, model.u_lb, model.u_ub)
        a = self._env_action(clipped_u).astype(self.env.action_space.dtype)
        obs, reward, terminated, truncated, info = self.env.step(a)
        self._steps += 1
        x = self.state(obs)
        if model.task.at_goal(x) and not terminated:
            self._held += 1
        else:
            self._held = 0
        info = self._task_info(dict(info), x, terminated=bool(terminated),
                               clipped=bool(np.any(clipped_u != u)))
        return x.astype(np.float32), reward, bool(terminated), bool(truncated), info

    def _task_info(self, info: dict[str, Any], x: np.ndarray, *, terminated: bool,
                   clipped: bool) -> dict[str, Any]:
        """``info`` with the task's keys (the same as a :class:`~gp_envs.base.GPEnv`'s)."""
        model = self.nominal_model
        info.update(task_info(model.task, model.dt, self._steps, self._held, x, violation=None,
                              reason="terminated by the env" if terminated else None,
                              clipped=clipped))
        return info

    def oracle_model(self) -> ControlModel:
        """The ``true_model`` given to :func:`wrap` (for an upper-bound baseline only).

        Raises:
            ValueError: none was given (the truth of an outside simulator is not a model).
        """
        if self._true_model is None:
            name = self.env.spec.id if self.env.spec else type(self.env.unwrapped).__name__
            raise ValueError(f"this wrapped env ({name}) has no true model: pass true_model= "
                             f"to gp_envs.wrap for an oracle")
        return self._true_model


def wrap(env: gym.Env, model: ControlModel, *, state: StateMap | None = None,
         action: ActionMap | None = None, true_model: ControlModel | None = None
         ) -> ModelWrapper:
    """``env`` with a nominal model: an env every controller and the benchmark of this
    package take (:func:`gp_agents.make_mpc`, :func:`gp_agents.collect_initial_data`,
    :func:`gp_agents.rollout`, the RL agent).

    Args:
        env: a Gymnasium env with ``Box`` observation and action spaces (its physics, reward
            and termination stay as they are). Its period, if it declares one (``env.dt``),
            must be ``model.dt``.
        model: the nominal model of one env step (:class:`~gp_envs.model.ControlModel`, e.g.
            built from your own CasADi ODE): what a controller may know. Its task is what the
            controllers plan for and what ``info["success"]`` judges; its control bounds are
            the wrapper's action space (finite).
        state: ``state(obs) -> x`` (n,), the observation in the model's state coordinates
            (default: the observation itself, which must then be (n,)).
        action: ``action(u) -> a``, the model's control (m,) to the env's action (default: the
            control itself, which must then have the env's action shape).
        true_model: the true model, if one exists, for the ``oracle`` recipe (an upper bound);
            without it, the oracle raises.

    Returns:
        The wrapped env: observations (n,) float32 in the model's state, actions (m,) in the
        model's control bounds, the env's reward, ``info`` with the task's keys.

    Raises:
        TypeError: ``env`` is not a Gymnasium env or has a non-``Box`` space; ``model`` or
            ``true_model`` is not a :class:`~gp_envs.model.ControlModel`; ``state``/``action``
            not callable.
        ValueError: shapes that do not match the model without a ``state``/``action`` map;
            infinite control bounds; control bounds that ``action`` maps outside the env's
            action space; an env period other than ``model.dt``; a ``true_model`` of other
            sizes or period. At every reset and step: ``state(obs)`` of the wrong shape or not
            finite.
    """
    return ModelWrapper(env, model, state=state, action=action, true_model=true_model)


def nominal_model(env: gym.Env) -> ControlModel:
    """The nominal model of ``env``: a :func:`wrap`-ped env's, or a ``gp_envs`` env's
    ``nominal_model``, found through the wrapper chain (an env wrapped again still has it).

    Raises:
        TypeError: ``env`` has no nominal model (the message says how to give it one).
    """
    try:
        model = env.get_wrapper_attr("nominal_model")
    except AttributeError:
        model = None
    if not isinstance(model, ControlModel):
        raise TypeError(f"{type(env.unwrapped).__name__} has no nominal model: a gp_envs env "
                        f"has one; give any other Gymnasium env one with "
                        f"gp_envs.wrap(env, model, state=..., action=...)")
    return model


def model_wrapper(env: gym.Env) -> ModelWrapper | None:
    """The outermost :class:`ModelWrapper` in ``env``'s wrapper chain, or None."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, ModelWrapper):
            return env
        env = env.env
    return None
