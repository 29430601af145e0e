"""Benchmarks: compare controllers on the ``gp_envs`` environments through ``gym.make``.

Importing this package sets ``OMP_NUM_THREADS=1`` unless the caller set it: the thread count
of the BLAS that NumPy loads is fixed when NumPy is first imported, and it changes the last
bits of the learners' linear algebra, which a marginal closed loop (a cart-pole swing-up)
can amplify into a different outcome. Benchmarks time single-threaded, and spawned worker
processes inherit the setting.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
