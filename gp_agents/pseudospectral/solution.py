"""Solutions and initial guesses of the Gauss pseudospectral transcription.

Paper section "Gauss Pseudospectral Optimal Control", subsection "State, Control, and Costate
Approximation" (eq. state): within each mesh interval the state is the degree-K Lagrange
interpolant over the K + 1 support points ``{tau_0 = -1, tau_1..tau_K}`` and the control the
degree-(K-1) interpolant over the K Legendre-Gauss nodes. Reference errata note 5: there is no
control decision at t0, so :meth:`OCPSolution.initial_control` states explicitly which control a
receding-horizon controller applies at the current time.

Array conventions: time runs along the first axis, e.g. states are (N, n), controls (M, m).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gp_agents.pseudospectral.nodes import interpolation_matrix, legendre_gauss, support_points

__all__ = ["InitialGuess", "OCPSolution", "TrajectoryLike", "shift_solution"]

FloatArray = NDArray[np.float64]


class TrajectoryLike(Protocol):
    """Anything usable as an initial guess: evaluates a state and a control at given times."""

    @property
    def tf(self) -> float | None:
        """Final time of the trajectory (None: unknown)."""
        ...

    def state(self, t: ArrayLike) -> FloatArray:
        """States at times ``t`` (M,), shape (M, n)."""
        ...

    def control(self, t: ArrayLike) -> FloatArray:
        """Controls at times ``t`` (M,), shape (M, m)."""
        ...


def _as_2d(values: ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{name} must have shape (N, d), got {arr.shape}")
    return arr


def _interp_hold(t_query: FloatArray, t_data: FloatArray, values: FloatArray) -> FloatArray:
    """Piecewise-linear interpolation per column, holding the end values outside the data."""
    if t_data.size == 1:
        return np.repeat(values, t_query.size, axis=0)
    return np.column_stack(
        [np.interp(t_query, t_data, values[:, j]) for j in range(values.shape[1])]
    ).reshape(t_query.size, values.shape[1])


@dataclass(frozen=True)
class InitialGuess:
    """A sampled trajectory used as an initial guess (piecewise-linear between samples).

    Attributes:
        t: (N,) increasing sample times of the state, in time units.
        x: (N, n) states at ``t``.
        t_u: (M,) increasing sample times of the control.
        u: (M, m) controls at ``t_u``.
        tf: final time guess (used when tf is free), or None to keep the problem's guess.
    """

    t: FloatArray
    x: FloatArray
    t_u: FloatArray
    u: FloatArray
    tf: float | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float).ravel()
        t_u = np.asarray(self.t_u, dtype=float).ravel()
        x = _as_2d(self.x, "x")
        u = _as_2d(self.u, "u")
        if x.shape[0] != t.size or u.shape[0] != t_u.size or t.size == 0 or t_u.size == 0:
            raise ValueError(
                f"initial guess: x {x.shape} / u {u.shape} must have one row per time "
                f"(t: {t.size}, t_u: {t_u.size}), at least one sample each"
            )
        for name, arr in (("t", t), ("x", x), ("t_u", t_u), ("u", u)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"initial guess {name} contains NaN or inf")
        if np.any(np.diff(t) < 0) or np.any(np.diff(t_u) < 0):
            raise ValueError("initial guess times must be non-decreasing")
        if self.tf is not None and not np.isfinite(self.tf):
            raise ValueError("initial guess tf must be finite")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "t_u", t_u)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "u", u)

    def state(self, t: ArrayLike) -> FloatArray:
        """Linearly interpolated states at ``t`` (M,), shape (M, n); ends are held."""
        return _interp_hold(np.atleast_1d(np.asarray(t, dtype=float)).ravel(), self.t, self.x)

    def control(self, t: ArrayLike) -> FloatArray:
        """Linearly interpolated controls at ``t`` (M,), shape (M, m); ends are held."""
        return _interp_hold(np.atleast_1d(np.asarray(t, dtype=float)).ravel(), self.t_u, self.u)


@dataclass(frozen=True)
class OCPSolution:
    """Result of one Gauss pseudospectral solve (successful or not).

    With S mesh intervals of K_s nodes each, N = sum_s (K_s + 1) + 1 state points and
    M = sum_s K_s nodes.

    Attributes:
        t0, tf: initial and final time of the horizon (tf is the optimised value if free).
        t: (N,) state times: for each interval its K + 1 support points, then tf.
        x: (N, n) states at ``t``; ``x[-1]`` is the terminal state X_f.
        t_nodes: (M,) collocation (LG node) times.
        u: (M, m) controls at the nodes.
        cost: objective value J (Mayer + Gauss-quadrature Lagrange term).
        success: True if the NLP solver reported convergence and the result is finite.
        status: solver return status string (e.g. 'Solve_Succeeded', 'Infeasible_Problem_Detected',
            'Maximum_Iterations_Exceeded', or 'Exception: ...' if the solver raised).
        iterations: NLP iterations (-1 if unknown).
        solve_time: wall-clock time of the NLP solve in seconds.
        costate: (M, n) costate estimate at the nodes (Benson 2006 / Garg 2010 mapping of the
            defect and quadrature multipliers), units of cost per unit state.
        costate_initial: (n,) costate estimate at t0.
        costate_final: (n,) costate estimate at tf (from the last quadrature multiplier).
        nodes_per_interval: (S,) K_s, LG nodes of each interval.
        interval_times: (S + 1,) mesh interval boundaries in time.
        u_lb, u_ub: (m,) control bounds, used for clipping.
        p: (n_p,) parameter vector the problem was solved with.
        stats: raw CasADi solver statistics.
        nlp_x, nlp_lam_x, nlp_lam_g: raw NLP primal and dual vectors, used for warm starts.
        structure: hashable identity of the transcription that produced this solution.
    """

    t0: float
    tf: float
    t: FloatArray
    x: FloatArray
    t_nodes: FloatArray
    u: FloatArray
    cost: float
    success: bool
    status: str
    iterations: int
    solve_time: float
    costate: FloatArray
    costate_initial: FloatArray
    costate_final: FloatArray
    nodes_per_interval: tuple[int, ...]
    interval_times: FloatArray
    u_lb: FloatArray
    u_ub: FloatArray
    p: FloatArray
    stats: dict[str, Any] = field(repr=False, default_factory=dict)
    nlp_x: FloatArray | None = field(repr=False, default=None)
    nlp_lam_x: FloatArray | None = field(repr=False, default=None)
    nlp_lam_g: FloatArray | None = field(repr=False, default=None)
    structure: tuple[Any, ...] | None = field(repr=False, default=None)

    # ------------------------------------------------------------------ basic views
    @property
    def n_intervals(self) -> int:
        """Number of mesh intervals S."""
        return int(self.interval_times.size - 1)

    @property
    def _point_offset(self) -> np.ndarray:
        """(S + 1,) index of each interval's first support point (the last: X_f's)."""
        return np.concatenate([[0], np.cumsum([K + 1 for K in self.nodes_per_interval])])

    @property
    def _node_offset(self) -> np.ndarray:
        """(S + 1,) index of each interval's first node (the last: M)."""
        return np.concatenate([[0], np.cumsum(self.nodes_per_interval)])

    @property
    def x_nodes(self) -> FloatArray:
        """States at the collocation nodes ``t_nodes`` (support points 1..K_s of each
        interval), shape (M, n): the points where the dynamics were enforced."""
        off = self._point_offset
        rows = [int(off[s]) + k for s, K in enumerate(self.nodes_per_interval)
                for k in range(1, K + 1)]
        return self.x[rows].copy()

    @property
    def x_final(self) -> FloatArray:
        """Terminal state X_f, shape (n,)."""
        return self.x[-1].copy()

    @property
    def x_initial(self) -> FloatArray:
        """Initial state X_0, shape (n,)."""
        return self.x[0].copy()

    def _segments(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Interval index (M,) and local tau in [-1, 1] (M,) of times clamped to [t0, tf]."""
        tc = np.clip(t, self.t0, self.tf)
        edges = self.interval_times
        seg = np.clip(np.searchsorted(edges, tc, side="right") - 1, 0, self.n_intervals - 1)
        a, b = edges[seg], edges[seg + 1]
        tau = 2.0 * (tc - a) / (b - a) - 1.0
        return seg, np.clip(tau, -1.0, 1.0)

    # ------------------------------------------------------------------ interpolation
    def state(self, t: ArrayLike) -> FloatArray:
        """State interpolant at arbitrary times (paper eq. state).

        Lagrange interpolation of degree K over the K + 1 support points of the interval that
        contains each time. Times outside [t0, tf] are clamped (the end states are held).

        Args:
            t: times, scalar or shape (M,).

        Returns:
            States, shape (n,) for a scalar ``t``, else (M, n).
        """
        scalar = np.ndim(t) == 0
        tq = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
        out = np.empty((tq.size, self.x.shape[1]))
        seg, tau = self._segments(tq)
        off = self._point_offset
        for s in np.unique(seg):
            idx = seg == s
            values = self.x[off[s] : off[s + 1]]
            support = support_points(self.nodes_per_interval[s])
            out[idx] = interpolation_matrix(support, tau[idx]) @ values
        out[tq >= self.tf] = self.x[-1]
        return out[0] if scalar else out

    def control(self, t: ArrayLike) -> FloatArray:
        """Control interpolant at arbitrary times.

        Lagrange interpolation of degree K - 1 over the K LG nodes of the interval containing
        each time. Between an interval's end and its first/last node this is extrapolation (the
        LG nodes are interior); times outside [t0, tf] are clamped. Values are *not* clipped to
        the control bounds here (see :meth:`initial_control`).

        Args:
            t: times, scalar or shape (M,).

        Returns:
            Controls, shape (m,) for a scalar ``t``, else (M, m).
        """
        scalar = np.ndim(t) == 0
        tq = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
        out = np.empty((tq.size, self.u.shape[1]))
        seg, tau = self._segments(tq)
        off = self._node_offset
        for s in np.unique(seg):
            idx = seg == s
            nodes, _ = legendre_gauss(self.nodes_per_interval[s])
            out[idx] = interpolation_matrix(nodes, tau[idx]) @ self.u[off[s] : off[s + 1]]
        return out[0] if scalar else out

    def initial_control(
        self,
        method: Literal["extrapolate", "first_node"] = "extrapolate",
        clip: bool = True,
    ) -> FloatArray:
        """The control to apply at t0 (reference errata note 5).

        The LG method has no control decision at ``tau_0 = -1``. Two readings are offered:

        * ``"extrapolate"`` (default): the Lagrange interpolant of the first interval's K node
          controls evaluated at t0 (polynomial extrapolation, consistent with the dynamics the
          NLP enforced near t0);
        * ``"first_node"``: the control at the first LG node ``tau_1`` (a zero-order hold of the
          nearest decision).

        Args:
            method: ``"extrapolate"`` or ``"first_node"``.
            clip: clip the result to the control bounds (extrapolation can overshoot them).

        Returns:
            Control, shape (m,).
        """
        if method == "extrapolate":
            u0 = self.control(self.t0)
        elif method == "first_node":
            u0 = self.u[0].copy()
        else:
            raise ValueError(f"method must be 'extrapolate' or 'first_node', got {method!r}")
        if clip:
            u0 = np.clip(u0, self.u_lb, self.u_ub)
        return u0

    def costate_times(self) -> FloatArray:
        """Times of :attr:`costate`, i.e. :attr:`t_nodes`, shape (M,)."""
        return self.t_nodes.copy()

    # ------------------------------------------------------------------ warm starts
    def shift(self, dt: float) -> InitialGuess:
        """This solution advanced by ``dt`` in time, as an initial guess on the same horizon.

        See :func:`shift_solution`.
        """
        return shift_solution(self, dt)


def shift_solution(solution: OCPSolution, dt: float) -> InitialGuess:
    """Shift a solution by a time delta, for a receding-horizon warm start.

    The guess has the same horizon [t0, tf] and sample times as ``solution``; its value at time
    ``t`` is the solution's Lagrange interpolant at ``t + dt``. Beyond the horizon the last values
    are held: the terminal state X_f and the control at the last LG node. Controls are clipped to
    the bounds.

    Args:
        solution: a solution (typically the previous MPC solve).
        dt: time shift, >= 0, in time units (e.g. the control period).

    Returns:
        An :class:`InitialGuess` sampled at ``solution.t`` (states) and ``solution.t_nodes``
        (controls), with ``tf = solution.tf``.
    """
    dt = float(dt)
    if not np.isfinite(dt) or dt < 0:
        raise ValueError(f"shift dt must be finite and >= 0, got {dt}")
    x = solution.state(np.minimum(solution.t + dt, solution.tf))
    t_last_node = solution.t_nodes[-1]
    u = solution.control(np.minimum(solution.t_nodes + dt, t_last_node))
    u = np.clip(u, solution.u_lb, solution.u_ub)
    return InitialGuess(t=solution.t.copy(), x=x, t_u=solution.t_nodes.copy(), u=u, tf=solution.tf)
