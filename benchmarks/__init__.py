"""Benchmarks: compare controllers on the ``gp_envs`` environments through ``gym.make``."""
