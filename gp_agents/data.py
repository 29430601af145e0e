"""Initial training data: a crude feedback controller tracking a sinusoidal reference.

Paper, Results, "Cart Pole": "We generated 200 points of data using a sinusoidal desired
trajectory from a crude feedback controller"; for the quadrotor the reference was a circle in x-y
at constant height ("flying in circles", "remained level in the z direction"). The controllers
(each system's registered ``data_policy``, :mod:`gp_envs.systems`, written in its env module)
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
from gp_envs.model import ControlModel
from gp_envs.systems import system_of


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
                         action_noise: float = 0.05, *, same_system: bool = True
                         ) -> Transitions:
    """Roll out the crude sinusoid-tracking controller of ``env``'s system on ``env``.

    The controller is the system's registered :attr:`gp_envs.systems.System.data_policy`,
    started from its ``data_start`` state if it has one. By default the data come from the
    system that ``env.reset(seed=seed)`` gives: with a randomized truth (``randomize > 0``) or a
    redrawn nominal model, the episode you then run with ``env.reset(seed=seed)`` is on the
    same system the data came from (every data episode after the first resets with
    ``options={"keep_system": True}``). In a time-varying scenario the data episodes see its
    changes as any episode does; make the data env with ``time_varying=False`` for data from
    before them.

    Args:
        env: a ``gp_envs`` environment (made with ``gym.make``); it is reset here.
        n_points: number of transitions to collect (episodes are restarted as needed).
        seed: seeds the env resets, the reference and the action noise.
        action_noise: standard deviation of Gaussian action noise, as a fraction of the action
            range.
        same_system: False: each data episode is an ordinary reset with seed
            ``seed * 1000 + k``, so on a randomized env the data come from *other* systems
            than the episode of ``seed`` (data from other draws, on purpose).

    Returns:
        The transitions, ``len == n_points``.

    Raises:
        ValueError: for an env of an unknown system or ``n_points < 1``.
    """
    system = system_of(env)
    if isinstance(n_points, bool) or int(n_points) < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    n_points = int(n_points)
    rng = np.random.default_rng(seed)
    if same_system:
        env.reset(seed=seed)  # draws the system that the episode of this seed runs on
    X, U, Xn = [], [], []
    episode = 0
    while sum(len(x) for x in X) < n_points:
        options: dict[str, Any] = {} if system.data_start is None else {
            "state": np.array(system.data_start)}
        if same_system:
            options["keep_system"] = True
        agent = _NoisyTracker(env, rng, action_noise)
        run = rollout(env, agent, None if same_system else seed * 1000 + episode,
                      options=options or None, max_steps=n_points - sum(len(x) for x in X))
        X.append(run.observations[:-1])
        U.append(run.actions.astype(np.float32).astype(float))
        Xn.append(run.observations[1:])
        episode += 1
    return Transitions(np.concatenate(X), np.concatenate(U), np.concatenate(Xn))


class _NoisyTracker:
    """The system's crude tracking controller plus Gaussian action noise, as an
    :class:`gp_agents.agent.Agent`; its reference is drawn at each reset, for the episode's
    nominal model."""

    def __init__(self, env: gym.Env, rng: np.random.Generator, noise: float) -> None:
        self.env, self.rng = env, rng
        self.span = env.action_space.high - env.action_space.low
        self.noise = noise

    def reset(self) -> None:
        model: ControlModel = self.env.unwrapped.nominal_model
        self.policy = system_of(model).data_policy(model, self.rng)
        self.dt, self.t = model.dt, 0.0

    def act(self, obs: np.ndarray) -> np.ndarray:
        action = self.policy(np.asarray(obs, float), self.t) + self.noise * self.span * (
            self.rng.normal(size=self.span.shape))
        self.t += self.dt
        return np.clip(action, self.env.action_space.low,
                       self.env.action_space.high).astype(np.float32)

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """The tracker does not learn."""
