"""The controllers' defaults for the puck (the module the ``gp_agents.systems`` entry point
names): how far ahead the MPC looks, and the crude controller that collects initial data."""

import numpy as np

from gp_agents import PlanningDefaults, SystemDefaults, register_defaults


def data_policy(model, rng):
    """The initial-data controller: a PD law to a random target (nominal model only)."""
    target = rng.uniform(-1.0, 1.0)

    def policy(obs, t):
        return np.array([2.0 * (target - obs[0]) - obs[1]])

    return policy


register_defaults("puck", SystemDefaults(
    planning=PlanningDefaults(horizon=1.0, n_nodes=6, n_intervals=1, nodes_per_period=3),
    data_policy=data_policy))
