"""Changing one piece: the controller's settings objects. Each option lives on the object it
configures; a setting that does not apply to the combination raises instead of being ignored.

Run: ``python examples/custom_settings.py``
"""

import gymnasium as gym

import gp_envs  # noqa: F401
from gp_agents import (
    RTI,
    Constraints,
    PseudospectralMPC,
    RecedingHorizon,
    Residual,
    make_mpc,
    online_ssgp,
)

env = gym.make("gp_envs/DubinsObstacle-v0")

# a recipe with one override: a longer horizon with more nodes
agent = make_mpc(env, "robust", horizon=RecedingHorizon(horizon=5.0, n_nodes=14))
print(agent.config.horizon)

# the full form: the paper's learner in a split real-time iteration with a wider obstacle margin
agent = PseudospectralMPC.from_env(
    env, online_ssgp(n_frequencies=30),
    scheme=RTI(split=True, levenberg_marquardt=0.02),
    term="linearized",
    residual=Residual(learn_online=True),
    constraints=Constraints(obstacle_margin=0.2),
)
print(agent.config.scheme)

# a setting that does not apply is an error, not a silent no-op
cartpole = gym.make("gp_envs/CartPoleSwingUp-v0")
try:
    PseudospectralMPC.from_env(cartpole, constraints=Constraints(obstacle_margin=0.3))
except ValueError as err:
    print("ValueError:", err)
