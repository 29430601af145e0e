"""Randomized truth: every reset draws new true parameters (within +-10%), hidden from the
controller; the robust recipe against the nominal-physics MPC and the oracle on a few seeds.

Run: ``python examples/randomized_truth.py`` (``GP_EXAMPLES_SMOKE=1``: one seed, 40 steps)
"""

import os

import gymnasium as gym

import gp_envs  # noqa: F401
from gp_agents import collect_initial_data, make_mpc, rollout

smoke = os.environ.get("GP_EXAMPLES_SMOKE") == "1"
seeds = [0] if smoke else [0, 1, 2]
max_steps = 40 if smoke else None

env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online", randomize=0.1)
for seed in seeds:
    line = [f"seed {seed}:"]
    for recipe in ("nominal", "robust", "oracle"):
        agent = make_mpc(env, recipe)
        if agent.learner is not None:
            agent.pretrain(collect_initial_data(env, 200, seed=seed))
        episode = rollout(env, agent, seed, max_steps=max_steps)
        line.append(f"{recipe} {'ok  ' if episode.final_info['success'] else 'miss'} "
                    f"cost {episode.cost:6.2f}")
    print("  ".join(line))
