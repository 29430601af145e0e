"""Gauss pseudospectral transcription of a Bolza problem to a parametric CasADi NLP, and its solve.

Paper section "Gauss Pseudospectral Optimal Control", subsection "Gauss Pseudospectral
Discretization of the Continuous Bolza Problem", eqs. (DBP), (AC), (QC), (PC), with the standard
LG reading (Benson et al. 2006; Garg et al. 2010; reference errata note 5). The horizon
[t0, tf] is split into S mesh intervals [a_s, b_s] (S = 1 is the paper's global method); each
has K LG nodes, ``h_s = (b_s - a_s) / 2`` and decision variables

* ``X_{s,0..K}`` (n each): the state at the support points ``tau_0 = -1, tau_1..tau_K``;
* ``U_{s,1..K}`` (m each): the control at the nodes, or, in a *held* interval, one control
  ``U_s`` shared by all its nodes (a zero-order hold: the control a sampled-data plant applies
  over a control period). The Lagrange interpolant of equal node values is that constant, so a
  held interval's dynamics are collocated under exactly the control the plant will hold.

The node count may differ per interval (``n_nodes`` a sequence, ``K_s``).

The end point of interval s *is* the start point X_{s+1,0} of the next one (state continuity by
shared variables), and after the last interval comes X_f. Constraints, in this order in ``g``:

1. defects (AC): ``sum_i D[k, i] X_{s,i} - h_s f(X_{s,k}, U_{s,k}, p) = 0``, (S K n);
2. quadrature (QC): ``X_{s+1,0} - X_{s,0} - h_s sum_k w_k f(X_{s,k}, U_{s,k}, p) = 0``, (S n);
3. path constraints (PC) at every node, (S K n_c);
4. path constraints at the end point of every held interval (a control period's boundary,
   under that period's control), (H n_c);
5. boundary constraints ``b(X_0, X_f, tf, p)``, (n_b).

Cost (DBP): ``Phi(X_0, X_f, tf, p) + sum_s h_s sum_k w_k L(X_{s,k}, U_{s,k}, p)``.

Costate estimate (Garg et al. 2010, Thm. 1, written for CasADi's multiplier convention
``grad f + J_g' lam_g + lam_x = 0``, which IPOPT and sqpmethod results follow in CasADi):
with nu_{s,k} the defect multipliers and nu_{s,f} the quadrature multipliers,

    lambda(t_{s,k}) = -(nu_{s,k} / w_k + nu_{s,f}),     lambda(b_s) = -nu_{s,f},
    lambda(t0) = -nu_{1,f} + sum_k D[k, 0] nu_{1,k}.

These follow from the NLP stationarity conditions by discrete integration by parts; the last
line is the transversality condition lambda(t0) = -dPhi/dx0 - (initial-bound multiplier).
"""

from __future__ import annotations

import copy
import dataclasses
import time
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from gp_agents.pseudospectral.buffered import BufferedFunction
from gp_agents.pseudospectral.nodes import differentiation_matrix, legendre_gauss, support_points
from gp_agents.pseudospectral.problem import OptimalControlProblem
from gp_agents.pseudospectral.solution import (
    InitialGuess,
    OCPSolution,
    TrajectoryLike,
    shift_solution,
)

__all__ = ["IPOPT_WARM_START_OPTIONS", "GaussPseudospectralSolver", "default_solver_options"]

FloatArray = NDArray[np.float64]

_QUIET_QPSOL: dict[str, dict[str, Any]] = {
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False},
    "qpoases": {"printLevel": "none"},
    "osqp": {"osqp": {"verbose": False}},
    "highs": {"highs": {"output_flag": False}},
    "proxqp": {},
    "daqp": {},
}


IPOPT_WARM_START_OPTIONS: dict[str, Any] = {
    "ipopt": {
        "warm_start_init_point": "yes",
        "mu_init": 1e-6,
        "warm_start_bound_push": 1e-9,
        "warm_start_mult_bound_push": 1e-9,
    }
}
"""IPOPT options that make it use the multipliers of a previous solution (``lam_x0``/``lam_g0``)
and start with a small barrier parameter. Pass as ``solver_options`` when most solves are
re-solves from a previous solution of the same solver (MPC); cold solves may take a few more
iterations with them."""


def _deep_merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, val in extra.items():
        if isinstance(val, Mapping) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], val)
        else:
            out[key] = copy.deepcopy(val)
    return out


def default_solver_options(solver: str, user: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Quiet default CasADi ``nlpsol`` options for ``solver``, deep-merged with ``user``.

    * ``'ipopt'``: ``print_level 0``, no banner, ``print_time False``.
    * ``'sqpmethod'``: exact Hessian, ``qpsol='qrqp'`` unless given, all printing off (also for the
      QP solvers qrqp, qpoases, osqp, highs).
    * anything else: ``print_time False`` only.

    Args:
        solver: CasADi nlpsol plugin name.
        user: options in CasADi's nested format, e.g. ``{"ipopt": {"max_iter": 50}}``.

    Returns:
        The merged options dictionary.
    """
    user = dict(user or {})
    base: dict[str, Any] = {"print_time": False, "error_on_fail": False}
    if solver == "ipopt":
        base["ipopt"] = {"print_level": 0, "sb": "yes"}
    elif solver == "sqpmethod":
        qpsol = str(user.get("qpsol", "qrqp"))
        base.update(
            {
                "qpsol": qpsol,
                "print_header": False,
                "print_iteration": False,
                "print_status": False,
                "qpsol_options": _deep_merge({"error_on_fail": False}, _QUIET_QPSOL.get(qpsol, {})),
            }
        )
    return _deep_merge(base, user)


class _MeshLayout:
    """Index bookkeeping of a mesh with per-interval node counts and held controls.

    Args:
        counts: (S,) LG nodes K_s per interval. hold: (S,) held-control flags.
    """

    def __init__(self, counts: Sequence[int], hold: Sequence[bool]) -> None:
        self.counts = [int(K) for K in counts]
        rules = [legendre_gauss(K) for K in self.counts]
        self.tau = [tau for tau, _ in rules]
        self.weights = [w for _, w in rules]
        self.support = [support_points(K) for K in self.counts]
        self.D = [differentiation_matrix(K) for K in self.counts]
        self.point_offset = np.concatenate([[0], np.cumsum([K + 1 for K in self.counts])])
        """(S + 1,) index of each interval's first support point; the last entry is X_f's."""
        self.node_offset = np.concatenate([[0], np.cumsum(self.counts)])
        """(S + 1,) index of each interval's first node; the last entry is M."""
        self.n_points = int(self.point_offset[-1]) + 1
        self.n_nodes = int(self.node_offset[-1])
        S = len(self.counts)
        self.node_cols = [int(self.point_offset[s]) + k for s in range(S)
                          for k in range(1, self.counts[s] + 1)]
        self.start_cols = [int(c) for c in self.point_offset[:-1]]
        self.end_cols = [int(c) for c in self.point_offset[1:]]
        index, decisions, column = [], [], 0
        for K, held in zip(self.counts, hold, strict=True):
            decisions.append(column)
            index.extend([column] * K if held else range(column, column + K))
            column += 1 if held else K
        self.control_index = np.array(index, dtype=int)
        """(M,) control decision of each node."""
        self.n_control_decisions = column
        self.held_intervals = [s for s in range(S) if hold[s]]
        self.held_decisions = [decisions[s] for s in self.held_intervals]
        self.held_end_cols = [self.end_cols[s] for s in self.held_intervals]
        self.held_last_nodes = [int(self.node_offset[s + 1]) - 1 for s in self.held_intervals]


class GaussPseudospectralSolver:
    """Builds the LG pseudospectral NLP of a problem once and solves it many times.

    Everything that may change between solves is an input of the CasADi NLP solver, not a
    rebuild: the parameter vector ``p`` (NLP parameter), the initial state (bounds of X_0) and the
    initial guess / multipliers (warm start).

    Example:
        >>> solver = GaussPseudospectralSolver(problem, n_nodes=10)   # doctest: +SKIP
        >>> sol = solver.solve(p=p0)                                  # doctest: +SKIP
        >>> sol = solver.solve(p=p1, x0=x_now, initial_guess=sol.shift(0.05))  # doctest: +SKIP

    Args:
        problem: the optimal control problem.
        n_nodes: K, LG nodes per mesh interval (>= 1), or one count per interval (then the
            number of intervals is its length, and ``n_intervals`` is ignored).
        n_intervals: S, number of equal mesh intervals (ignored if ``mesh`` is given).
        mesh: optional (S + 1,) increasing interval boundaries as fractions of the horizon,
            from 0 to 1 (e.g. ``[0, 0.2, 1]``).
        hold: optional (S,) flags: ``True`` makes an interval's control one decision held over
            the whole interval (zero-order hold), with the path constraints also enforced at
            its end point. Default: no held interval (the paper's polynomial control).
        solver: CasADi nlpsol plugin: ``'ipopt'`` (default), ``'sqpmethod'``, ``'fatrop'``, ...
        solver_options: CasADi options (nested format) merged over quiet defaults, see
            :func:`default_solver_options`.
        expand: expand the MX graph to SX before solving (faster evaluation). Default: True if
            the problem's callables could be evaluated with SX symbols, else False (e.g. external
            functions or callbacks).
        jit: compile the NLP functions to C with the system compiler (CasADi JIT, opt-in).
            Compilation costs ~1 s or more once at construction; evaluation gets faster.
        jit_flags: compiler flags for JIT (default ``["-O1"]``).
    """

    def __init__(
        self,
        problem: OptimalControlProblem,
        n_nodes: int | Sequence[int] = 10,
        n_intervals: int = 1,
        mesh: Sequence[float] | None = None,
        solver: str = "ipopt",
        solver_options: Mapping[str, Any] | None = None,
        expand: bool | None = None,
        jit: bool = False,
        jit_flags: Sequence[str] | None = None,
        hold: Sequence[bool] | None = None,
    ) -> None:
        if not isinstance(problem, OptimalControlProblem):
            raise ValueError("problem must be an OptimalControlProblem")
        per_interval = not isinstance(n_nodes, (int, np.integer))
        counts = list(n_nodes) if per_interval else [n_nodes]  # type: ignore[arg-type]
        for K in counts:
            if isinstance(K, bool) or not isinstance(K, (int, np.integer)) or K < 1:
                raise ValueError(f"n_nodes must be integers >= 1, got {n_nodes!r}")
        if per_interval and mesh is None:
            if not counts:
                raise ValueError("n_nodes must not be empty")
            n_intervals = len(counts)
        if mesh is None:
            if (
                isinstance(n_intervals, bool)
                or not isinstance(n_intervals, (int, np.integer))
                or n_intervals < 1
            ):
                raise ValueError(f"n_intervals must be an integer >= 1, got {n_intervals!r}")
            mesh_arr = np.linspace(0.0, 1.0, int(n_intervals) + 1)
        else:
            mesh_arr = np.asarray(mesh, dtype=float).ravel()
            if (
                mesh_arr.size < 2
                or not np.all(np.isfinite(mesh_arr))
                or mesh_arr[0] != 0.0
                or mesh_arr[-1] != 1.0
                or np.any(np.diff(mesh_arr) <= 0.0)
            ):
                raise ValueError(
                    "mesh must be strictly increasing fractions of the horizon from 0 to 1, "
                    f"got {mesh_arr}"
                )
        S = int(mesh_arr.size - 1)
        if not per_interval:
            counts = counts * S
        if len(counts) != S:
            raise ValueError(f"n_nodes has {len(counts)} entries for {S} mesh intervals")
        held = [False] * S if hold is None else [bool(h) for h in hold]
        if len(held) != S:
            raise ValueError(f"hold has {len(held)} entries for {S} mesh intervals")
        if not ca.has_nlpsol(solver):
            raise ValueError(f"CasADi NLP solver plugin {solver!r} is not available")

        self.problem = problem
        self.nodes_per_interval: tuple[int, ...] = tuple(int(K) for K in counts)
        """K_s, LG nodes of each mesh interval, (S,)."""
        self.hold: tuple[bool, ...] = tuple(held)
        """Whether each interval's control is one held decision, (S,)."""
        self.mesh = mesh_arr
        self.n_intervals = S
        self.solver_name = solver
        if expand is None:
            expand = problem.functions().node.is_a("SXFunction")
        self.expand = bool(expand)
        self.jit = bool(jit)
        opts = default_solver_options(solver, solver_options)
        if self.jit:
            opts = _deep_merge(
                {
                    "jit": True,
                    "compiler": "shell",
                    "jit_options": {"flags": list(jit_flags or ["-O1"]), "verbose": False},
                },
                opts,
            )
        self.solver_options = opts

        self._layout = _MeshLayout(self.nodes_per_interval, self.hold)
        # Fraction of the horizon at which each support point / node lies: (N,), (M,)
        frac_a, frac_len = mesh_arr[:-1], np.diff(mesh_arr)
        lay = self._layout
        self._frac_support = np.concatenate(
            [frac_a[s] + 0.5 * (lay.support[s] + 1.0) * frac_len[s] for s in range(S)] + [[1.0]]
        )
        self._frac_nodes = np.concatenate(
            [frac_a[s] + 0.5 * (lay.tau[s] + 1.0) * frac_len[s] for s in range(S)]
        )
        self._frac_len = frac_len
        self._structure = (id(self), self.nodes_per_interval, self.hold, tuple(mesh_arr.tolist()))
        self._build()

    # ------------------------------------------------------------------ sizes
    @property
    def n_states(self) -> int:
        """State dimension n."""
        return self.problem.n_states

    @property
    def n_controls(self) -> int:
        """Control dimension m."""
        return self.problem.n_controls

    @property
    def n_points(self) -> int:
        """Number N = sum_s (K_s + 1) + 1 of state points (support points of all intervals, plus
        X_f)."""
        return self._layout.n_points

    @property
    def n_collocation(self) -> int:
        """Number M = sum_s K_s of collocation nodes."""
        return self._layout.n_nodes

    @property
    def n_control_decisions(self) -> int:
        """Number of control decisions (m each): one per node of a free interval, one per held
        interval."""
        return self._layout.n_control_decisions

    @property
    def n_variables(self) -> int:
        """Number of NLP decision variables."""
        return int(self._nlp_x_size)

    @property
    def n_constraints(self) -> int:
        """Number of NLP constraints."""
        return int(self._nlp_g_size)

    def state_times(self, tf: float | None = None) -> FloatArray:
        """Times of the N state points for a given tf (default: fixed tf or tf guess), (N,)."""
        tf = self._tf_value(tf)
        return self.problem.t0 + (tf - self.problem.t0) * self._frac_support

    def node_times(self, tf: float | None = None) -> FloatArray:
        """Times of the M collocation nodes for a given tf, (M,)."""
        tf = self._tf_value(tf)
        return self.problem.t0 + (tf - self.problem.t0) * self._frac_nodes

    def _tf_value(self, tf: float | None) -> float:
        pb = self.problem
        if pb.tf is not None:
            return pb.tf
        if tf is not None:
            return float(tf)
        if pb.tf_guess is not None:
            return pb.tf_guess
        lo, hi = pb.tf_bounds
        if np.isfinite(hi):
            return 0.5 * (lo + hi) if lo > pb.t0 else pb.t0 + 0.5 * (hi - pb.t0)
        return max(lo, pb.t0 + 1.0)

    # ------------------------------------------------------------------ NLP construction
    def _build(self) -> None:
        pb = self.problem
        fns = pb.functions()
        n, m, n_p = pb.n_states, pb.n_controls, pb.n_params
        lay, S = self._layout, self.n_intervals
        N, M = self.n_points, self.n_collocation

        X = ca.MX.sym("X", n, N)
        U_dec = ca.MX.sym("U", m, lay.n_control_decisions)
        U = U_dec[:, lay.control_index.tolist()]  # (m, M): held intervals share one column
        n_q = pb.n_node_params
        # NLP parameter: [p; vec(Q)] with Q (n_q, M) the per-node parameters, node k's contiguous
        P_all = ca.MX.sym("p", n_p + n_q * M)
        P = P_all[:n_p]
        Q = ca.reshape(P_all[n_p:], n_q, M)
        if pb.free_final_time:
            tf_sym = ca.MX.sym("tf")
            tf_expr: ca.MX = tf_sym
            w = ca.vertcat(ca.vec(X), ca.vec(U_dec), tf_sym)
        else:
            tf_expr = ca.MX(pb.tf)
            w = ca.vertcat(ca.vec(X), ca.vec(U_dec))

        # Half interval lengths h_s per node column: (1, M); h_s = (tf - t0)/2 * frac_len_s.
        half_span = 0.5 * (tf_expr - pb.t0)
        h_row = half_span * ca.DM(np.repeat(self._frac_len, lay.counts)[None, :])

        # Block-diagonal differentiation and quadrature matrices (sparse constants).
        rows, cols, vals = [], [], []
        for s in range(S):
            K, D = lay.counts[s], lay.D[s]
            for k in range(K):
                for i in range(K + 1):
                    rows.append(lay.point_offset[s] + i)
                    cols.append(lay.node_offset[s] + k)
                    vals.append(D[k, i])
        D_big = ca.DM(ca.Sparsity.triplet(N, M, rows, cols), vals)
        node_weights = np.concatenate(lay.weights)
        q_cols = np.repeat(np.arange(S), lay.counts).tolist()
        W_big = ca.DM(ca.Sparsity.triplet(M, S, list(range(M)), q_cols), node_weights)
        node_cols, start_cols, end_cols = lay.node_cols, lay.start_cols, lay.end_cols
        n_held = len(lay.held_intervals)

        def transcribe(node: ca.Function) -> tuple[ca.MX, ca.MX]:
            """Cost and constraints with dynamics, running cost and path constraints evaluated
            at all M nodes through one mapped call of ``node``."""
            F, L, C = node.map(M)(X[:, node_cols], U, ca.repmat(P, 1, M), Q)
            hF = F * ca.repmat(h_row, n, 1)  # (n, M): h_s f at the nodes
            defects = ca.mtimes(X, D_big) - hF  # paper eq. (AC)
            quadrature = X[:, end_cols] - X[:, start_cols] - ca.mtimes(hF, W_big)  # eq. (QC)
            phi, b = fns.boundary(X[:, 0], X[:, N - 1], tf_expr, P)
            cost = phi + ca.mtimes(L * h_row, ca.DM(node_weights))  # eq. (DBP)
            C_end = ca.MX(0, 1)
            if n_held:  # path constraints at held intervals' end points, under their control
                _, _, C_end = node.map(n_held)(
                    X[:, lay.held_end_cols], U_dec[:, lay.held_decisions],
                    ca.repmat(P, 1, n_held), Q[:, lay.held_last_nodes])
            return cost, ca.vertcat(ca.vec(defects), ca.vec(quadrature), ca.vec(C),
                                    ca.vec(C_end), b)

        cost, g = transcribe(fns.node)
        self._nlp_x_size = int(w.shape[0])
        self._nlp_g_size = int(g.shape[0])
        self._n_defect = n * M
        self._n_quad = n * S

        # Constant bounds (the X_0 block is overwritten per solve if x0 is given).
        lbx_X = np.tile(pb.x_lb[:, None], (1, N))
        ubx_X = np.tile(pb.x_ub[:, None], (1, N))
        lbx_X[:, 0], ubx_X[:, 0] = pb.x0_lb, pb.x0_ub
        lbx_X[:, -1], ubx_X[:, -1] = pb.xf_lb, pb.xf_ub
        lbx = [lbx_X.ravel(order="F"), np.tile(pb.u_lb, lay.n_control_decisions)]
        ubx = [ubx_X.ravel(order="F"), np.tile(pb.u_ub, lay.n_control_decisions)]
        if pb.free_final_time:
            lbx.append([pb.tf_bounds[0]])
            ubx.append([pb.tf_bounds[1]])
        self._lbx = np.concatenate(lbx).astype(float)
        self._ubx = np.concatenate(ubx).astype(float)
        zeros = np.zeros(n * M + n * S)
        self._lbg = np.concatenate([zeros, np.tile(pb.path_lb, M + n_held), pb.boundary_lb])
        self._ubg = np.concatenate([zeros, np.tile(pb.path_ub, M + n_held), pb.boundary_ub])

        nlp = {"x": w, "p": P_all, "f": cost, "g": g}
        self._nlp = nlp
        opts = dict(self.solver_options)
        opts.setdefault("expand", self.expand)
        if fns.node_hessian is not None and "hess_lag" not in opts:
            # Lagrangian Hessian of the same NLP with the problem's hessian_dynamics: the
            # multipliers are the true NLP's, the second derivatives the approximation's.
            cost_h, g_h = transcribe(fns.node_hessian)
            lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.shape[0])
            lagrangian = lam_f * cost_h + ca.dot(lam_g, g_h)
            hess = ca.triu(ca.hessian(lagrangian, w)[0])
            hess_lag = ca.Function("gpm_hess_lag", [w, P_all, lam_f, lam_g], [hess],
                                   ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
            opts["hess_lag"] = hess_lag.expand() if self.expand else hess_lag
        self._solver = ca.nlpsol("gpm_nlp", self.solver_name, nlp, opts)
        self._buffered_solver = BufferedFunction(self._solver)

    # ------------------------------------------------------------------ initial guesses
    def _default_guess(self, x0: FloatArray | None) -> tuple[FloatArray, FloatArray, float]:
        """Straight line from the initial to the terminal state, mid-range controls."""
        pb = self.problem

        def _mid(lb: FloatArray, ub: FloatArray, fallback: FloatArray) -> FloatArray:
            out = fallback.copy()
            both = np.isfinite(lb) & np.isfinite(ub)
            out[both] = 0.5 * (lb[both] + ub[both])
            out = np.where(np.isfinite(lb) & ~np.isfinite(ub), np.maximum(out, lb), out)
            out = np.where(~np.isfinite(lb) & np.isfinite(ub), np.minimum(out, ub), out)
            return out

        start = x0 if x0 is not None else _mid(pb.x0_lb, pb.x0_ub, np.zeros(pb.n_states))
        end = _mid(pb.xf_lb, pb.xf_ub, start)
        frac = self._frac_support[:, None]
        X = (1.0 - frac) * start[None, :] + frac * end[None, :]
        u_mid = _mid(pb.u_lb, pb.u_ub, np.zeros(pb.n_controls))
        U = np.tile(u_mid, (self.n_collocation, 1))
        return X, U, self._tf_value(None)

    def _guess_from(self, guess: TrajectoryLike) -> tuple[FloatArray, FloatArray, float]:
        tf = self._tf_value(getattr(guess, "tf", None))
        X = np.asarray(guess.state(self.state_times(tf)), dtype=float)
        U = np.asarray(guess.control(self.node_times(tf)), dtype=float)
        if X.shape != (self.n_points, self.n_states):
            raise ValueError(
                f"initial guess state has {X.shape[-1]} components, expected {self.n_states}"
            )
        if U.shape != (self.n_collocation, self.n_controls):
            raise ValueError(
                f"initial guess control has {U.shape[-1]} components, expected {self.n_controls}"
            )
        return X, U, tf

    def _pack(self, X: FloatArray, U: FloatArray, tf: float) -> FloatArray:
        """NLP primal vector from node states X (N, n) and node controls U (M, m); a held
        interval's decision is the mean of its nodes' controls."""
        lay = self._layout
        U_dec = np.zeros((lay.n_control_decisions, U.shape[1]))
        np.add.at(U_dec, lay.control_index, U)
        U_dec /= np.bincount(lay.control_index, minlength=lay.n_control_decisions)[:, None]
        parts = [X.T.ravel(order="F"), U_dec.T.ravel(order="F")]
        if self.problem.free_final_time:
            parts.append([tf])
        return np.concatenate(parts)

    # ------------------------------------------------------------------ solve
    def solve(
        self,
        p: ArrayLike | None = None,
        x0: ArrayLike | None = None,
        initial_guess: OCPSolution | InitialGuess | TrajectoryLike | None = None,
        warm_start_multipliers: bool = True,
        node_params: ArrayLike | None = None,
        multipliers: tuple[ArrayLike, ArrayLike] | None = None,
    ) -> OCPSolution:
        """Solve the NLP for one parameter value.

        A failed solve (infeasible, iteration limit, NaN during evaluation, solver exception)
        returns an :class:`OCPSolution` with ``success=False`` and the status string; it does not
        raise.

        Args:
            p: parameter vector (n_p,); required iff the problem declares ``n_params > 0``.
            x0: if given, fixes the initial state X(t0) = x0 (n,) for this solve, replacing the
                problem's initial-state bounds (no rebuild: these are NLP variable bounds). It is
                not checked against the state bounds (a measured state may violate them).
            initial_guess: None (straight-line default guess), a previous :class:`OCPSolution`
                (its interpolant is sampled; if it comes from this solver its raw primal and dual
                vectors are reused exactly), an :class:`InitialGuess` (e.g. ``sol.shift(dt)``),
                or any object with ``state(t)``, ``control(t)`` and ``tf``.
            warm_start_multipliers: pass the multipliers of a previous solution of this solver as
                ``lam_x0`` / ``lam_g0`` (used by IPOPT only with ``warm_start_init_point yes``).
            node_params: (M, n_q) per-node parameters, row k for the collocation node at
                ``node_times()[k]``; required iff the problem declares ``n_node_params > 0``.
            multipliers: ``(lam_x (n_w,), lam_g (n_g,))`` to start from with any initial guess
                (e.g. a previous solution's, with the guess shifted in time); ignored if not
                finite. IPOPT uses them only with ``warm_start_init_point yes``.

        Returns:
            The solution.

        Raises:
            ValueError: wrong shapes, or NaN/inf in ``p``, ``x0`` or the initial guess.
        """
        pb = self.problem
        n = pb.n_states
        if p is None:
            if pb.n_params:
                raise ValueError(f"this problem declares n_params={pb.n_params}: pass p")
            p_arr = np.zeros(0)
        else:
            p_arr = np.asarray(p, dtype=float).ravel()
            if p_arr.size != pb.n_params:
                raise ValueError(f"p must have {pb.n_params} entries, got {p_arr.size}")
            if not np.all(np.isfinite(p_arr)):
                raise ValueError(f"p contains NaN or inf: {p_arr}")
        n_q, M = pb.n_node_params, self.n_collocation
        if node_params is None:
            if n_q:
                raise ValueError(f"this problem declares n_node_params={n_q}: pass node_params")
            q_arr = np.zeros(0)
        else:
            q_arr = np.asarray(node_params, dtype=float)
            if q_arr.shape != (M, n_q) and not (n_q == 1 and q_arr.shape == (M,)):
                raise ValueError(f"node_params must have shape ({M}, {n_q}), got {q_arr.shape}")
            if not np.all(np.isfinite(q_arr)):
                raise ValueError("node_params contains NaN or inf")
            q_arr = q_arr.ravel()
        x0_arr: FloatArray | None = None
        if x0 is not None:
            x0_arr = np.asarray(x0, dtype=float).ravel()
            if x0_arr.size != n:
                raise ValueError(f"x0 must have {n} entries, got {x0_arr.size}")
            if not np.all(np.isfinite(x0_arr)):
                raise ValueError(f"x0 contains NaN or inf: {x0_arr}")

        lbx, ubx = self._lbx.copy(), self._ubx.copy()
        if x0_arr is not None:
            lbx[:n] = x0_arr
            ubx[:n] = x0_arr

        args: dict[str, Any] = {"p": np.concatenate([p_arr, q_arr]), "lbg": self._lbg,
                                "ubg": self._ubg}
        if (
            isinstance(initial_guess, OCPSolution)
            and initial_guess.structure == self._structure
            and initial_guess.nlp_x is not None
            and np.all(np.isfinite(initial_guess.nlp_x))
        ):
            # Same transcription: reuse the raw primal (and dual) vectors exactly.
            w0 = initial_guess.nlp_x.copy()
            if warm_start_multipliers and initial_guess.nlp_lam_g is not None:
                lam_g = initial_guess.nlp_lam_g
                lam_x = initial_guess.nlp_lam_x
                if lam_x is not None and np.all(np.isfinite(lam_g)) and np.all(np.isfinite(lam_x)):
                    args["lam_g0"] = lam_g
                    args["lam_x0"] = lam_x
        else:
            if initial_guess is None:
                X, U, tf_guess = self._default_guess(x0_arr)
            else:
                X, U, tf_guess = self._guess_from(initial_guess)
                if not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
                    raise ValueError("initial guess contains NaN or inf")
            w0 = self._pack(X, U, tf_guess)
        if multipliers is not None:
            lam_x, lam_g = (np.asarray(v, float).ravel() for v in multipliers)
            if (lam_x.size, lam_g.size) != (self._nlp_x_size, self._nlp_g_size):
                raise ValueError(f"multipliers must have sizes ({self._nlp_x_size}, "
                                 f"{self._nlp_g_size}), got ({lam_x.size}, {lam_g.size})")
            if np.all(np.isfinite(lam_x)) and np.all(np.isfinite(lam_g)):
                args["lam_x0"], args["lam_g0"] = lam_x, lam_g
        if x0_arr is not None:
            w0[:n] = x0_arr
        # Start inside the bounds (IPOPT would push the point in anyway; sqpmethod would not).
        w0 = np.minimum(np.maximum(w0, lbx), ubx)
        args.update({"x0": w0, "lbx": lbx, "ubx": ubx})

        t_start = time.perf_counter()
        try:  # on numpy memory: no DM conversion of p (a GP's parameters: ~1e5 numbers)
            res: dict[str, Any] | None = self._buffered_solver.call(**args)
            error: str | None = None
        except RuntimeError as err:  # CasADi raises on evaluation errors with some plugins
            res, error = None, str(err).strip().splitlines()[-1] if str(err).strip() else "error"
        solve_time = time.perf_counter() - t_start
        try:
            stats = self._buffered_solver.stats()
        except RuntimeError:  # no stats after an early failure
            stats = {}
        return self._make_solution(res, stats, error, solve_time, p_arr, w0)

    # ------------------------------------------------------------------ the NLP itself
    @property
    def nlp(self) -> dict[str, ca.MX]:
        """The transcribed NLP (MX): decision vector ``x`` (w: states point by point, then the
        control decisions, then tf if free), parameter ``p`` (``[p; vec(Q)]``, node k's ``q``
        contiguous), objective ``f`` and constraints ``g`` (module doc order). For schemes
        that step the NLP themselves (e.g. a real-time iteration's QP)."""
        return self._nlp

    def bounds(self, x0: ArrayLike | None = None) -> tuple[FloatArray, ...]:
        """``(lbx, ubx, lbg, ubg)`` of :attr:`nlp`; ``x0`` (n,) fixes X(t0) as ``solve`` does."""
        lbx, ubx = self._lbx.copy(), self._ubx.copy()
        if x0 is not None:
            lbx[: self.n_states] = ubx[: self.n_states] = np.asarray(x0, float).ravel()
        return lbx, ubx, self._lbg.copy(), self._ubg.copy()

    def control_decision(self, c: int) -> slice:
        """Where control decision ``c`` (m,) lies in w (a held interval's is its one column)."""
        start = self.n_states * self.n_points + self.n_controls * int(c)
        return slice(start, start + self.n_controls)

    def same_transcription(self, solution: OCPSolution) -> bool:
        """Whether ``solution`` came from this transcription or one with the same mesh and
        sizes (e.g. this solver rebuilt after unpickling), so its raw vectors fit this NLP."""
        return (solution.structure is not None and solution.structure[1:] == self._structure[1:]
                and solution.nlp_x is not None and solution.nlp_x.size == self.n_variables)

    def node_indices(self) -> tuple[np.ndarray, np.ndarray]:
        """Where the collocation nodes' states and controls lie in w: integer arrays (M, n)
        and (M, m), so that ``w[ix]`` and ``w[iu]`` are a solution's ``x_nodes`` and ``u``
        (for schemes that evaluate node-wise functions of w inside a compiled step)."""
        n, m, lay = self.n_states, self.n_controls, self._layout
        rows = np.asarray(lay.node_cols, dtype=np.int64)
        ix = rows[:, None] * n + np.arange(n)[None, :]
        iu = (n * self.n_points + m * np.asarray(lay.control_index, dtype=np.int64)[:, None]
              + np.arange(m)[None, :])
        return ix, iu

    def decision_of_node(self, k: int) -> int:
        """The control decision of collocation node ``k``."""
        return int(self._layout.control_index[k])

    def shift_operator(self, dt: float) -> FloatArray:
        """The (n_w, n_w) matrix that maps a solution's w to w of that solution shifted by
        ``dt`` in time (:func:`gp_agents.pseudospectral.shift_solution`, before its clip to
        the control bounds): the Lagrange interpolants of the states and controls at the
        shifted times, the ends held; a held interval's decision is its nodes' mean.

        Raises:
            ValueError: a free final time (the horizon must be fixed).
        """
        if self.problem.free_final_time:
            raise ValueError("shift_operator needs a fixed final time")
        N, C, M = self.n_points, self._layout.n_control_decisions, self.n_collocation
        n, m = self.n_states, self.n_controls
        basis = self.solution_from_primal(np.zeros(self.n_variables), np.zeros(0), status="basis",
                                          success=True)
        expand = np.zeros((M, C))
        expand[np.arange(M), self._layout.control_index] = 1.0
        unit = dataclasses.replace(basis, x=np.eye(N), u=expand,
                                   u_lb=np.full(C, -np.inf), u_ub=np.full(C, np.inf))
        shifted = shift_solution(unit, dt)
        mean = expand.T / expand.sum(axis=0)[:, None]  # (C, M): a decision is its nodes' mean
        A_x, A_u = shifted.x, mean @ shifted.u  # (N, N), (C, C)
        return np.block([[np.kron(A_x, np.eye(n)), np.zeros((n * N, m * C))],
                         [np.zeros((m * C, n * N)), np.kron(A_u, np.eye(m))]])

    def solution_from_primal(self, w: ArrayLike, p: ArrayLike, *, status: str, success: bool,
                             iterations: int = 0, solve_time: float = 0.0,
                             cost: float = float("nan"), lam_x: ArrayLike | None = None,
                             lam_g: ArrayLike | None = None) -> OCPSolution:
        """An :class:`OCPSolution` of a primal vector w (n_w,) computed outside the NLP solver,
        with multiplier estimates ``lam_x`` (n_w,) and ``lam_g`` if known (else NaN: then the
        costates are NaN too)."""
        w_arr = np.asarray(w, float).ravel()
        if w_arr.size != self.n_variables:
            raise ValueError(f"w must have {self.n_variables} entries, got {w_arr.size}")
        res = {"x": w_arr,
               "lam_x": (np.full(self._nlp_x_size, np.nan) if lam_x is None
                         else np.asarray(lam_x, float).ravel()),
               "lam_g": (np.full(self._nlp_g_size, np.nan) if lam_g is None
                         else np.asarray(lam_g, float).ravel()), "f": cost}
        stats = {"return_status": status, "success": success, "iter_count": iterations}
        sol = self._make_solution(res, stats, None, solve_time, np.asarray(p, float).ravel(), w_arr)
        return dataclasses.replace(sol, success=bool(success), status=status)

    # ------------------------------------------------------------------ solution assembly
    def _make_solution(
        self,
        res: Mapping[str, Any] | None,
        stats: dict[str, Any],
        error: str | None,
        solve_time: float,
        p_arr: FloatArray,
        w0: FloatArray,
    ) -> OCPSolution:
        pb = self.problem
        n, m = pb.n_states, pb.n_controls
        lay, S, N, M = self._layout, self.n_intervals, self.n_points, self.n_collocation
        if res is None:
            w = w0.copy()
            lam_x = np.full(self._nlp_x_size, np.nan)
            lam_g = np.full(self._nlp_g_size, np.nan)
            cost = float("nan")
            status = f"Exception: {error}"
            success = False
        else:
            w = np.asarray(res["x"], dtype=float).ravel()
            lam_x = np.asarray(res["lam_x"], dtype=float).ravel()
            lam_g = np.asarray(res["lam_g"], dtype=float).ravel()
            cost = float(np.asarray(res["f"], dtype=float).ravel()[0])
            status = str(stats.get("return_status", "unknown"))
            success = bool(stats.get("success", False))
            if not (np.all(np.isfinite(w)) and np.isfinite(cost)):
                success = False
                if status in ("Solve_Succeeded", "Solved_To_Acceptable_Level"):
                    status = "Invalid_Number_Detected"
        X = w[: n * N].reshape(N, n)
        U = w[n * N : n * N + m * lay.n_control_decisions].reshape(-1, m)[lay.control_index]
        tf = float(w[-1]) if pb.free_final_time else float(pb.tf)

        nu = lam_g[: self._n_defect].reshape(M, n)
        nu_f = lam_g[self._n_defect : self._n_defect + self._n_quad].reshape(S, n)
        interval = np.repeat(np.arange(S), lay.counts)
        costate = -(nu / np.concatenate(lay.weights)[:, None] + nu_f[interval])
        costate_final = -nu_f[-1]
        costate_initial = -nu_f[0] + lay.D[0][:, 0] @ nu[: lay.counts[0]]

        iters = stats.get("iter_count", -1)
        return OCPSolution(
            t0=pb.t0,
            tf=tf,
            t=self.state_times(tf),
            x=X.copy(),
            t_nodes=self.node_times(tf),
            u=U.copy(),
            cost=cost,
            success=success,
            status=status,
            iterations=int(iters) if iters is not None else -1,
            solve_time=solve_time,
            costate=costate,
            costate_initial=costate_initial,
            costate_final=costate_final,
            nodes_per_interval=self.nodes_per_interval,
            interval_times=pb.t0 + (tf - pb.t0) * self.mesh,
            u_lb=pb.u_lb.copy(),
            u_ub=pb.u_ub.copy(),
            p=p_arr.copy(),
            stats=stats,
            nlp_x=w,
            nlp_lam_x=lam_x,
            nlp_lam_g=lam_g,
            structure=self._structure,
        )
