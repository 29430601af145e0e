"""Definition of a continuous-time Bolza optimal control problem.

Paper section "Gauss Pseudospectral Optimal Control", eqs. (Cost), (dyn), (bound): minimise

    J = Phi(x(t0), x(tf), tf, p) + int_{t0}^{tf} L(x(t), u(t), p) dt

subject to ``xdot = f(x, u, p)``, box bounds on the state and the control, nonlinear path
constraints ``c_lb <= c(x, u, p) <= c_ub``, boundary conditions on ``x(t0)`` and ``x(tf)``
(fixed, free or bounded), general boundary (event) constraints
``b_lb <= b(x(t0), x(tf), tf, p) <= b_ub`` and a fixed or free final time ``tf``.
The initial time ``t0`` is fixed.

``p`` is a user-declared parameter vector of fixed size ``n_params`` (goal, learned-model
weights, obstacle data, ...). It becomes an NLP *parameter*: changing it does not rebuild the NLP.
``q`` (size ``n_node_params``) is a parameter vector with one value per collocation node: the
dynamics, running cost and path constraints at node ``k`` see ``q_k`` (e.g. a model linearized
about a previous trajectory, one linearization per node). It is an NLP parameter too.

The callables receive CasADi symbols (SX, or MX if SX evaluation fails) and must return CasADi
expressions; a :class:`casadi.Function` works too. Trailing arguments may be omitted: a
dynamics ``f(x, u)`` without parameters is accepted, and so is ``terminal_cost(x0, xf)``.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["OptimalControlProblem", "ProblemFunctions"]

FloatArray = NDArray[np.float64]
SymbolicFn = Callable[..., Any] | ca.Function
"""A Python function of CasADi symbols returning a CasADi expression, or a casadi.Function."""


def _n_positional(fn: SymbolicFn) -> int | None:
    """Number of positional arguments ``fn`` accepts (None: variadic)."""
    if isinstance(fn, ca.Function):
        return int(fn.n_in())
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    count = 0
    for par in sig.parameters.values():
        if par.kind == inspect.Parameter.VAR_POSITIONAL:
            return None
        if par.kind in (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD):
            count += 1
    return count


def _call(fn: SymbolicFn, name: str, args: list[Any], min_args: int) -> Any:
    """Call ``fn`` with as many leading ``args`` as it accepts (at least ``min_args``)."""
    n = _n_positional(fn)
    if n is None:
        n = len(args)
    if n < min_args or n > len(args):
        raise ValueError(
            f"{name} must accept between {min_args} and {len(args)} positional arguments, "
            f"it accepts {n}"
        )
    out = fn(*args[:n])
    if isinstance(out, dict):
        raise ValueError(f"{name} returned a dict; pass a casadi.Function with positional I/O")
    if isinstance(out, (list, tuple)):
        if len(out) != 1:
            raise ValueError(f"{name} must return a single expression, got {len(out)} outputs")
        out = out[0]
    return out


def _as_column(expr: Any, sym_type: type, name: str) -> Any:
    """Convert a callable's output to a CasADi column of type ``sym_type``."""
    if isinstance(expr, (ca.SX, ca.MX, ca.DM)):
        out = expr
    else:
        try:
            out = ca.vertcat(*[e for e in np.atleast_1d(np.asarray(expr, dtype=object)).ravel()])
        except Exception as err:  # any conversion failure: one clear message
            raise ValueError(f"{name} must return a CasADi expression, got {type(expr)}") from err
    if isinstance(out, ca.DM):
        out = sym_type(out)
    if out.is_empty():
        return sym_type(0, 1)
    if out.shape[1] != 1:
        if out.shape[0] == 1:
            out = out.T
        else:
            raise ValueError(f"{name} must return a vector, got shape {out.shape}")
    return out


def _bounds(value: ArrayLike | None, size: int, default: float, name: str) -> FloatArray:
    """Broadcast a bound (None, scalar or (size,)) to a float array of shape (size,)."""
    if value is None:
        return np.full(size, default)
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    arr = arr.ravel()
    if arr.shape != (size,):
        raise ValueError(f"{name} must be a scalar or have shape ({size},), got {arr.shape}")
    if np.any(np.isnan(arr)):
        raise ValueError(f"{name} contains NaN")
    return arr.copy()


def _check_lb_ub(lb: FloatArray, ub: FloatArray, name: str) -> None:
    bad = np.flatnonzero(lb > ub)
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"inconsistent {name} bounds: lb > ub at index {i} ({lb[i]} > {ub[i]})")


@dataclass(frozen=True)
class ProblemFunctions:
    """CasADi functions of an :class:`OptimalControlProblem` (built by ``functions()``).

    Attributes:
        node: ``(x (n,), u (m,), p (n_p,), q (n_q,)) -> (xdot (n,), L (1,), c (n_c,))``.
        node_hessian: the same with the problem's ``hessian_dynamics`` in place of its
            ``dynamics``, or None if it has none.
        boundary: ``(x0 (n,), xf (n,), tf (1,), p (n_p,)) -> (Phi (1,), b (n_b,))``.
        n_path: number of path constraints n_c.
        n_boundary: number of boundary constraints n_b.
    """

    node: ca.Function
    boundary: ca.Function
    n_path: int
    n_boundary: int
    node_hessian: ca.Function | None = None


@dataclass
class OptimalControlProblem:
    """A Bolza optimal control problem with fixed t0 and fixed or free tf.

    Units are the user's; the solver only assumes ``t`` is time (e.g. seconds), ``f`` is the
    state rate per unit time and ``running_cost`` is cost per unit time.

    Attributes:
        n_states: state dimension n.
        n_controls: control dimension m.
        dynamics: ``f(x (n,), u (m,), p (n_p,)) -> xdot (n,)``; ``f(x, u)`` also accepted, and
            ``f(x, u, p, q)`` with per-node parameters ``q (n_q,)``.
        n_params: size n_p of the parameter vector p (0: no parameters).
        n_node_params: size n_q of the per-node parameter vector q (0: none). Its value is an
            (M, n_q) array, one row per collocation node, given at every solve.
        running_cost: Lagrange integrand ``L(x, u, p[, q]) -> scalar``, cost per unit time, or
            None.
        terminal_cost: Mayer term ``Phi(x0 (n,), xf (n,), tf (scalar), p) -> scalar``, or None.
        t0: initial time (fixed).
        tf: final time if fixed; None for a free final time (then ``tf_bounds`` apply).
        tf_bounds: (lb, ub) on a free final time; ``lb`` is raised to ``t0`` if below it.
        tf_guess: initial guess of a free final time (default: a finite point in the bounds).
        x_lb, x_ub: state bounds, scalar or (n,); applied at the collocation nodes, segment
            boundaries and the terminal point (not at t0, see ``x0_lb``).
        u_lb, u_ub: control bounds, scalar or (m,); applied at the nodes.
        x0: fixed initial state (n,); shortcut for ``x0_lb = x0_ub = x0``. May be overridden at
            every solve (``solve(x0=...)``).
        x0_lb, x0_ub: bounds on x(t0) (default: the state bounds).
        xf: fixed terminal state (n,); shortcut for ``xf_lb = xf_ub = xf``.
        xf_lb, xf_ub: bounds on x(tf), intersected with the state bounds.
        path_constraints: ``c(x, u, p[, q]) -> (n_c,)`` enforced at every collocation node, or
            None.
        path_lb, path_ub: bounds on c, scalar or (n_c,) (default: ``c <= 0`` like paper eq. PC,
            i.e. lb = -inf, ub = 0).
        boundary_constraints: ``b(x0, xf, tf, p) -> (n_b,)``, or None.
        boundary_lb, boundary_ub: bounds on b (default: ``b == 0``).
        hessian_dynamics: optional approximation of ``dynamics`` (same signature) used only for
            the second derivatives the NLP solver asks for: the Hessian of the Lagrangian is
            that of the problem with ``hessian_dynamics`` in place of ``dynamics``. Constraints
            and their Jacobian stay exact, so a converged solution is the same; only the Newton
            steps are inexact. Worth it when ``dynamics`` is a cheap dominant part plus an
            expensive small correction (physics plus a learned residual): the correction's
            second derivatives are the dearest part of each iteration. None: exact Hessian.
    """

    n_states: int
    n_controls: int
    dynamics: SymbolicFn
    n_params: int = 0
    n_node_params: int = 0
    running_cost: SymbolicFn | None = None
    terminal_cost: SymbolicFn | None = None
    t0: float = 0.0
    tf: float | None = 1.0
    tf_bounds: tuple[float, float] = (0.0, math.inf)
    tf_guess: float | None = None
    x_lb: ArrayLike | None = None
    x_ub: ArrayLike | None = None
    u_lb: ArrayLike | None = None
    u_ub: ArrayLike | None = None
    x0: ArrayLike | None = None
    x0_lb: ArrayLike | None = None
    x0_ub: ArrayLike | None = None
    xf: ArrayLike | None = None
    xf_lb: ArrayLike | None = None
    xf_ub: ArrayLike | None = None
    path_constraints: SymbolicFn | None = None
    path_lb: ArrayLike | None = None
    path_ub: ArrayLike | None = None
    boundary_constraints: SymbolicFn | None = None
    boundary_lb: ArrayLike | None = None
    boundary_ub: ArrayLike | None = None
    hessian_dynamics: SymbolicFn | None = None
    _functions: ProblemFunctions | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("n_states", "n_controls", "n_params", "n_node_params"):
            val = getattr(self, name)
            if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {val!r}")
            setattr(self, name, int(val))
        if self.n_states < 1:
            raise ValueError("n_states must be >= 1")
        if not callable(self.dynamics):
            raise ValueError("dynamics must be callable (a Python function or casadi.Function)")
        if self.hessian_dynamics is not None and not callable(self.hessian_dynamics):
            raise ValueError("hessian_dynamics must be callable or None")
        for name in ("running_cost", "terminal_cost", "path_constraints", "boundary_constraints"):
            fn = getattr(self, name)
            if fn is not None and not callable(fn):
                raise ValueError(f"{name} must be callable or None")
        if self.running_cost is None and self.terminal_cost is None:
            raise ValueError("the problem needs a running_cost, a terminal_cost, or both")
        n, m = self.n_states, self.n_controls
        if not math.isfinite(float(self.t0)):
            raise ValueError(f"t0 must be finite, got {self.t0}")
        self.t0 = float(self.t0)
        if self.tf is not None:
            self.tf = float(self.tf)
            if not math.isfinite(self.tf) or self.tf <= self.t0:
                raise ValueError(f"fixed final time tf={self.tf} must be finite and > t0={self.t0}")
        else:
            lo, hi = (float(v) for v in self.tf_bounds)
            if math.isnan(lo) or math.isnan(hi):
                raise ValueError("tf_bounds contains NaN")
            lo = max(lo, self.t0)
            if hi <= lo:
                raise ValueError(
                    f"inconsistent tf_bounds: need t0 <= lb < ub, got {self.tf_bounds}"
                )
            self.tf_bounds = (lo, hi)
            if self.tf_guess is not None:
                g = float(self.tf_guess)
                if not (math.isfinite(g) and lo <= g <= hi and g > self.t0):
                    raise ValueError(f"tf_guess={g} must be finite, > t0 and within tf_bounds")
                self.tf_guess = g

        self.x_lb = _bounds(self.x_lb, n, -np.inf, "x_lb")
        self.x_ub = _bounds(self.x_ub, n, np.inf, "x_ub")
        _check_lb_ub(self.x_lb, self.x_ub, "state")
        self.u_lb = _bounds(self.u_lb, m, -np.inf, "u_lb")
        self.u_ub = _bounds(self.u_ub, m, np.inf, "u_ub")
        _check_lb_ub(self.u_lb, self.u_ub, "control")

        for point, lb_name, ub_name in (("x0", "x0_lb", "x0_ub"), ("xf", "xf_lb", "xf_ub")):
            fixed = getattr(self, point)
            if fixed is not None:
                if getattr(self, lb_name) is not None or getattr(self, ub_name) is not None:
                    raise ValueError(f"give either {point} or {lb_name}/{ub_name}, not both")
                val = _bounds(fixed, n, 0.0, point)
                if not np.all(np.isfinite(val)):
                    raise ValueError(f"{point} must be finite")
                setattr(self, point, val)
                setattr(self, lb_name, val.copy())
                setattr(self, ub_name, val.copy())
        if self.x0_lb is None and self.x0_ub is None:
            self.x0_lb, self.x0_ub = self.x_lb.copy(), self.x_ub.copy()
        self.x0_lb = _bounds(self.x0_lb, n, -np.inf, "x0_lb")
        self.x0_ub = _bounds(self.x0_ub, n, np.inf, "x0_ub")
        _check_lb_ub(self.x0_lb, self.x0_ub, "initial-state")
        xf_lb = np.maximum(_bounds(self.xf_lb, n, -np.inf, "xf_lb"), self.x_lb)
        xf_ub = np.minimum(_bounds(self.xf_ub, n, np.inf, "xf_ub"), self.x_ub)
        _check_lb_ub(xf_lb, xf_ub, "terminal-state (intersected with the state bounds)")
        self.xf_lb, self.xf_ub = xf_lb, xf_ub

        fns = self.functions()
        self.path_lb = _bounds(self.path_lb, fns.n_path, -np.inf, "path_lb")
        self.path_ub = _bounds(self.path_ub, fns.n_path, 0.0, "path_ub")
        _check_lb_ub(self.path_lb, self.path_ub, "path-constraint")
        self.boundary_lb = _bounds(self.boundary_lb, fns.n_boundary, 0.0, "boundary_lb")
        self.boundary_ub = _bounds(self.boundary_ub, fns.n_boundary, 0.0, "boundary_ub")
        _check_lb_ub(self.boundary_lb, self.boundary_ub, "boundary-constraint")

    @property
    def free_final_time(self) -> bool:
        """True if tf is a decision variable."""
        return self.tf is None

    def functions(self) -> ProblemFunctions:
        """Build (once) and return the CasADi functions of the problem.

        Symbolic evaluation is tried with SX first (fastest derivatives); if a callable only
        supports MX (e.g. it calls a non-expandable casadi.Function) MX is used.

        Raises:
            ValueError: if a callable returns an expression of the wrong shape.
        """
        if self._functions is None:
            try:
                self._functions = self._build(ca.SX)
            except ValueError:
                raise
            except Exception:  # SX unsupported by the user's callable: try MX
                self._functions = self._build(ca.MX)
        return self._functions

    def _build(self, sym: type) -> ProblemFunctions:
        n, m, n_p = self.n_states, self.n_controls, self.n_params
        x, u, p = sym.sym("x", n), sym.sym("u", m), sym.sym("p", n_p)
        q = sym.sym("q", self.n_node_params)
        x0, xf, tf = sym.sym("x0", n), sym.sym("xf", n), sym.sym("tf")

        xdot = _as_column(_call(self.dynamics, "dynamics", [x, u, p, q], 2), sym, "dynamics")
        if xdot.shape != (n, 1):
            raise ValueError(f"dynamics must return shape ({n},), got {xdot.shape}")
        xdot_h = None
        if self.hessian_dynamics is not None:
            xdot_h = _as_column(_call(self.hessian_dynamics, "hessian_dynamics", [x, u, p, q], 2),
                                sym, "hessian_dynamics")
            if xdot_h.shape != (n, 1):
                raise ValueError(f"hessian_dynamics must return shape ({n},), got {xdot_h.shape}")
        if self.running_cost is not None:
            lag = _as_column(
                _call(self.running_cost, "running_cost", [x, u, p, q], 2), sym, "running_cost"
            )
        else:
            lag = sym(1, 1)
        if lag.shape != (1, 1):
            raise ValueError(f"running_cost must return a scalar, got shape {lag.shape}")
        if self.path_constraints is not None:
            c = _as_column(
                _call(self.path_constraints, "path_constraints", [x, u, p, q], 2),
                sym,
                "path_constraints",
            )
        else:
            c = sym(0, 1)
        if self.terminal_cost is not None:
            phi = _as_column(
                _call(self.terminal_cost, "terminal_cost", [x0, xf, tf, p], 2),
                sym,
                "terminal_cost",
            )
        else:
            phi = sym(1, 1)
        if phi.shape != (1, 1):
            raise ValueError(f"terminal_cost must return a scalar, got shape {phi.shape}")
        if self.boundary_constraints is not None:
            b = _as_column(
                _call(self.boundary_constraints, "boundary_constraints", [x0, xf, tf, p], 2),
                sym,
                "boundary_constraints",
            )
        else:
            b = sym(0, 1)
        node = ca.Function(
            "gpm_node", [x, u, p, q], [xdot, lag, c], ["x", "u", "p", "q"], ["xdot", "L", "c"]
        )
        node_hessian = None
        if xdot_h is not None:
            node_hessian = ca.Function("gpm_node_hessian", [x, u, p, q], [xdot_h, lag, c],
                                       ["x", "u", "p", "q"], ["xdot", "L", "c"])
        boundary = ca.Function(
            "gpm_boundary", [x0, xf, tf, p], [phi, b], ["x0", "xf", "tf", "p"], ["Phi", "b"]
        )
        return ProblemFunctions(
            node=node, boundary=boundary, n_path=int(c.shape[0]), n_boundary=int(b.shape[0]),
            node_hessian=node_hessian,
        )
