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

ANY_REAL = ParamRange(-np.inf, np.inf, False, False, "a model parameter (no range given)")
"""The range of a parameter of an ODE whose module declares no ``PARAM_RANGES``: any finite
real number."""

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


@dataclass(frozen=True, kw_only=True)
class Task:
    """The control task: the controllers' cost and the success rule.

    Stage cost (per second): ``l(x, u) = e' Q e + (u - u_ref)' R (u - u_ref) + stage(x, u)``
    with the error ``e = x - goal`` in which each *periodic* component (an angle whose goal is
    reached from either side, like the upright cart pole) is wrapped to ``[-pi, pi]``,
    ``atan2(sin e, cos e)``, so that the cost is the same for ``theta`` and ``theta + 2 pi``; a
    controller adds ``e' Qf e + terminal(x)`` at the end of its horizon (:meth:`terminal_cost`).
    The quadratic part is the default; ``stage`` and ``terminal`` add any CasADi expression
    (e.g. a saturating cost; set ``Q``/``R`` to zero for none of the quadratic part). A
    ``gp_envs`` env's reward for one control period is ``-dt * l(x_k, u_k)``; an env given its
    model by :func:`gp_envs.wrap` keeps its own reward.

    Attributes:
        goal: (n,) goal state.
        Q: (n, n) state weight.
        R: (m, m) control weight.
        goal_tolerance: (n,) per-component ``abs(x_i - goal_i)`` tolerance; ``inf`` means "not
            checked".
        hold_time: seconds the state must stay within tolerance for the task to count as success.
        duration: episode length in seconds (the time limit).
        Qf: (n, n) terminal weight for finite-horizon controllers (default: none, zeros).
        u_ref: (m,) control the cost is centred on (e.g. nominal hover thrust; default zeros).
        obstacles: obstacles to keep clear of (position = first two state components).
        body_radius: the vehicle's radius in metres, for obstacle clearance.
        periodic_indices: state components whose error is wrapped to ``[-pi, pi]``.
        stage: an extra stage cost ``stage(x, u) -> scalar`` per second, in CasADi operations
            (x (n,), u (m,) symbols), or None.
        terminal: an extra terminal cost ``terminal(x) -> scalar`` in CasADi operations, or
            None.

    Raises:
        ValueError: weights, goal, tolerance or reference of sizes that do not match; a
            negative ``hold_time``; a non-positive ``duration``; ``stage``/``terminal`` not
            callable.
    """

    goal: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    goal_tolerance: np.ndarray
    hold_time: float
    duration: float
    Qf: np.ndarray | None = None
    u_ref: np.ndarray | None = None
    obstacles: tuple[Obstacle, ...] = ()
    body_radius: float = 0.0
    periodic_indices: tuple[int, ...] = ()
    stage: Callable[[Any, Any], Any] | None = field(default=None, repr=False)
    terminal: Callable[[Any], Any] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        put = object.__setattr__
        goal = np.asarray(self.goal, dtype=float).reshape(-1)
        n = goal.size
        R = np.atleast_2d(np.asarray(self.R, dtype=float))
        m = R.shape[0]
        put(self, "goal", goal)
        put(self, "R", R)
        put(self, "Q", np.atleast_2d(np.asarray(self.Q, dtype=float)))
        put(self, "Qf", np.zeros((n, n)) if self.Qf is None
            else np.atleast_2d(np.asarray(self.Qf, dtype=float)))
        put(self, "u_ref", np.zeros(m) if self.u_ref is None
            else np.asarray(self.u_ref, dtype=float).reshape(-1))
        put(self, "goal_tolerance", np.asarray(self.goal_tolerance, dtype=float).reshape(-1))
        put(self, "periodic_indices", tuple(int(i) for i in self.periodic_indices))
        for name, shape in (("Q", (n, n)), ("Qf", (n, n)), ("R", (m, m)), ("u_ref", (m,)),
                            ("goal_tolerance", (n,))):
            if getattr(self, name).shape != shape:
                raise ValueError(f"Task: {name} must have shape {shape} (goal has {n} "
                                 f"components, R is {m} x {m}), got "
                                 f"{getattr(self, name).shape}")
        if np.any(np.isnan(self.goal_tolerance)) or np.any(self.goal_tolerance < 0):
            raise ValueError(f"Task: goal_tolerance must be >= 0 (inf: not checked), got "
                             f"{self.goal_tolerance}")
        if any(not 0 <= i < n for i in self.periodic_indices):
            raise ValueError(f"Task: periodic_indices must be in [0, {n}), got "
                             f"{self.periodic_indices}")
        if not (np.isfinite(self.hold_time) and self.hold_time >= 0):
            raise ValueError(f"Task: hold_time must be a number of seconds >= 0, got "
                             f"{self.hold_time!r}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"Task: duration must be a positive number of seconds, got "
                             f"{self.duration!r}")
        for name in ("stage", "terminal"):
            if getattr(self, name) is not None and not callable(getattr(self, name)):
                raise ValueError(f"Task: {name} must be a function of CasADi symbols or None")

    def check_sizes(self, n: int, m: int, owner: str = "Task") -> None:
        """Raise ``ValueError`` unless this task is for n states and m controls (and its extra
        costs give scalars on CasADi symbols of those sizes)."""
        if (self.goal.size, self.u_ref.size) != (n, m):
            raise ValueError(f"{owner}: the task is for {self.goal.size} states and "
                             f"{self.u_ref.size} controls, the model has {n} and {m}")
        x, u = ca.SX.sym("x", n), ca.SX.sym("u", m)
        for name, args in (("stage", (x, u)), ("terminal", (x,))):
            fn = getattr(self, name)
            if fn is None:
                continue
            try:
                shape = ca.SX(fn(*args)).shape
            except Exception as err:  # any failure of a user's function
                raise ValueError(f"{owner}: the task's {name} cost failed on CasADi symbols: "
                                 f"{type(err).__name__}: {err}") from err
            if shape != (1, 1):
                raise ValueError(f"{owner}: the task's {name} cost must be a scalar, got shape "
                                 f"{shape}")

    def _extra(self, name: str, *args: np.ndarray) -> float:
        """The extra cost ``name`` evaluated numerically (compiled once per function)."""
        fn = getattr(self, name)
        key = (fn, *(np.size(a) for a in args))
        if key not in _COST_CACHE:
            syms = [ca.SX.sym(f"a{i}", int(np.size(a))) for i, a in enumerate(args)]
            _COST_CACHE[key] = ca.Function(name, syms, [fn(*syms)])
        return float(_COST_CACHE[key](*[np.asarray(a, float).reshape(-1) for a in args]))

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
            xs = x if isinstance(x, (ca.SX, ca.MX)) else ca.DM(x)
            e = self.error(xs)
            du = u - ca.DM(self.u_ref)
            cost = ca.bilin(ca.DM(self.Q), e, e) + ca.bilin(ca.DM(self.R), du, du)
            return cost + self.stage(xs, u) if self.stage is not None else cost
        e = self.error(x)
        du = np.asarray(u, dtype=float) - self.u_ref
        cost = float(e @ self.Q @ e + du @ self.R @ du)
        return cost + self._extra("stage", x, u) if self.stage is not None else cost

    def terminal_cost(self, x: np.ndarray | ca.SX | ca.MX) -> float | ca.SX:
        """``e' Qf e + terminal(x)`` for a controller's horizon end; numeric or symbolic like
        :meth:`error`."""
        e = self.error(x)
        if isinstance(e, (ca.SX, ca.MX)):
            cost = ca.bilin(ca.DM(self.Qf), e, e)
            return cost + self.terminal(x) if self.terminal is not None else cost
        cost = float(e @ self.Qf @ e)
        return cost + self._extra("terminal", x) if self.terminal is not None else cost

    def at_goal(self, x: np.ndarray) -> bool:
        """True when every component is within ``goal_tolerance`` of the goal (errors wrapped)."""
        return bool(np.all(np.abs(self.error(x)) <= self.goal_tolerance))

    def goal_distance(self, x: np.ndarray) -> float:
        """Distance of state ``x`` (n,) to the goal that :meth:`at_goal` judges: the Euclidean
        norm of the error's checked components (finite ``goal_tolerance``), in their units."""
        checked = np.isfinite(self.goal_tolerance)
        return float(np.linalg.norm(self.error(x)[checked]))


@dataclass(frozen=True, kw_only=True)
class ControlModel:
    """A physical model with one set of parameter values, bounds and a task.

    Built by keyword, from your own CasADi ODE as from a physics module of
    :mod:`gp_envs.physics` (:meth:`from_physics`)::

        model = ControlModel(
            name="my_swing", ode=lambda x, u, p: ca.vertcat(x[1], p[0] * ca.sin(x[0]) + u[0]),
            params={"a": 15.0}, state_names=("theta", "thetadot"), control_names=("torque",),
            dt=0.05, u_lb=[-2.0], u_ub=[2.0],
            task=Task(goal=[0.0, 0.0], Q=np.diag([1.0, 0.1]), R=[[1e-3]],
                      goal_tolerance=[0.1, np.inf], hold_time=1.0, duration=10.0))

    Immutable; it pickles and deep-copies (the compiled CasADi functions it caches are not
    copied but rebuilt on first use, so a copy evaluates exactly like the original; an ``ode``
    that is a lambda or a local function does not pickle, a module-level function does).

    Attributes:
        name: the model's own name (``"cartpole"``, ``"my_swing"``); the controllers look
            their per-system defaults up by it.
        ode: the physics, ``ode(x, u, p) -> xdot`` in CasADi operations: state (n,), control
            (m,), parameters (k,) in the order of ``param_names``; returns (n,).
        params: parameter values by name (read-only mapping). Each must be a real number
            inside its range in ``param_ranges``; construction (and so :meth:`with_params`)
            raises ``ValueError`` otherwise, naming the parameter, its value and its range.
        param_names: names of the entries of ``p``, in order (default: the order of
            ``params``).
        state_names: (n,) names of the state components.
        control_names: (m,) names of the control components.
        dt: control period in seconds (zero-order hold): one env step.
        x_lb, x_ub: (n,) planning state bounds (``-inf``/``inf`` where unbounded; default
            unbounded). The box a controller keeps to; an env's termination rule is its own.
        u_lb, u_ub: (m,) control bounds.
        task: the control task.
        substeps: RK4 substeps per control period used by :meth:`step`.
        angle_indices: indices of state components that are angles (radians).
        dynamic_indices: indices of the components whose rates come from forces (accelerations,
            or for a kinematic vehicle its actuated rates), as opposed to kinematic identities
            such as ``d(x)/dt = xdot`` that no parameter can make wrong. A learned residual
            belongs on these. Default (None): every component.
        param_ranges: valid range of each parameter (:class:`~gp_envs.physics.ParamRange`,
            read-only mapping). Default: the ``PARAM_RANGES`` table of the module that defines
            ``ode`` (every :mod:`gp_envs.physics` module has one), else any finite real number.

    Raises:
        ValueError: (at construction) parameter values outside their ranges; names, bounds,
            indices or task of sizes that do not match; a lower bound above an upper one; a
            non-positive ``dt`` or ``substeps``; an ``ode`` whose output is not (n,) for
            (n,) states, (m,) controls and (k,) parameters.
    """

    name: str
    ode: OdeFn
    params: Mapping[str, float]
    state_names: tuple[str, ...]
    control_names: tuple[str, ...]
    dt: float
    u_lb: np.ndarray
    u_ub: np.ndarray
    task: Task
    param_names: tuple[str, ...] = ()
    x_lb: np.ndarray | None = None
    x_ub: np.ndarray | None = None
    substeps: int = 10
    angle_indices: tuple[int, ...] = ()
    dynamic_indices: tuple[int, ...] | None = None
    param_ranges: Mapping[str, ParamRange] | None = field(default=None, repr=False)
    _fns: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        name = self.name
        if not (isinstance(name, str) and name):
            raise ValueError(f"ControlModel: name must be a non-empty string, got {name!r}")
        if not callable(self.ode):
            raise ValueError(f"{name}: ode must be a function ode(x, u, p) -> xdot")
        put = object.__setattr__
        put(self, "state_names", tuple(str(v) for v in self.state_names))
        put(self, "control_names", tuple(str(v) for v in self.control_names))
        put(self, "param_names", tuple(self.param_names) or tuple(self.params))
        n, m = len(self.state_names), len(self.control_names)
        if n < 1 or m < 1:
            raise ValueError(f"{name}: a model needs at least one state and one control, got "
                             f"{n} state names and {m} control names")
        for field_name, size, default in (("x_lb", n, -np.inf), ("x_ub", n, np.inf),
                                          ("u_lb", m, None), ("u_ub", m, None)):
            value = getattr(self, field_name)
            if value is None and default is not None:
                value = np.full(size, default)
            try:
                array = np.asarray(value, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: {field_name} must be {size} numbers, got "
                                 f"{value!r}") from None
            if array.shape != (size,) or np.any(np.isnan(array)):
                raise ValueError(f"{name}: {field_name} must be {size} numbers (not NaN), got "
                                 f"{value!r}")
            put(self, field_name, array)
        for low, high in (("x_lb", "x_ub"), ("u_lb", "u_ub")):
            if np.any(getattr(self, low) > getattr(self, high)):
                raise ValueError(f"{name}: {low} {getattr(self, low)} exceeds {high} "
                                 f"{getattr(self, high)}")
        if not (isinstance(self.dt, (int, float, np.floating)) and not isinstance(self.dt, bool)
                and np.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"{name}: dt must be a positive number of seconds, got {self.dt!r}")
        put(self, "dt", float(self.dt))
        if isinstance(self.substeps, bool) or not isinstance(self.substeps, (int, np.integer)) \
                or self.substeps < 1:
            raise ValueError(f"{name}: substeps must be an integer >= 1, got {self.substeps!r}")
        dynamic = tuple(range(n)) if self.dynamic_indices is None else self.dynamic_indices
        for field_name, indices in (("angle_indices", self.angle_indices),
                                    ("dynamic_indices", dynamic)):
            indices = tuple(int(i) for i in indices)
            if any(not 0 <= i < n for i in indices) or len(set(indices)) != len(indices):
                raise ValueError(f"{name}: {field_name} must be distinct indices in [0, {n}), "
                                 f"got {indices}")
            put(self, field_name, indices)
        if not isinstance(self.task, Task):
            raise ValueError(f"{name}: task must be a gp_envs Task, got "
                             f"{type(self.task).__name__}")
        self.task.check_sizes(n, m, owner=name)
        ranges = self.param_ranges
        if ranges is None:
            ranges = getattr(inspect.getmodule(self.ode), "PARAM_RANGES", None)
            if ranges is None:
                ranges = {k: ANY_REAL for k in self.param_names}
        if set(ranges) != set(self.param_names):
            raise ValueError(f"{name}: param_ranges must cover exactly "
                             f"{list(self.param_names)}, got {list(ranges)}")
        ranges = {k: ranges[k] for k in self.param_names}
        put(self, "param_ranges", ReadOnlyMapping(ranges))
        # the one check of parameter values (see gp_envs.physics.ranges)
        put(self, "params", ReadOnlyMapping(check_params(name, ranges, self.params)))
        _check_ode(self.ode, n, m, len(self.param_names), name)

    @classmethod
    def from_physics(cls, physics: Any, params: Mapping[str, float] | None = None, *,
                     dt: float, u_lb: Sequence[float], u_ub: Sequence[float], task: Task,
                     name: str | None = None, **fields: Any) -> ControlModel:
        """A model of a physics module of :mod:`gp_envs.physics` (or a module laid out like
        one: ``ode``, ``PARAM_RANGES``, ``STATE_NAMES``, ``CONTROL_NAMES``) with your own
        parameter values, bounds and task, in one call.

        Args:
            physics: the module, e.g. :mod:`gp_envs.physics.cartpole`.
            params: parameter values by name; every parameter of the module.
            dt, u_lb, u_ub, task: as the class's attributes.
            name: the model's name (default: the module's short name).
            **fields: any other attribute (``x_lb``, ``x_ub``, ``substeps``,
                ``angle_indices``, ``dynamic_indices``).

        Raises:
            ValueError: as the constructor.
        """
        return cls(name=name or physics.__name__.rsplit(".", 1)[-1], ode=physics.ode,
                   params=dict(params or {}), param_names=tuple(physics.PARAM_NAMES),
                   state_names=tuple(physics.STATE_NAMES),
                   control_names=tuple(physics.CONTROL_NAMES), dt=dt, u_lb=u_lb, u_ub=u_ub,
                   task=task, param_ranges=physics.PARAM_RANGES, **fields)

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
                "f", [x, u], [self.ode(x, u, ca.DM(self.param_vector))],
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
_COST_CACHE: dict[tuple, ca.Function] = {}
_CHECKED_ODES: set[tuple[Any, int, int, int]] = set()


def _check_ode(ode: OdeFn, n: int, m: int, k: int, name: str) -> None:
    """``ode`` evaluated once on CasADi symbols of these sizes gives an (n,) expression (checked
    once per ode and sizes)."""
    key = (ode, n, m, k)
    if key in _CHECKED_ODES:
        return
    x, u, p = ca.SX.sym("x", n), ca.SX.sym("u", m), ca.SX.sym("p", k)
    try:
        out = ode(x, u, p)
        shape = ca.SX(out).shape
    except Exception as err:  # any failure of a user's function
        raise ValueError(f"{name}: ode(x, u, p) failed on CasADi symbols of sizes ({n},), "
                         f"({m},), ({k},): {type(err).__name__}: {err}") from err
    if shape not in ((n, 1), (1, n)):
        raise ValueError(f"{name}: ode(x, u, p) must return {n} components (one per state), "
                         f"got shape {shape}")
    _CHECKED_ODES.add(key)


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
