"""What a controller may know about a system: its dynamics, bounds and task.

A :class:`ControlModel` bundles one physical model (an ODE written once, in CasADi, in
:mod:`gp_envs.physics`) with a set of parameter values, the control period, the state and control
bounds and the task. The envs build one from their *true* parameters to simulate the plant and
expose another, built from the *nominal* parameters, as ``env.unwrapped.nominal_model``; both run
the same formula, so the env and a controller never hold two copies of the physics.

Numeric evaluation goes through compiled CasADi functions (``f``, ``step``); symbolic evaluation
(``f`` called with CasADi symbols, or :meth:`ControlModel.casadi_function`) gives expressions an
optimizer can differentiate.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import casadi as ca
import numpy as np

from gp_envs.physics.ranges import ParamRange, check_params

OdeFn = Callable[[ca.SX, ca.SX, ca.SX], ca.SX]
"""Signature of a physics module's ``ode(x, u, p)``: state (n,), control (m,), params (k,)."""

_V = TypeVar("_V")


class ReadOnlyMapping(Mapping[str, _V]):
    """An immutable ``str -> value`` mapping that, unlike ``types.MappingProxyType``, pickles.

    It holds its own copy of the items: changing the mapping it was built from changes nothing,
    and it has no method that changes it (item assignment raises ``TypeError``).
    """

    __slots__ = ("_items",)

    def __init__(self, items: Mapping[str, _V]) -> None:
        self._items: dict[str, _V] = dict(items)

    def __getitem__(self, key: str) -> _V:
        return self._items[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._items!r})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (type(self), (self._items,))


@dataclass(frozen=True)
class Obstacle:
    """A circular obstacle in the plane of the first two state components.

    Attributes:
        center: (2,) centre in metres.
        radius: radius in metres.
    """

    center: tuple[float, float]
    radius: float

    def clearance(self, position: np.ndarray, body_radius: float = 0.0) -> np.ndarray:
        """Distance from the obstacle's rim to a body's rim, metres (< 0 means contact).

        Args:
            position: (..., 2) positions in metres.
            body_radius: radius of the body, metres.
        """
        d = np.asarray(position, dtype=float)[..., :2] - np.asarray(self.center)
        return np.hypot(d[..., 0], d[..., 1]) - self.radius - body_radius


@dataclass(frozen=True)
class Task:
    """The control task shared by the env's reward and the controllers' cost.

    Stage cost (per second): ``l(x, u) = e' Q e + (u - u_ref)' R (u - u_ref)`` with the error
    ``e = x - goal`` in which each *periodic* component (an angle whose goal is reached from
    either side, like the upright cart pole) is wrapped to ``[-pi, pi]``, ``atan2(sin e, cos e)``,
    so that the cost is the same for ``theta`` and ``theta + 2 pi``. The env's reward for one
    control period is ``-dt * l(x_k, u_k)``; a controller adds ``e' Qf e`` at the end of its
    horizon (:meth:`terminal_cost`).

    Attributes:
        goal: (n,) goal state.
        Q: (n, n) state weight.
        R: (m, m) control weight.
        Qf: (n, n) terminal weight for finite-horizon controllers.
        u_ref: (m,) control the cost is centred on (e.g. nominal hover thrust).
        goal_tolerance: (n,) per-component ``abs(x_i - goal_i)`` tolerance; ``inf`` means "not
            checked".
        hold_time: seconds the state must stay within tolerance for the task to count as success.
        duration: episode length in seconds (the time limit).
        obstacles: obstacles to keep clear of (position = first two state components).
        body_radius: the vehicle's radius in metres, for obstacle clearance.
        periodic_indices: state components whose error is wrapped to ``[-pi, pi]``.
    """

    goal: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    Qf: np.ndarray
    u_ref: np.ndarray
    goal_tolerance: np.ndarray
    hold_time: float
    duration: float
    obstacles: tuple[Obstacle, ...] = ()
    body_radius: float = 0.0
    periodic_indices: tuple[int, ...] = ()

    def error(self, x: np.ndarray | ca.SX | ca.MX) -> np.ndarray | ca.SX | ca.MX:
        """``e = x - goal`` with periodic components wrapped; (n,) numeric or (n, 1) symbolic."""
        if isinstance(x, (ca.SX, ca.MX)):
            e = x - ca.DM(self.goal)
            if not self.periodic_indices:
                return e
            parts = [ca.atan2(ca.sin(e[i]), ca.cos(e[i])) if i in self.periodic_indices
                     else e[i] for i in range(e.shape[0])]
            return ca.vertcat(*parts)
        e = np.asarray(x, dtype=float) - self.goal
        for i in self.periodic_indices:
            e[..., i] = np.arctan2(np.sin(e[..., i]), np.cos(e[..., i]))
        return e

    def stage_cost(self, x: np.ndarray, u: np.ndarray) -> float | ca.SX:
        """``l(x, u)`` (see class doc); numeric for arrays, symbolic for CasADi inputs."""
        if isinstance(x, (ca.SX, ca.MX)) or isinstance(u, (ca.SX, ca.MX)):
            e = self.error(x if isinstance(x, (ca.SX, ca.MX)) else ca.DM(x))
            du = u - ca.DM(self.u_ref)
            return ca.bilin(ca.DM(self.Q), e, e) + ca.bilin(ca.DM(self.R), du, du)
        e = self.error(x)
        du = np.asarray(u, dtype=float) - self.u_ref
        return float(e @ self.Q @ e + du @ self.R @ du)

    def terminal_cost(self, x: np.ndarray | ca.SX | ca.MX) -> float | ca.SX:
        """``e' Qf e`` for a controller's horizon end; numeric or symbolic like :meth:`error`."""
        e = self.error(x)
        if isinstance(e, (ca.SX, ca.MX)):
            return ca.bilin(ca.DM(self.Qf), e, e)
        return float(e @ self.Qf @ e)

    def at_goal(self, x: np.ndarray) -> bool:
        """True when every component is within ``goal_tolerance`` of the goal (errors wrapped)."""
        return bool(np.all(np.abs(self.error(x)) <= self.goal_tolerance))

    def goal_distance(self, x: np.ndarray) -> float:
        """Distance of state ``x`` (n,) to the goal that :meth:`at_goal` judges: the Euclidean
        norm of the error's checked components (finite ``goal_tolerance``), in their units."""
        checked = np.isfinite(self.goal_tolerance)
        return float(np.linalg.norm(self.error(x)[checked]))


@dataclass(frozen=True)
class ControlModel:
    """A physical model with one set of parameter values, bounds and a task.

    Immutable; it pickles and deep-copies (the compiled CasADi functions it caches are not
    copied but rebuilt on first use, so a copy evaluates exactly like the original).

    Attributes:
        name: system name (``"cartpole"``, ``"quadrotor"``, ``"dubins"``).
        ode: the physics, ``ode(x, u, p) -> xdot`` in CasADi operations.
        param_names: names of the entries of ``p``, in order (the paper's symbols).
        params: parameter values by name (read-only mapping). Each must be a real number
            inside its range in ``param_ranges``; construction (and so :meth:`with_params`)
            raises ``ValueError`` otherwise, naming the parameter, its value and its range.
        state_names: (n,) names of the state components, in the paper's order.
        control_names: (m,) names of the control components.
        dt: control period in seconds (zero-order hold).
        x_lb, x_ub: (n,) state bounds (``-inf``/``inf`` where unbounded).
        u_lb, u_ub: (m,) control bounds.
        task: the control task.
        substeps: RK4 substeps per control period used by :meth:`step`.
        angle_indices: indices of state components that are angles (radians).
        dynamic_indices: indices of the components whose rates come from forces (accelerations,
            or for a kinematic vehicle its actuated rates), as opposed to kinematic identities
            such as ``d(x)/dt = xdot`` that no parameter can make wrong. A learned residual
            belongs on these.
        param_ranges: valid range of each parameter (:class:`~gp_envs.physics.ParamRange`,
            read-only mapping). Default: the ``PARAM_RANGES`` table of the module that defines
            ``ode`` (every :mod:`gp_envs.physics` module has one).
    """

    name: str
    ode: OdeFn
    param_names: tuple[str, ...]
    params: Mapping[str, float]
    state_names: tuple[str, ...]
    control_names: tuple[str, ...]
    dt: float
    x_lb: np.ndarray
    x_ub: np.ndarray
    u_lb: np.ndarray
    u_ub: np.ndarray
    task: Task
    substeps: int = 10
    angle_indices: tuple[int, ...] = ()
    dynamic_indices: tuple[int, ...] = ()
    param_ranges: Mapping[str, ParamRange] | None = field(default=None, repr=False)
    _fns: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        ranges = self.param_ranges
        if ranges is None:
            ranges = getattr(inspect.getmodule(self.ode), "PARAM_RANGES", None)
            if ranges is None:
                raise ValueError(f"{self.name}: pass param_ranges; the module of ode "
                                 f"{getattr(self.ode, '__qualname__', self.ode)!r} has no "
                                 f"PARAM_RANGES table")
        if set(ranges) != set(self.param_names):
            raise ValueError(f"{self.name}: param_ranges must cover exactly "
                             f"{list(self.param_names)}, got {list(ranges)}")
        ranges = {k: ranges[k] for k in self.param_names}
        object.__setattr__(self, "param_ranges", ReadOnlyMapping(ranges))
        # the one check of parameter values (see gp_envs.physics.ranges)
        object.__setattr__(self, "params", ReadOnlyMapping(check_params(self.name, ranges,
                                                                        self.params)))

    # ----------------------------------------------------------------- pickling
    def __getstate__(self) -> dict[str, Any]:
        """Pickled state: every field except the cache of compiled CasADi functions.

        The cache is rebuilt on first use after unpickling (or ``copy.deepcopy``), so a copy
        never depends on whether, or how, CasADi serializes a compiled function.
        """
        state = self.__dict__.copy()
        state["_fns"] = {}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.__dict__["_fns"] = {}

    # ----------------------------------------------------------------- sizes and parameters
    @property
    def n_states(self) -> int:
        """Number of state components n."""
        return len(self.state_names)

    @property
    def n_controls(self) -> int:
        """Number of control components m."""
        return len(self.control_names)

    @property
    def param_vector(self) -> np.ndarray:
        """(k,) parameter values in the order of ``param_names``."""
        return np.array([self.params[k] for k in self.param_names], dtype=float)

    def with_params(self, **overrides: float) -> ControlModel:
        """A copy with some parameter values replaced.

        Raises:
            ValueError: an unknown name, or a value outside its range in ``param_ranges``.
        """
        unknown = set(overrides) - set(self.param_names)
        if unknown:
            raise ValueError(
                f"{self.name}: unknown parameter(s) {sorted(unknown)}; "
                f"known: {list(self.param_names)}"
            )
        new = {**self.params, **overrides}  # checked by the constructor
        return ControlModel(
            name=self.name, ode=self.ode, param_names=self.param_names, params=new,
            state_names=self.state_names, control_names=self.control_names, dt=self.dt,
            x_lb=self.x_lb, x_ub=self.x_ub, u_lb=self.u_lb, u_ub=self.u_ub, task=self.task,
            substeps=self.substeps, angle_indices=self.angle_indices,
            dynamic_indices=self.dynamic_indices, param_ranges=self.param_ranges,
        )

    # ----------------------------------------------------------------- CasADi functions
    def _symbols(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        return (ca.SX.sym("x", self.n_states), ca.SX.sym("u", self.n_controls),
                ca.SX.sym("p", len(self.param_names)))

    def _parametric(self, key: str) -> ca.Function:
        """Compiled-once CasADi functions of (x, u, p), shared by models of the same system."""
        cache = _FUNCTION_CACHE.setdefault((self.ode, self.dt, self.substeps), {})
        if key not in cache:
            x, u, p = self._symbols()
            if key == "f":
                cache[key] = ca.Function("f", [x, u, p], [self.ode(x, u, p)],
                                         ["x", "u", "p"], ["xdot"])
            elif key == "step":
                x_next = rk4(lambda xx: self.ode(xx, u, p), x, self.dt, self.substeps)
                cache[key] = ca.Function("step", [x, u, p], [x_next], ["x", "u", "p"],
                                         ["x_next"])
            else:  # pragma: no cover - internal keys only
                raise KeyError(key)
        return cache[key]

    def casadi_function(self) -> ca.Function:
        """CasADi ``f(x (n,), u (m,)) -> xdot (n,)`` with this model's parameter values embedded."""
        if "f_embedded" not in self._fns:
            x, u, _ = self._symbols()
            self._fns["f_embedded"] = ca.Function(
                f"{self.name}_f", [x, u], [self.ode(x, u, ca.DM(self.param_vector))],
                ["x", "u"], ["xdot"])
        return self._fns["f_embedded"]

    def casadi_parametric_function(self) -> ca.Function:
        """CasADi ``f(x (n,), u (m,), p (k,)) -> xdot (n,)`` with parameters as an input."""
        return self._parametric("f")

    # ----------------------------------------------------------------- evaluation
    def f(self, x: np.ndarray | ca.SX | ca.MX, u: np.ndarray | ca.SX | ca.MX
          ) -> np.ndarray | ca.SX | ca.MX:
        """Continuous dynamics ``xdot = f(x, u)`` with this model's parameters.

        Args:
            x: state, (n,) or a batch (N, n); or a CasADi symbol/expression (n, 1).
            u: control, (m,) or a batch (N, m); or a CasADi symbol/expression (m, 1).

        Returns:
            xdot with the shape of ``x`` (numeric), or a CasADi expression (symbolic).
        """
        if any(isinstance(a, (ca.SX, ca.MX)) for a in (x, u)):
            return self.casadi_function()(x, u)
        return self._batched("f", x, u)

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """State after one control period ``dt`` under zero-order hold on ``u`` (RK4).

        Args:
            x: (n,) or (N, n) state(s). u: (m,) or (N, m) control(s).

        Returns:
            (n,) or (N, n) next state(s).
        """
        return self._batched("step", x, u)

    def _batched(self, key: str, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        single = x.ndim == 1
        xb = np.atleast_2d(x)
        ub = np.atleast_2d(u)
        if xb.shape[-1] != self.n_states or ub.shape[-1] != self.n_controls:
            raise ValueError(
                f"{self.name}: expected x (..., {self.n_states}) and u (..., {self.n_controls}), "
                f"got {x.shape} and {u.shape}")
        if ub.shape[0] != xb.shape[0]:
            if ub.shape[0] == 1:
                ub = np.repeat(ub, xb.shape[0], axis=0)
            else:
                raise ValueError(f"{self.name}: batch sizes differ: x {x.shape}, u {u.shape}")
        fn = self._parametric(key)
        p = self.param_vector
        if xb.shape[0] == 1:
            out = np.asarray(fn(xb[0], ub[0], p)).reshape(1, -1)
        else:
            out = np.asarray(fn.map(xb.shape[0])(xb.T, ub.T, p)).T
        return out[0] if single else out


_FUNCTION_CACHE: dict[tuple, dict[str, ca.Function]] = {}


def rk4(rate: Callable[[ca.SX], ca.SX], x: ca.SX, duration: float, substeps: int) -> ca.SX:
    """Classical Runge-Kutta (RK4) integration of ``xdot = rate(x)`` over ``duration``.

    Args:
        rate: the right-hand side with the control held constant (zero-order hold).
        x: (n,) initial state (CasADi expression).
        duration: seconds to integrate. substeps: equal RK4 steps.

    Returns:
        (n,) state after ``duration`` (CasADi expression).
    """
    h = duration / substeps
    for _ in range(substeps):
        k1 = rate(x)
        k2 = rate(x + h / 2 * k1)
        k3 = rate(x + h / 2 * k2)
        k4 = rate(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def diag(values: Sequence[float]) -> np.ndarray:
    """Square diagonal matrix from a sequence (helper for cost weights)."""
    return np.diag(np.asarray(values, dtype=float))
