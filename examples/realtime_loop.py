"""A real-time loop: the real-time iteration split into a feedback phase (the QP with the
measured state, the latency) and a preparation phase (after the action is sent: the learner
update and the next QP's data), with the episode's health counts.

Run: ``python examples/realtime_loop.py`` (``GP_EXAMPLES_SMOKE=1``: 30 steps)
"""

import os
import warnings

import gymnasium as gym
import numpy as np

import gp_envs  # noqa: F401
from gp_agents import ControllerDegradedWarning, collect_initial_data, make_mpc

steps = 30 if os.environ.get("GP_EXAMPLES_SMOKE") == "1" else 120
env = gym.make("gp_envs/Quadrotor-v0", scenario="online")
agent = make_mpc(env, "robust", scheme="rti-split")
agent.pretrain(collect_initial_data(env, 200, seed=0))

obs, _ = env.reset(seed=0)
agent.reset()
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always", ControllerDegradedWarning)
    for _ in range(steps):
        action = agent.act(obs)  # feedback, then preparation of the next step
        next_obs, reward, terminated, truncated, info = env.step(action)
        agent.observe(obs, action, next_obs)
        obs = next_obs
        if terminated or truncated:
            break

d = agent.diagnostics_arrays()
latency = d["act_time"] - d["preparation_time"]
print(f"median latency {1e3 * np.median(latency[1:]):.2f} ms, "
      f"median preparation {1e3 * np.median(d['preparation_time'][1:]):.2f} ms")
print("health:", agent.health())
print("degradation warnings:", len(caught))
