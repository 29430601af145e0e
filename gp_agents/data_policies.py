"""The built-in systems' initial-data controllers (the paper's "crude feedback controller").

A data policy is a function of the episode's *nominal* model and a seeded RNG that returns a
feedback law ``u = policy(obs, t)`` (observation (n,), seconds since the episode's start,
control (m,)): :func:`gp_agents.data.collect_initial_data` builds one per data episode (its
reference phases and amplitudes drawn from the RNG) and adds the action noise. They use the
nominal model only (gains, hover thrust), never the truth. Each is registered with its system's
controller defaults (:mod:`gp_agents.defaults`), by the system's name.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gp_envs.model import ControlModel

__all__ = ["DataPolicy", "Policy", "cartpole_data_policy", "dubins_data_policy",
           "pendulum_data_policy", "pilco_cartpole_data_policy", "quadrotor_data_policy"]

Policy = Callable[[np.ndarray, float], np.ndarray]
"""A feedback law ``u = policy(obs, t)``: observation (n,), time in seconds, action (m,)."""
DataPolicy = Callable[[ControlModel, np.random.Generator], Policy]
"""Builds one episode's initial-data controller from the episode's nominal model and an RNG
(reference phases and amplitudes are drawn from it)."""




def cartpole_data_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    """Crude initial-data controller (paper: "a sinusoidal desired trajectory from a crude
    feedback controller"): PD control of the cart onto a sinusoid of drawn amplitude (0.4-0.8
    m), frequency (2-4 rad/s) and phase; uses no model parameter."""
    amp = rng.uniform(0.4, 0.8)          # m
    omega = rng.uniform(2.0, 4.0)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)
    kp, kd = 20.0, 5.0                   # N/m, N s/m on the cart

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        ref = amp * np.sin(omega * t + phase)
        return np.array([kp * (ref - obs[0]) - kd * obs[2]])

    return policy


def quadrotor_data_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    """Crude initial-data controller (paper: "flying in circles", level in z): a cascade of
    PD position control onto a circle of drawn radius (0.3-0.6 m), rate (1-2 rad/s) and phase
    through the env's first position, a small-attitude inversion of the *nominal* model at
    ``psi = 0`` and PD attitude control; uses the nominal mass, inertias and arm length."""
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


def dubins_data_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    """Crude initial-data controller: P control of the heading onto a sinusoid of drawn
    amplitude (0.5-1 rad), frequency (0.4-0.8 rad/s) and phase, at a speed command varying
    around 1 m/s; uses no model parameter."""
    amp = rng.uniform(0.5, 1.0)          # rad
    omega = rng.uniform(0.4, 0.8)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        heading_ref = amp * np.sin(omega * t + phase)
        err = np.arctan2(np.sin(heading_ref - obs[2]), np.cos(heading_ref - obs[2]))
        return np.array([1.0 + 0.5 * np.sin(1.3 * omega * t), 2.0 * err])

    return policy


def pendulum_data_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    """Crude initial-data controller: PD control of the angle onto a sinusoid around hanging
    of drawn amplitude (0.5-1.5 rad), frequency (2-5 rad/s) and phase, saturated by the
    env's torque bound; uses no model parameter."""
    amp = rng.uniform(0.5, 1.5)          # rad
    omega = rng.uniform(2.0, 5.0)        # rad/s
    phase = rng.uniform(0, 2 * np.pi)
    kp, kd = 4.0, 0.4                    # N m/rad, N m s/rad

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        ref = amp * np.sin(omega * t + phase)
        err = np.arctan2(np.sin(ref - obs[0]), np.cos(ref - obs[0]))
        return np.array([kp * err - kd * obs[1]])

    return policy


def pilco_cartpole_data_policy(model: ControlModel, rng: np.random.Generator) -> Policy:
    """PILCO's initial random trial: a force drawn uniformly from the model's control bounds at
    every call (``rollout.m`` without a policy function: ``maxU .* (2 rand - 1)``)."""
    low, high = np.asarray(model.u_lb, float), np.asarray(model.u_ub, float)

    def policy(obs: np.ndarray, t: float) -> np.ndarray:
        return rng.uniform(low, high)

    return policy
