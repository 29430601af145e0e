"""The RL comparison: the shipped stable-baselines3 SAC policy and the robust MPC on the same
seeds, through the same ``act(obs)`` interface (needs the ``rl`` extra).

Run: ``python examples/rl_comparison.py`` (``GP_EXAMPLES_SMOKE=1``: one seed, 40 steps)
"""

import os

import gymnasium as gym

import gp_envs  # noqa: F401
from benchmarks.controllers import MODELS_DIR
from gp_agents import collect_initial_data, make_mpc, rollout
from gp_agents.rl import RLAgent

smoke = os.environ.get("GP_EXAMPLES_SMOKE") == "1"
seeds = [0] if smoke else [0, 1, 2, 3, 4]
max_steps = 40 if smoke else None

env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
sac = RLAgent.load("cartpole/sac", env, search=[MODELS_DIR])
print(f"SAC trained for {sac.training_steps} env steps")
for seed in seeds:
    mpc = make_mpc(env).pretrain(collect_initial_data(env, 200, seed=seed))
    results = {name: rollout(env, agent, seed, max_steps=max_steps)
               for name, agent in (("robust MPC", mpc), ("SAC", sac))}
    print(f"seed {seed}: " + "  ".join(
        f"{name} {'ok  ' if ep.final_info['success'] else 'miss'} cost {ep.cost:6.2f}"
        for name, ep in results.items()))
