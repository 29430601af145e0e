"""Initial training data: a crude feedback controller tracking a sinusoidal reference.

Paper, Results, "Cart Pole": "We generated 200 points of data using a sinusoidal desired
trajectory from a crude feedback controller"; for the quadrotor the reference was a circle in x-y
at constant height ("flying in circles", "remained level in the z direction"). The controllers
(:mod:`gp_agents.data_policies`, registered by system name in :mod:`gp_agents.defaults`)
use only the env's *nominal* model (gains, hover thrust), act through ``env.step`` on the true
plant, and are seeded (reference phase, amplitude and small action noise).

The data is the list of observed transitions ``(x_k, u_k, x_{k+1})``; see
:class:`gp_agents.residual.ResidualModel` for turning them into GP targets.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from gp_agents.agent import rollout
from gp_agents.data_policies import DataPolicy, Policy
from gp_agents.defaults import system_defaults
from gp_envs.base import GPEnv
from gp_envs.model import ControlModel
from gp_envs.wrapper import nominal_model


@dataclass(frozen=True)
class Transitions:
    """Observed transitions.

    Attributes:
        X: (N, n) states at the start of each control period.
        U: (N, m) actions applied (after the env's clipping).
        X_next: (N, n) states one period later.
    """

    X: np.ndarray
    U: np.ndarray
    X_next: np.ndarray

    def __len__(self) -> int:
        return int(self.X.shape[0])


def collect_initial_data(env: gym.Env, n_points: int = 200, seed: int = 0,
                         action_noise: float = 0.05, *, same_system: bool = True,
                         policy: Policy | None = None) -> Transitions:
    """Roll out a data-collecting controller on ``env``: its system's crude tracking controller,
    uniform random actions, or your own ``policy``.

    The controller, unless ``policy`` is given: the data policy registered for the model's
    system (:class:`gp_agents.defaults.SystemDefaults`; on a ``gp_envs`` env started from its
    ``data_start`` state if it has one) plus Gaussian action noise; for a model without one
    (an env given its model by :func:`gp_envs.wrap`, say), actions drawn uniformly within the
    model's control bounds. By default the data come from the system that
    ``env.reset(seed=seed)`` gives: with a randomized truth (``randomize > 0``) or a redrawn
    nominal model, the episode you then run with ``env.reset(seed=seed)`` is on the same system
    the data came from (every data episode after the first resets with ``options=
    {"keep_system": True}`` on a ``gp_envs`` env, and without a seed, continuing the env's own
    random stream, on any other). In a time-varying scenario the data episodes see its changes
    as any episode does; make the data env with ``time_varying=False`` for data from before
    them.

    Args:
        env: an env with a nominal model (:func:`gp_envs.nominal_model`); it is reset here.
        n_points: number of transitions to collect (episodes are restarted as needed).
        seed: seeds the env resets, the reference and the action noise.
        action_noise: standard deviation of Gaussian action noise added to a tracking
            controller or ``policy``, as a fraction of the action range (not added to the
            uniform random actions).
        same_system: False: each data episode is an ordinary reset with seed
            ``seed * 1000 + k``, so on a randomized env the data come from *other* systems
            than the episode of ``seed`` (data from other draws, on purpose).
        policy: your own data controller ``policy(obs, t) -> u`` (observation (n,), seconds
            since the episode's start, control (m,)); None: the default above.

    Returns:
        The transitions, ``len == n_points``.

    Raises:
        ValueError: ``n_points < 1``; a negative or non-finite ``action_noise``.
        TypeError: an env without a nominal model; ``policy`` not callable.
    """
    model = nominal_model(env)
    if isinstance(n_points, bool) or int(n_points) < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    if not (np.isfinite(action_noise) and action_noise >= 0):
        raise ValueError(f"action_noise must be a finite number >= 0, got {action_noise}")
    if policy is not None and not callable(policy):
        raise TypeError(f"policy must be a function policy(obs, t) -> u, got "
                        f"{type(policy).__name__}")
    defaults = system_defaults(model)
    n_points = int(n_points)
    rng = np.random.default_rng(seed)
    if same_system:
        env.reset(seed=seed)  # draws the system that the episode of this seed runs on
    X, U, Xn = [], [], []
    episode = 0
    while sum(len(x) for x in X) < n_points:
        options: dict[str, Any] = {}
        if defaults.data_start is not None and isinstance(env.unwrapped, GPEnv):
            options["state"] = np.array(defaults.data_start)
        if same_system and isinstance(env.unwrapped, GPEnv):
            options["keep_system"] = True
        if policy is not None:
            agent: _DataAgent = _NoisyTracker(env, rng, action_noise, lambda m, r: policy)
        elif defaults.data_policy is not None:
            agent = _NoisyTracker(env, rng, action_noise, defaults.data_policy)
        else:
            agent = _UniformActions(env, rng)
        run = rollout(env, agent, None if same_system else seed * 1000 + episode,
                      options=options or None, max_steps=n_points - sum(len(x) for x in X))
        X.append(run.observations[:-1])
        U.append(run.actions.astype(np.float32).astype(float))
        Xn.append(run.observations[1:])
        episode += 1
    return Transitions(np.concatenate(X), np.concatenate(U), np.concatenate(Xn))


class _DataAgent:
    """A data controller as an :class:`gp_agents.agent.Agent` (it does not learn)."""

    def __init__(self, env: gym.Env, rng: np.random.Generator) -> None:
        self.env, self.rng = env, rng
        self.low, self.high = env.action_space.low, env.action_space.high

    def reset(self) -> None:
        """Nothing to forget."""

    def act(self, obs: np.ndarray) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """A data controller does not learn."""


class _NoisyTracker(_DataAgent):
    """A tracking controller (built per episode by ``make(model, rng)``, for the episode's
    nominal model) plus Gaussian action noise."""

    def __init__(self, env: gym.Env, rng: np.random.Generator, noise: float,
                 make: DataPolicy) -> None:
        super().__init__(env, rng)
        self.span = self.high - self.low
        self.noise, self.make = noise, make

    def reset(self) -> None:
        model: ControlModel = nominal_model(self.env)
        self.policy = self.make(model, self.rng)
        self.dt, self.t = model.dt, 0.0

    def act(self, obs: np.ndarray) -> np.ndarray:
        action = np.asarray(self.policy(np.asarray(obs, float), self.t), float)
        if action.shape != self.span.shape or not np.all(np.isfinite(action)):
            raise ValueError(f"the data policy must return {self.span.shape} finite controls, "
                             f"got {action!r}")
        action = action + self.noise * self.span * self.rng.normal(size=self.span.shape)
        self.t += self.dt
        return np.clip(action, self.low, self.high).astype(np.float32)


class _UniformActions(_DataAgent):
    """Actions drawn uniformly within the action space (the model's control bounds)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.rng.uniform(self.low, self.high).astype(np.float32)
