"""Alias of :mod:`benchmarks.rl.train`: ``python -m benchmarks.train_rl`` keeps working."""

from benchmarks.rl.train import *  # noqa: F403
from benchmarks.rl.train import main

if __name__ == "__main__":
    raise SystemExit(main())
