"""Your own system in Python: import its env module (which registers it), then every recipe
works on it. To use it from the command line too (``gp-bench --envs puck``, ``python -m
benchmarks.train_rl --env puck``), install it: ``pip install -e examples/own_system``.

Run: ``python examples/own_system/run.py``
"""

import sys
from pathlib import Path

import gymnasium as gym

sys.path.insert(0, str(Path(__file__).resolve().parent))  # not needed once installed
import gp_puck.control  # its controller defaults (registered on import)
import gp_puck.env  # noqa: F401  (registers the system "puck")

from gp_agents import collect_initial_data, make_mpc, rollout

env = gym.make("gp_puck/Puck-v0")
for recipe in ("nominal", "robust"):
    agent = make_mpc(env, recipe)
    if agent.learner is not None:
        agent.pretrain(collect_initial_data(env, 40, seed=0))
    episode = rollout(env, agent, seed=0)
    print(f"{recipe:8s} success {episode.final_info['success']}, cost {episode.cost:.3f}, "
          f"final position {episode.observations[-1][0]:.3f} m")
