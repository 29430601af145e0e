"""The interface every controller of this package has, and the one closed loop that runs it.

An :class:`Agent` is anything with ``reset()``, ``act(obs)`` and ``observe(obs, action,
next_obs)``: the pseudospectral MPC, the RL policies, the peer library's MPC in the benchmarks.
:func:`rollout` is the episode loop that the README, the tests and the benchmarks all use::

    episode = rollout(env, agent, seed=0)
    episode.success, episode.cost, episode.act_times.mean()
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

__all__ = ["Agent", "Episode", "rollout", "rollout_lockstep"]


@runtime_checkable
class Agent(Protocol):
    """A controller of a Gymnasium env, in the closed loop of :func:`rollout`."""

    def reset(self) -> None:
        """Start a new episode (called right after ``env.reset``)."""
        ...

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The action for an observation: (n,) -> (m,) inside the env's action space."""
        ...

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """The transition the last action caused (learning agents learn from it)."""
        ...


@dataclass
class Episode:
    """One closed-loop episode.

    Attributes:
        observations: (T + 1, n) from the reset's observation to the last one.
        actions: (T, m) actions as the agent returned them.
        rewards: (T,) rewards.
        infos: the T step infos.
        act_times: (T,) wall-clock seconds of each ``agent.act`` (the only load-dependent
            field).
        terminated: the episode ended by the env (state box, obstacle), not by time.
        truncated: the env's time limit ended it (neither flag: ``max_steps`` did).
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    infos: list[dict[str, Any]] = field(repr=False)
    act_times: np.ndarray = field(repr=False)
    terminated: bool = False
    truncated: bool = False

    @property
    def steps(self) -> int:
        """T, env steps taken."""
        return int(self.rewards.size)

    @property
    def cost(self) -> float:
        """Minus the return: the task's cost (``gp_envs`` rewards are minus the stage cost)."""
        return -float(np.sum(self.rewards))

    @property
    def final_info(self) -> dict[str, Any]:
        """The last step's info (empty if no step was taken)."""
        return self.infos[-1] if self.infos else {}

    @property
    def success(self) -> bool:
        """``info["success"]`` at the last step (the env's held-at-the-goal criterion)."""
        return bool(self.final_info.get("success", False))

    def summary(self) -> dict[str, Any]:
        """The episode in a few numbers, as the RL tooling records them: ``return`` (sum of
        rewards), ``success`` (``info["is_success"]`` at the last step, the key SB3 reads),
        ``success_any`` (``info["is_success"]`` at some step), ``length`` (steps),
        ``final_distance`` (``info["distance_to_goal"]`` at the end, in the task's units; NaN
        without it) and ``end`` (the termination reason, or ``"time limit"``)."""
        info = self.final_info
        return {"return": float(np.sum(self.rewards)),
                "success": bool(info.get("is_success", False)),
                "success_any": any(bool(i.get("is_success", False)) for i in self.infos),
                "length": self.steps,
                "final_distance": float(info.get("distance_to_goal", np.nan)),
                "end": info.get("termination_reason") or "time limit"}


def rollout(env: gym.Env, agent: Agent, seed: int | None = None, *,
            options: dict[str, Any] | None = None, max_steps: int | None = None) -> Episode:
    """Run ``agent`` on ``env`` for one episode: reset both, then act, step, observe.

    Args:
        env: a Gymnasium env (``gym.make``: its TimeLimit ends the episode).
        agent: an :class:`Agent`.
        seed: ``env.reset`` seed.
        options: ``env.reset`` options.
        max_steps: stop after this many steps (None: until terminated or truncated).

    Returns:
        The :class:`Episode`.

    Raises:
        ValueError: ``max_steps`` < 1.
    """
    return rollout_lockstep([(env, agent)], seed, options=options, max_steps=max_steps)[0]


def rollout_lockstep(pairs: list[tuple[gym.Env, Agent]], seed: int | None = None, *,
                     options: dict[str, Any] | None = None, max_steps: int | None = None
                     ) -> list[Episode]:
    """:func:`rollout` of several (env, agent) pairs, one step of each in turn.

    For timing comparisons on a shared machine: the agents' ``act`` calls interleave, so a
    change in the machine's load affects them alike. Each pair's episode is exactly what
    :func:`rollout` gives it alone (the pairs share nothing but the seed).
    """
    if max_steps is not None and max_steps < 1:
        raise ValueError(f"max_steps must be >= 1 or None, got {max_steps}")
    loops = [_episode_steps(env, agent, seed, options, max_steps) for env, agent in pairs]
    episodes: list[Episode | None] = [None] * len(loops)
    while any(e is None for e in episodes):
        for i, loop in enumerate(loops):
            if episodes[i] is None:
                episodes[i] = next(loop)
    return [e for e in episodes if e is not None]


def _episode_steps(env: gym.Env, agent: Agent, seed: int | None,
                   options: dict[str, Any] | None, max_steps: int | None
                   ) -> Iterator[Episode | None]:
    """The closed loop, one step per ``next``: yields None after each step, the
    :class:`Episode` after the last."""
    obs, _ = env.reset(seed=seed, options=options)
    agent.reset()
    observations, actions, rewards, infos, times = [np.asarray(obs, float)], [], [], [], []
    terminated = truncated = False
    while True:
        start = time.perf_counter()
        action = agent.act(obs)
        times.append(time.perf_counter() - start)
        next_obs, reward, terminated, truncated, info = env.step(action)
        agent.observe(obs, action, next_obs)
        observations.append(np.asarray(next_obs, float))
        actions.append(np.asarray(action, float).ravel())
        rewards.append(float(reward))
        infos.append(info)
        obs = next_obs
        if terminated or truncated or (max_steps is not None and len(rewards) >= max_steps):
            break
        yield None
    yield Episode(np.array(observations), np.array(actions), np.array(rewards), infos,
                  np.array(times), bool(terminated), bool(truncated))
