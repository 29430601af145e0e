"""What the benchmark needs of a system beyond its env: scenarios to sweep, what to score.

Kept by the system's name (:attr:`gp_envs.ControlModel.name`), as the controllers keep their
defaults in :mod:`gp_agents.defaults`: the envs know nothing of the benchmark. A system with no
entry runs every scenario of its env, reports no position error and offers no perturbed start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gp_envs.systems import load_system_plugins

__all__ = ["BenchmarkSystem", "benchmark_system", "register_benchmark_system",
           "unregister_benchmark_system"]


@dataclass(frozen=True)
class BenchmarkSystem:
    """The benchmark's view of one system.

    Attributes:
        scenarios: scenarios the benchmark runs (None: every scenario of the env).
        position_dims: the first ``position_dims`` state components are a position in metres
            (the benchmark reports the final position error); 0: none is reported.
        perturbation: (n,) half-widths, in the states' units, of the uniform offset the
            benchmark adds to the env's start for a "perturbed start" (None: not offered).
    """

    scenarios: tuple[str, ...] | None = None
    position_dims: int = 0
    perturbation: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if isinstance(self.position_dims, bool) or int(self.position_dims) < 0:
            raise ValueError(f"BenchmarkSystem: position_dims must be an int >= 0, got "
                             f"{self.position_dims!r}")
        if self.perturbation is not None:
            width = tuple(float(w) for w in self.perturbation)
            if not all(np.isfinite(w) and w >= 0 for w in width):
                raise ValueError(f"BenchmarkSystem: perturbation widths must be finite and "
                                 f">= 0, got {self.perturbation}")
            object.__setattr__(self, "perturbation", width)


_SYSTEMS: dict[str, BenchmarkSystem] = {
    "cartpole": BenchmarkSystem(perturbation=(0.5, 0.3, 0.1, 0.1)),
    "quadrotor": BenchmarkSystem(
        position_dims=3,
        perturbation=(0.3, 0.3, 0.3, 0.05, 0.05, 0.05, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1)),
    "dubins": BenchmarkSystem(position_dims=2, perturbation=(0.5, 0.5, 0.3)),
    "pendulum": BenchmarkSystem(perturbation=(0.3, 0.3)),
}


def register_benchmark_system(name: str, system: BenchmarkSystem) -> BenchmarkSystem:
    """Register (or replace) the benchmark's entry of the system ``name``; returns it.

    Raises:
        TypeError: ``system`` is not a :class:`BenchmarkSystem`.
    """
    if not isinstance(system, BenchmarkSystem):
        raise TypeError(f"system must be a BenchmarkSystem, got {type(system).__name__}")
    _SYSTEMS[str(name)] = system
    return system


def unregister_benchmark_system(name: str) -> BenchmarkSystem | None:
    """Remove the benchmark's entry of ``name``; returns it (None: there was none)."""
    return _SYSTEMS.pop(name, None)


def benchmark_system(name: str) -> BenchmarkSystem:
    """The benchmark's entry of the system ``name`` (an empty one for a system without)."""
    return _SYSTEMS.get(name, BenchmarkSystem())


PLUGIN_GROUP = "benchmarks.systems"
"""Entry-point group of installed packages' modules that register benchmark entries
(:func:`register_benchmark_system`) for their systems; loaded when this module is imported."""
load_system_plugins(PLUGIN_GROUP)
