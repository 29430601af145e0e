"""The real-time iteration's QP, solved from a guessed active set, with a conic fallback.

Between two control periods the RTI's QP (:mod:`gp_agents.mpc.rti`) changes little, and so
does the set of bounds and inequality rows at which its solution sits: most periods none
(the quadrotor's thrusts and the cart's force are inside their bounds once the transient is
over). An interior-point or ADMM solver (proxqp, osqp, piqp) pays for not knowing that; a
primal-dual active-set method (Hintermüller, Ito and Kunisch, *SIAM J. Optim.* 13(3), 2002)
starting from the right set needs one linear solve. :class:`ActiveSetQP` does that:

1. Guess the active set: the bounds at which the shifted plan sits and the inequality rows at
   which its constraint values sit (the caller passes the guess).
2. With that set fixed, the QP is an equality-constrained one: its KKT system,

       [[F H F + A_x + eps I,  F J' S    ],  [z  ]   [-F (q + H c)]
        [S J F,               -(I - S) - eps I]] [lam] = [ S (b - J c) ],

   with ``F`` the free variables' diagonal mask, ``A_x = I - F``, ``S`` the active rows',
   ``c`` the fixed variables' bound values and ``b`` the active rows' bounds, is symmetric and
   quasi-definite. It is equilibrated (rows and columns scaled to unit 2-norm rows), given a
   tiny regularization ``eps`` (in the scaled units; it makes CasADi's sparse LDL', which
   does not pivot, exist for a merely semidefinite Hessian) and solved; when the residual
   against the unregularized system, relative to the right-hand side (its largest entry, at
   least 1), is above ``residual_tol``, one step of iterative refinement follows, and a
   residual still above it ends the iterations (step 4). (Relative, because rounding and
   the regularization leave residuals proportional to the data: an absolute threshold sent
   a well-posed QP stated in large units to the fallback (tested), and refined QPs with
   large right-hand sides, the learned model's among them, often enough to cost a fifth of
   the split RTI's latency.) The refinement is a second factorization (CasADi's ``solve``
   factorizes at every call), so its threshold is the step's price: ``residual_tol`` 1e-7 is
   the tightest value at which most first solves pass without a refinement, at the closed-loop
   costs and rejected steps of a tighter one.
   ``dw = F z + c``; the bounds' multipliers follow from stationarity.
3. The next set, by the primal-dual rule: a free variable (row) beyond a bound becomes active
   at it, an active one whose multiplier has the wrong sign is released. An unchanged set is
   a KKT point of the QP within the tolerances (free variables and inactive rows inside their
   bounds, active ones with multipliers of the right sign, stationarity exact to the linear
   solve): the step is accepted.
4. After ``max_iter`` iterations without that, or at a solve whose residual stays above
   ``residual_tol`` (a singular matrix from a dependent active set, non-finite data), the QP
   goes to the conic ``fallback`` plugin instead, from scratch.

All of it is one CasADi expression (a chain of ``Function.if_else`` switches, so only the
iterations that are needed run), so it compiles into the RTI's one-call warm step. The
iterations are capped by count, never by time: the result is a function of the inputs only.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

__all__ = ["ActiveSetQP"]


class ActiveSetQP:
    """A QP ``min 1/2 x'Hx + q'x  s.t.  lba <= A x <= uba, lbx <= x <= ubx`` solved by
    primal-dual active-set iterations from a guessed active set, falling back to a CasADi
    ``conic`` plugin (see the module docstring).

    Args:
        fallback: the CasADi conic plugin used when the iterations do not settle.
        fallback_options: its CasADi options.
        max_iter: active-set iterations before the fallback, >= 1.
        tol: primal tolerance of a bound or row (in the variables' and rows' units) and dual
            tolerance of a multiplier's sign.
        residual_tol: largest residual of an accepted linear solve (infinity norm,
            equilibrated units, relative to the right-hand side's largest entry if above 1).
        regularization: ``eps`` of the KKT matrix (module docstring), > 0.
    """

    def __init__(self, fallback: str = "proxqp", fallback_options: Mapping[str, Any] | None = None,
                 *, max_iter: int = 8, tol: float = 1e-9, residual_tol: float = 1e-7,
                 regularization: float = 1e-10) -> None:
        if int(max_iter) < 1:
            raise ValueError(f"max_iter must be >= 1, got {max_iter}")
        for name, value in (("tol", tol), ("residual_tol", residual_tol),
                            ("regularization", regularization)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, got {value}")
        if not ca.has_conic(fallback):
            raise ValueError(f"CasADi QP solver plugin {fallback!r} is not available")
        self.fallback = fallback
        self.fallback_options = dict(fallback_options or {})
        self.max_iter, self.tol, self.regularization = int(max_iter), float(tol), \
            float(regularization)
        self.residual_tol = float(residual_tol)

    def __repr__(self) -> str:
        return f"ActiveSetQP(fallback={self.fallback!r}, max_iter={self.max_iter})"

    def function(self, h: ca.Sparsity, a: ca.Sparsity) -> ca.Function:
        """The solver for Hessians of sparsity ``h`` (n, n) and constraint Jacobians ``a``
        (m, n): ``(h, g, a, lba, uba, lbx, ubx, guess_x, guess_a) -> (x, lam_a, lam_x,
        iterations)``. ``guess_x`` (n,) and ``guess_a`` (m,) hold -1 (at the lower bound),
        +1 (upper) or 0 (inactive) per variable and row; equal bounds are always active.
        ``lam_*`` follow CasADi's sign convention (negative at a lower bound);
        ``iterations`` counts the active-set iterations, or is 0 when the fallback solved the QP (or
        the data were not finite: then every output but ``iterations`` is NaN)."""
        n, m = h.size1(), a.size1()
        data = [ca.MX.sym("h", h), ca.MX.sym("g", n), ca.MX.sym("a", a), ca.MX.sym("lba", m),
                ca.MX.sym("uba", m), ca.MX.sym("lbx", n), ca.MX.sym("ubx", n)]
        names = ["h", "g", "a", "lba", "uba", "lbx", "ubx"]
        out_names = ["x", "lam_a", "lam_x", "iterations"]
        sx, sa = ca.MX.sym("guess_x", n), ca.MX.sym("guess_a", m)

        options = dict(self.fallback_options)
        options.setdefault("error_on_fail", False)
        conic = ca.conic("active_set_fallback", self.fallback, {"h": h, "a": a}, options)
        H, q, A, lba, uba, lbx, ubx = data
        res = conic(h=H, g=q, a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx)
        fallback = ca.Function("active_set_fallback_step", [*data, sx, sa],
                               [res["x"], res["lam_a"], res["lam_x"], ca.MX(0)],
                               [*names, "guess_x", "guess_a"], out_names)
        level = fallback
        iterate = self._iteration(data, sx, sa)
        x, lam_a, lam_x = (ca.MX.sym(k, size) for k, size in (("x", n), ("lam_a", m),
                                                                ("lam_x", n)))
        for k in range(self.max_iter, 0, -1):
            args = [*data, sx, sa, x, lam_a, lam_x]
            done = ca.Function(f"active_set_done_{k}", args, [x, lam_a, lam_x, ca.MX(k)])
            more = ca.Function(f"active_set_more_{k}", args, level(*data, sx, sa))
            give_up = ca.Function(f"active_set_give_up_{k}", args, fallback(*data, sx, sa))
            switch = ca.Function.conditional(f"active_set_switch_{k}", [done, more], give_up)
            xk, lam_ak, lam_xk, sx_new, sa_new, outcome = iterate(*data, sx, sa)
            level = ca.Function(f"active_set_level_{k}", [*data, sx, sa],
                                switch(outcome, *data, sx_new, sa_new, xk, lam_ak, lam_xk),
                                [*names, "guess_x", "guess_a"], out_names)
        # non-finite data (a NaN in the Hessian, gradient or Jacobian, or bounds that are NaN):
        # NaN out, without calling a fallback that might iterate on NaNs up to its cap
        finite = ca.logic_and(
            ca.sum1(ca.vertcat(ca.fabs(q), ca.fabs(H.nz[:]), ca.fabs(A.nz[:]))) < np.inf,
            ca.sum1(ca.vertcat(lba <= uba, lbx <= ubx)) == m + n)
        nan = ca.Function("active_set_non_finite", [*data, sx, sa],
                          [np.nan * ca.DM.ones(n), np.nan * ca.DM.ones(m),
                           np.nan * ca.DM.ones(n), ca.MX(0)])
        checked = ca.Function.if_else("active_set_checked", level, nan)
        return ca.Function("active_set_qp", [*data, sx, sa], checked(finite, *data, sx, sa),
                           [*names, "guess_x", "guess_a"], out_names)

    def _regularization(self, n: int, m: int) -> ca.DM:
        eps = self.regularization
        return ca.DM(ca.diag(ca.vertcat(eps * ca.DM.ones(n), -eps * ca.DM.ones(m))))

    def _refinement(self, sparsity: ca.Sparsity, n: int, m: int) -> ca.Function:
        """``(refine, K, rhs, y) -> y`` or ``y`` plus one refinement step's correction."""
        K, rhs, y = ca.MX.sym("K", sparsity), ca.MX.sym("rhs", n + m), ca.MX.sym("y", n + m)
        keep = ca.Function("keep", [K, rhs, y], [y])
        step = y + ca.solve(K + self._regularization(n, m), rhs - ca.mtimes(K, y), "ldl")
        refine = ca.Function("refine", [K, rhs, y], [step])
        return ca.Function.if_else("active_set_refinement", refine, keep)

    def _iteration(self, data: list[ca.MX], sx: ca.MX, sa: ca.MX) -> ca.Function:
        """One primal-dual active-set iteration: ``(data, set_x, set_a) -> (x, lam_a, lam_x,
        next set_x, next set_a, outcome)``, outcome 0 settled, 1 go on, 2 give up."""
        H, q, A, lba, uba, lbx, ubx = data
        n, m = q.numel(), lba.numel()
        tol = self.tol
        eq_x, eq_a = lbx == ubx, lba == uba
        lo_x = ca.fmax(eq_x, sx < 0)
        hi_x = (1 - eq_x) * (sx > 0)
        lo_a = ca.fmax(eq_a, sa < 0)
        hi_a = (1 - eq_a) * (sa > 0)
        fixed, active = lo_x + hi_x, lo_a + hi_a
        free = 1 - fixed
        # if_else_zero, not a product: an infinite bound of an inactive entry contributes 0
        c = ca.if_else(lo_x, lbx, 0) + ca.if_else(hi_x, ubx, 0)
        b = ca.if_else(lo_a, lba, 0) + ca.if_else(hi_a, uba, 0)
        F, S = ca.diag(free), ca.diag(active)
        K = ca.blockcat([
            [ca.mtimes([F, H, F]) + ca.diag(fixed), ca.mtimes([F, A.T, S])],
            [ca.mtimes([S, A, F]), -ca.diag(1 - active)]])
        rhs = ca.vertcat(-ca.mtimes(F, q + ca.mtimes(H, c)), ca.mtimes(S, b - ca.mtimes(A, c)))
        # symmetric equilibration (unit 2-norm rows) and a tiny quasi-definite regularization
        # for the LDL' without pivoting; one step of iterative refinement against the
        # unregularized matrix when the first solve's residual is above ``residual_tol``
        d = 1 / ca.sqrt(ca.sum2(K * K))
        Ks, rs = ca.mtimes([ca.diag(d), K, ca.diag(d)]), d * rhs
        y = ca.solve(Ks + self._regularization(n, m), rs, "ldl")
        scale = ca.fmax(1, ca.mmax(ca.fabs(rs)))
        residual = ca.mmax(ca.fabs(rs - ca.mtimes(Ks, y))) / scale
        y = self._refinement(Ks.sparsity(), n, m)(residual > self.residual_tol, Ks, rs, y)
        residual = ca.mmax(ca.fabs(rs - ca.mtimes(Ks, y))) / scale
        sol = d * y
        x = free * sol[:n] + c
        lam_a = active * sol[n:]
        lam_x = -fixed * (ca.mtimes(H, x) + q + ca.mtimes(A.T, lam_a))
        r = ca.mtimes(A, x)
        # the primal-dual rule (equal bounds stay as they are, outside the comparison)
        up_x = (1 - eq_x) * ca.fmax(free * (x > ubx + tol), hi_x * (lam_x > -tol))
        dn_x = (1 - eq_x) * ca.fmax(free * (x < lbx - tol), lo_x * (lam_x < tol))
        up_a = (1 - eq_a) * ca.fmax((1 - active) * (r > uba + tol), hi_a * (lam_a > -tol))
        dn_a = (1 - eq_a) * ca.fmax((1 - active) * (r < lba - tol), lo_a * (lam_a < tol))
        sx_new, sa_new = up_x - dn_x, up_a - dn_a
        changed = (ca.sum1(ca.fabs(sx_new - (1 - eq_x) * (hi_x - lo_x)))
                   + ca.sum1(ca.fabs(sa_new - (1 - eq_a) * (hi_a - lo_a))))
        # (mmax skips NaNs, a sum does not)
        accurate = ca.logic_and(residual <= self.residual_tol, ca.sum1(ca.fabs(y)) < np.inf)
        # 0: settled (a KKT point), 1: iterate again, 2: the fallback (an inaccurate solve:
        # a singular matrix from a dependent active set, or non-finite data)
        outcome = ca.if_else(accurate, ca.if_else(changed == 0, 0, 1), 2)
        return ca.Function("active_set_iteration", [*data, sx, sa],
                           [x, lam_a, lam_x, sx_new, sa_new, outcome])
