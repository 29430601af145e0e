"""One registration per system: its name and its Gymnasium env.

A *system* is registered once, by :func:`register_system`, next to its env class (the last
lines of each env module). That call registers the Gymnasium id (``gym.make(system.env_id)``)
under the system's name, which is the name of the env's model
(:attr:`gp_envs.model.ControlModel.name`). Nothing here knows a controller or a benchmark: the
controllers keep their defaults for a system (time scales, a data controller) in
:mod:`gp_agents.defaults` and the benchmark its scenarios to sweep in :mod:`benchmarks.systems`,
both by this name. A system of your own::

    from gp_envs.systems import System, register_system

    register_system(System(name="mysystem", env_id="mypkg/MySystem-v0",
                           entry_point="mypkg.env:MySystemEnv", max_episode_steps=100))

The built-in systems are registered when :mod:`gp_envs` is imported, and so are the systems of
installed packages that declare an entry point in the group ``gp_envs.systems`` (the module
that calls :func:`register_system`), e.g. in the package's ``pyproject.toml``::

    [project.entry-points."gp_envs.systems"]
    mysystem = "mypkg.env"

so that every process that imports :mod:`gp_envs` knows them -- the benchmark's spawned worker
processes included, which a registration in a script's ``__main__`` does not reach
(``docs/guide/own-system.md``; ``tests/test_own_system.py`` does all of it with a small
system).
"""

from __future__ import annotations

import importlib
import importlib.metadata
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from gymnasium.envs.registration import register, registry


@dataclass(frozen=True)
class System:
    """A registered system (see the module docstring).

    Attributes:
        name: short name, the ``name`` of the env's :class:`~gp_envs.model.ControlModel`
            (e.g. ``"cartpole"``); the benchmark's ``--envs`` name and the key the controllers'
            defaults are kept under.
        env_id: Gymnasium id, e.g. ``"gp_envs/CartPoleSwingUp-v0"``.
        entry_point: ``"module:Class"`` of the env (a :class:`gp_envs.base.GPEnv` subclass).
        max_episode_steps: Gymnasium's time limit (the task's duration over the control period).
    """

    name: str
    env_id: str
    entry_point: str
    max_episode_steps: int

    def env_class(self) -> type:
        """The env class named by :attr:`entry_point` (imported on first use)."""
        module, _, attr = self.entry_point.partition(":")
        return getattr(importlib.import_module(module), attr)

    @property
    def scenarios(self) -> tuple[str, ...]:
        """The env's scenarios."""
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
        ValueError: another system already has that name or env id; the env class's model is
            not named :attr:`System.name`; its physics module without ``STATE_UNITS`` /
            ``CONTROL_UNITS`` matching its names; ``max_episode_steps < 1``.
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
    model_name = cls.model_name() if hasattr(cls, "model_name") else None
    if model_name != system.name:
        raise ValueError(f"system {system.name!r}: its env {system.entry_point} names its "
                         f"model {model_name!r}; the names must match (the controllers find "
                         f"a model's defaults by the model's name)")
    for names, units in (("STATE_NAMES", "STATE_UNITS"), ("CONTROL_NAMES", "CONTROL_UNITS")):
        if len(getattr(physics, units, ())) != len(getattr(physics, names)):
            raise ValueError(f"system {system.name!r}: its physics module needs {units}, one "
                             f"unit string per entry of {names} (for plots and docs)")
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


def load_system_plugins(group: str = ENTRY_POINT_GROUP) -> list[str]:
    """Import every module declared in the entry-point group ``group`` (each registers its
    systems, or its entries for them); returns the entry points' names. Called by ``import
    gp_envs`` for :data:`ENTRY_POINT_GROUP`; the layers above load their own groups the same
    way (``gp_agents.systems``: the controllers' defaults, ``benchmarks.systems``: the
    benchmark's entries), so that a plugin's module imports only the layer it registers with.

    A plugin that fails to import is skipped with a ``RuntimeWarning`` naming it and the error
    (the package itself stays usable); its systems are then unknown names.
    """
    loaded = []
    for entry in importlib.metadata.entry_points(group=group):
        try:
            entry.load()
        except Exception as err:  # any failure of a third-party module
            warnings.warn(f"{group}: plugin {entry.name!r} ({entry.value}) failed to load and "
                          f"is skipped: {type(err).__name__}: {err}", RuntimeWarning,
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
