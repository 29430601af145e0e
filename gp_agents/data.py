"""Initial training data: a crude feedback controller tracking a sinusoidal reference.

Paper, Results, "Cart Pole": "We generated 200 points of data using a sinusoidal desired
trajectory from a crude feedback controller"; for the quadrotor the reference was a circle in x-y
at constant height ("flying in circles", "remained level in the z direction"). The controllers
here use only the env's *nominal* model (gains, hover thrust), act through ``env.step`` on the
true plant, and are seeded (reference phase, amplitude and small action noise).

The data is the list of observed transitions ``(x_k, u_k, x_{k+1})``; see
:class:`gp_agents.residual.ResidualModel` for turning them into GP targets.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from gp_agents.agent import rollout
from gp_envs.model import ControlModel

Policy = Callable[[np.ndarray, float], np.ndarray]


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


def _cartpole_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    amp = rng.uniform(0.4, 0.8)          # m
    omega = rng.uniform(2.0, 4.0)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)
    kp, kd = 20.0, 5.0                   # N/m, N s/m on the cart

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        ref = amp * np.sin(omega * t + phase)
        return np.array([kp * (ref - obs[0]) - kd * obs[2]])

    return policy


def _quadrotor_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    p = model.params
    m, g, arm = p["m"], p["g"], p["L"]
    jx, jy, jz = p["Jx"], p["Jy"], p["Jz"]
    radius = rng.uniform(0.3, 0.6)       # m
    omega = rng.uniform(1.0, 2.0)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)
    center: list[np.ndarray] = []

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        if not center:
            center.append(obs[:3] - radius * np.array([np.cos(phase), np.sin(phase), 0.0]))
        c = center[0]
        ang = omega * t + phase
        ref = c + radius * np.array([np.cos(ang), np.sin(ang), 0.0])
        vref = radius * omega * np.array([-np.sin(ang), np.cos(ang), 0.0])
        acc = 4.0 * (ref - obs[:3]) + 3.0 * (vref - obs[6:9])          # m/s^2
        # small-attitude inversion of the paper's model at psi = 0: xdd ~ theta g, ydd ~ -phi g
        theta_des = np.clip(acc[0] / g, -0.3, 0.3)
        phi_des = np.clip(-acc[1] / g, -0.3, 0.3)
        thrust = m * (g - acc[2])                                        # N (NED: z down)
        tau_phi = jx * (100.0 * (phi_des - obs[3]) - 20.0 * obs[9])
        tau_theta = jy * (100.0 * (theta_des - obs[4]) - 20.0 * obs[10])
        tau_psi = jz * (25.0 * (0.0 - obs[5]) - 10.0 * obs[11])
        even = 0.5 * (thrust + tau_psi / (0.05 * arm))                   # F2 + F4
        odd = 0.5 * (thrust - tau_psi / (0.05 * arm))                    # F1 + F3
        return np.array([0.5 * (odd + tau_theta / arm), 0.5 * (even - tau_phi / arm),
                         0.5 * (odd - tau_theta / arm), 0.5 * (even + tau_phi / arm)])

    return policy


def _dubins_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    amp = rng.uniform(0.5, 1.0)          # rad
    omega = rng.uniform(0.4, 0.8)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        heading_ref = amp * np.sin(omega * t + phase)
        err = np.arctan2(np.sin(heading_ref - obs[2]), np.cos(heading_ref - obs[2]))
        return np.array([1.0 + 0.5 * np.sin(1.3 * omega * t), 2.0 * err])

    return policy


_POLICIES = {"cartpole": _cartpole_policy, "quadrotor": _quadrotor_policy,
             "dubins": _dubins_policy}
# Dubins data is gathered away from the obstacle: the actuator losses do not depend on position.
_START_STATES = {"dubins": np.array([-8.0, 6.0, 0.0])}


def collect_initial_data(env: gym.Env, n_points: int = 200, seed: int = 0,
                         action_noise: float = 0.05) -> Transitions:
    """Roll out the crude sinusoid-tracking controller of ``env``'s system on ``env``.

    Args:
        env: a ``gp_envs`` environment (made with ``gym.make``); it is reset here.
        n_points: number of transitions to collect (episodes are restarted as needed).
        seed: seeds the env resets, the reference and the action noise.
        action_noise: standard deviation of Gaussian action noise, as a fraction of the action
            range.

    Returns:
        The transitions, ``len == n_points``.

    Raises:
        ValueError: for an env of an unknown system or ``n_points < 1``.
    """
    model: ControlModel = env.unwrapped.nominal_model
    if model.name not in _POLICIES:
        raise ValueError(f"no initial-data controller for system {model.name!r}; "
                         f"known: {sorted(_POLICIES)}")
    if n_points < 1:
        raise ValueError(f"n_points must be >= 1, got {n_points}")
    rng = np.random.default_rng(seed)
    X, U, Xn = [], [], []
    episode = 0
    while sum(len(x) for x in X) < n_points:
        options = {"state": _START_STATES[model.name]} if model.name in _START_STATES else None
        agent = _NoisyTracker(env, rng, action_noise)
        run = rollout(env, agent, seed * 1000 + episode, options=options,
                      max_steps=n_points - sum(len(x) for x in X))
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
        model = self.env.unwrapped.nominal_model
        self.policy, self.dt, self.t = _POLICIES[model.name](model, self.rng), model.dt, 0.0

    def act(self, obs: np.ndarray) -> np.ndarray:
        action = self.policy(np.asarray(obs, float), self.t) + self.noise * self.span * (
            self.rng.normal(size=self.span.shape))
        self.t += self.dt
        return np.clip(action, self.env.action_space.low,
                       self.env.action_space.high).astype(np.float32)

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """The tracker does not learn."""
