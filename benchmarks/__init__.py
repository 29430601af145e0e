"""Benchmarks: compare controllers on the ``gp_envs`` environments through ``gym.make``.

Importing this package sets ``OMP_NUM_THREADS=1`` unless the caller set it: the thread count
of the BLAS that NumPy loads is fixed when NumPy is first imported, and it changes the last
bits of the learners' linear algebra, which a marginal closed loop (a cart-pole swing-up)
can amplify into a different outcome. Benchmarks time single-threaded, and spawned worker
processes inherit the setting.
"""

import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

USER_MODELS_DIR = Path("benchmarks") / "models"
"""The user's RL model directory, relative to the current directory: ``python -m
benchmarks.rl.train`` saves ``<env>/<algo>/`` there by default, and ``gp-bench`` looks there for
RL models (unless given ``--models DIR``) before the shipped ones; in a checkout's root it is
the shipped directory itself."""
