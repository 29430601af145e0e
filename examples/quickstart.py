"""Quickstart: the recommended controller on the cart-pole swing-up, in a few lines.

Run: ``python examples/quickstart.py``
"""

import gymnasium as gym

import gp_envs  # noqa: F401  (registers the environments)
from gp_agents import collect_initial_data, make_mpc, rollout

env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
data = collect_initial_data(env, n_points=200, seed=0)  # on the system env.reset(seed=0) gives
agent = make_mpc(env).pretrain(data)  # the "robust" recipe: nominal physics + learned residual
episode = rollout(env, agent, seed=0)

print(f"success: {episode.final_info['success']}, cost: {episode.cost:.2f}, "
      f"steps: {episode.steps}, learner samples: {agent.learner.n_samples_seen_}")
