"""One registration per system: the env, its controllers' defaults and its benchmark entry.

A *system* is registered once, by :func:`register_system`, next to its env class (the last
lines of each env module). That one call

- registers the Gymnasium id (``gym.make(system.env_id)``),
- gives model-based controllers the system's time scales (:class:`PlanningDefaults`: horizon and
  resolution, read by :meth:`gp_agents.PseudospectralMPC.from_env`),
- gives the learning controllers their initial-data controller (:attr:`System.data_policy`,
  read by :func:`gp_agents.data.collect_initial_data`), and
- makes the system a benchmark env (``python -m benchmarks --envs NAME``).

Everything else about the system (physics, parameters and their valid ranges, state and action
bounds, the task) lives in its physics module and env class. A system of your own::

    from gp_envs.systems import PlanningDefaults, System, register_system

    register_system(System(
        name="mysystem",                      # = the physics module's name
        env_id="mypkg/MySystem-v0", entry_point="mypkg.env:MySystemEnv",
        max_episode_steps=100, planning=PlanningDefaults(horizon=1.0, n_nodes=10),
        data_policy=my_crude_controller))

The built-in systems are registered when :mod:`gp_envs` is imported, and so are the systems of
installed packages that declare an entry point in the group ``gp_envs.systems`` (the module
that calls :func:`register_system`), e.g. in the package's ``pyproject.toml``::

    [project.entry-points."gp_envs.systems"]
    mysystem = "mypkg.env"

so that every process that imports :mod:`gp_envs` knows them -- the benchmark's spawned worker
processes included, which a registration in a script's ``__main__`` does not reach. With the
package installed, ``python -m benchmarks.rl.train --env mysystem --algo sac`` trains an RL
baseline into ``./benchmarks/models/mysystem/sac`` and ``gp-bench --envs mysystem --controllers
nominal-mpc,sac`` compares it with the MPC (``docs/guide/own-system.md``;
``tests/test_own_system.py`` does all of it with a small system).

This module knows no controller: the defaults are plain numbers, the data policy a function of
the nominal model.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import warnings
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium.envs.registration import register, registry

if TYPE_CHECKING:
    from gp_envs.model import ControlModel

Policy = Callable[[np.ndarray, float], np.ndarray]
"""A feedback law ``u = policy(obs, t)``: observation (n,), time in seconds, action (m,)."""
DataPolicy = Callable[["ControlModel", np.random.Generator], Policy]
"""Builds one episode's initial-data controller from the episode's nominal model and an RNG
(reference phases and amplitudes are drawn from it)."""


@dataclass(frozen=True)
class PlanningDefaults:
    """A system's time scales for a model-based controller: how far ahead to look and how finely
    (what the system's author measured works). Solver tuning (QP solvers, regularization, how a
    learned term enters a real-time iteration) is the controller's business and is registered
    with the controller (``gp_agents.mpc.tuning``), not here.

    Attributes:
        horizon: receding horizon, seconds.
        n_nodes: Legendre-Gauss nodes per interval of the polynomial part of the horizon.
        n_intervals: intervals of the polynomial part (after the held control periods).
        nodes_per_period: LG nodes in each held control period of an episodic plan.
    """

    horizon: float
    n_nodes: int
    n_intervals: int = 1
    nodes_per_period: int = 3

    def __post_init__(self) -> None:
        if not (np.isfinite(self.horizon) and self.horizon > 0):
            raise ValueError(f"PlanningDefaults: horizon must be a positive number of seconds, "
                             f"got {self.horizon!r}")
        for name in ("n_nodes", "n_intervals", "nodes_per_period"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"PlanningDefaults: {name} must be an integer >= 1, "
                                 f"got {value!r}")


@dataclass(frozen=True)
class System:
    """A registered system (see the module docstring).

    Attributes:
        name: short name, the ``name`` of the env's :class:`~gp_envs.model.ControlModel`
            (its physics module's name, e.g. ``"cartpole"``); the benchmark's ``--envs`` name.
        env_id: Gymnasium id, e.g. ``"gp_envs/CartPoleSwingUp-v0"``.
        entry_point: ``"module:Class"`` of the env (a :class:`gp_envs.base.GPEnv` subclass).
        max_episode_steps: Gymnasium's time limit (the task's duration over the control period).
        planning: default MPC settings.
        data_policy: the crude feedback controller that collects initial learning data; it may
            use the nominal model only.
        data_start: (n,) state the data episodes start from (None: the env's own reset).
        benchmark_scenarios: scenarios the benchmark runs (None: every scenario of the env).
        position_dims: the first ``position_dims`` state components are a position in metres
            (the benchmark reports the final position error); 0: none is reported.
        perturbation: (n,) half-widths, in the states' units, of the uniform offset the
            benchmark adds to the env's start for a "perturbed start" (None: not offered).
    """

    name: str
    env_id: str
    entry_point: str
    max_episode_steps: int
    planning: PlanningDefaults
    data_policy: DataPolicy
    data_start: tuple[float, ...] | None = None
    benchmark_scenarios: tuple[str, ...] | None = None
    position_dims: int = 0
    perturbation: tuple[float, ...] | None = None

    def env_class(self) -> type:
        """The env class named by :attr:`entry_point` (imported on first use)."""
        module, _, attr = self.entry_point.partition(":")
        return getattr(importlib.import_module(module), attr)

    @property
    def scenarios(self) -> tuple[str, ...]:
        """Scenarios the benchmark runs (:attr:`benchmark_scenarios` or all of the env's)."""
        if self.benchmark_scenarios is not None:
            return self.benchmark_scenarios
        return tuple(self.env_class().SCENARIOS)

    @property
    def default_scenario(self) -> str:
        """The env's default scenario."""
        return str(self.env_class().DEFAULT_SCENARIO)


_SYSTEMS: dict[str, System] = {}


def register_system(system: System) -> System:
    """Register ``system`` (its Gymnasium id included); returns it.

    Re-registering an identical system is a no-op (module reloads).

    Raises:
        ValueError: another system already has that name or env id; the env class's physics
            module is not named :attr:`System.name`; a benchmark scenario the env does not
            have; its physics module without ``STATE_UNITS`` / ``CONTROL_UNITS`` matching its
            names; ``max_episode_steps < 1``; ``position_dims`` outside ``[0, n]``; a
            ``data_start`` or ``perturbation`` of the wrong length.
    """
    old = _SYSTEMS.get(system.name)
    if old is not None:
        if old == system:
            return old
        raise ValueError(f"a system named {system.name!r} is already registered "
                         f"({old.env_id})")
    for other in _SYSTEMS.values():
        if other.env_id == system.env_id:
            raise ValueError(f"env id {system.env_id!r} is already registered by system "
                             f"{other.name!r}")
    if int(system.max_episode_steps) < 1:
        raise ValueError(f"{system.name}: max_episode_steps must be >= 1, "
                         f"got {system.max_episode_steps}")
    cls = system.env_class()
    physics = getattr(cls, "physics", None)
    model_name = getattr(physics, "__name__", "").rsplit(".", 1)[-1]
    if model_name != system.name:
        raise ValueError(f"system {system.name!r}: its env {system.entry_point} simulates "
                         f"physics module {model_name!r}; the names must match (the "
                         f"controllers find a model's system by the model's name)")
    unknown = sorted(set(system.benchmark_scenarios or ()) - set(cls.SCENARIOS))
    if unknown:
        raise ValueError(f"system {system.name!r}: benchmark scenario(s) {unknown} are not "
                         f"scenarios of {cls.__name__} ({sorted(cls.SCENARIOS)})")
    n = len(physics.STATE_NAMES)
    for names, units in (("STATE_NAMES", "STATE_UNITS"), ("CONTROL_NAMES", "CONTROL_UNITS")):
        if len(getattr(physics, units, ())) != len(getattr(physics, names)):
            raise ValueError(f"system {system.name!r}: its physics module needs {units}, one "
                             f"unit string per entry of {names} (for plots and docs)")
    if not 0 <= system.position_dims <= n:
        raise ValueError(f"system {system.name!r}: position_dims must be in [0, {n}], "
                         f"got {system.position_dims}")
    for field in ("data_start", "perturbation"):
        value = getattr(system, field)
        if value is not None and len(value) != n:
            raise ValueError(f"system {system.name!r}: {field} must have {n} components, "
                             f"got {len(value)}")
    if system.env_id not in registry:
        register(id=system.env_id, entry_point=system.entry_point,
                 max_episode_steps=int(system.max_episode_steps))
    _SYSTEMS[system.name] = system
    return system


def unregister_system(name: str) -> System:
    """Remove the system ``name`` and its Gymnasium id (e.g. after a test or in a notebook
    that redefines it); returns the removed system.

    Raises:
        ValueError: no system has that name.
    """
    system = get_system(name)
    del _SYSTEMS[name]
    registry.pop(system.env_id, None)
    return system


def get_system(name: str) -> System:
    """The registered system called ``name``.

    Raises:
        ValueError: no system has that name (the message lists the registered ones).
    """
    try:
        return _SYSTEMS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown system {name!r}; registered: {sorted(_SYSTEMS)}") from None


def system_of(obj: Any) -> System:
    """The registered system of an env (or a wrapper of one) or of a :class:`ControlModel`.

    Raises:
        ValueError: ``obj``'s system is not registered, or ``obj`` is neither.
    """
    model = getattr(getattr(obj, "unwrapped", None), "nominal_model", None)
    name = getattr(model if model is not None else obj, "name", None)
    if not isinstance(name, str):
        raise ValueError(f"system_of needs a gp_envs env or a ControlModel, got "
                         f"{type(obj).__name__}")
    return get_system(name)


ENTRY_POINT_GROUP = "gp_envs.systems"
"""Entry-point group of installed packages' system modules (see the module docstring)."""


def load_system_plugins() -> list[str]:
    """Import every module declared in the :data:`ENTRY_POINT_GROUP` entry-point group (each
    registers its systems); returns the entry points' names. Called by ``import gp_envs``.

    A plugin that fails to import is skipped with a ``RuntimeWarning`` naming it and the error
    (``gp_envs`` itself stays usable); its systems are then unknown names.
    """
    loaded = []
    for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            entry.load()
        except Exception as err:  # any failure of a third-party module
            warnings.warn(f"gp_envs: system plugin {entry.name!r} ({entry.value}) failed to "
                          f"load and is skipped: {type(err).__name__}: {err}", RuntimeWarning,
                          stacklevel=2)
            continue
        loaded.append(entry.name)
    return loaded


class _SystemsView(Mapping[str, System]):
    """Read-only, live view of the registered systems by name (registration order)."""

    def __getitem__(self, name: str) -> System:
        return _SYSTEMS[name]

    def __iter__(self) -> Iterator[str]:
        return iter(list(_SYSTEMS))

    def __len__(self) -> int:
        return len(_SYSTEMS)

    def __repr__(self) -> str:
        return f"SYSTEMS({list(_SYSTEMS)})"


SYSTEMS: Mapping[str, System] = _SystemsView()
"""Every registered system by name (live: a system registered later appears here)."""
