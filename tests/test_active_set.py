"""The RTI's active-set QP solve against KKT conditions checked here and against a CasADi
conic solver on the same QPs."""

from __future__ import annotations

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest

from gp_agents import RTI, PseudospectralMPC
from gp_agents.agent import rollout
from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.rti import resolve_qp_solver


def random_qp(seed: int, n: int = 30, m_eq: int = 8, m_in: int = 6) -> dict[str, np.ndarray]:
    """A strictly convex QP with equality rows, two-sided inequality rows and boxes, some of
    them active at its solution."""
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(n, n))
    H = L @ L.T / n + np.eye(n)
    A = rng.normal(size=(m_eq + m_in, n)) * (rng.random((m_eq + m_in, n)) < 0.4)
    lba = np.r_[rng.normal(size=m_eq), -0.5 * rng.random(m_in) - 0.1]
    uba = np.r_[lba[:m_eq], 0.5 * rng.random(m_in) + 0.1]
    lbx, ubx = -np.ones(n), np.ones(n)
    lbx[0] = ubx[0] = 0.05  # an equality bound
    ubx[1] = np.inf  # a one-sided one
    return dict(h=H, g=1.5 * rng.normal(size=n), a=A, lba=lba, uba=uba, lbx=lbx, ubx=ubx)


def kkt_residuals(qp: dict[str, np.ndarray], x: np.ndarray, lam_a: np.ndarray,
                  lam_x: np.ndarray) -> dict[str, float]:
    """Primal infeasibility, stationarity, complementarity and wrong-sign multipliers
    (CasADi's convention: negative at a lower bound)."""
    r = qp["a"] @ x
    prim = max(np.max(np.maximum(qp["lba"] - r, 0)), np.max(np.maximum(r - qp["uba"], 0)),
               np.max(np.maximum(qp["lbx"] - x, 0)), np.max(np.maximum(x - qp["ubx"], 0)))
    stat = np.max(np.abs(qp["h"] @ x + qp["g"] + qp["a"].T @ lam_a + lam_x))

    def comp(lam: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
        eq = lo == hi
        gap_lo = np.where(lam < 0, np.abs(v - lo), 0.0)
        gap_hi = np.where(lam > 0, np.abs(hi - v), 0.0)
        return float(np.max(np.where(eq, 0.0, (gap_lo + gap_hi) * np.abs(lam)), initial=0))

    return dict(prim=prim, stat=stat, comp=max(comp(lam_a, r, qp["lba"], qp["uba"]),
                                               comp(lam_x, x, qp["lbx"], qp["ubx"])))


def solve(solver: ActiveSetQP, qp: dict[str, np.ndarray], guess_x: np.ndarray,
          guess_a: np.ndarray) -> dict[str, np.ndarray]:
    f = solver.function(ca.DM(qp["h"]).sparsity(), ca.DM(qp["a"]).sparsity())
    out = f(**qp, guess_x=guess_x, guess_a=guess_a)
    return {k: np.asarray(v).ravel() for k, v in out.items()}


@pytest.mark.parametrize("seed", range(5))
def test_active_set_solution_is_a_kkt_point_and_equals_the_conic_solvers(seed):
    qp = random_qp(seed)
    out = solve(ActiveSetQP("proxqp", max_iter=30), qp, np.zeros(30), np.zeros(14))
    assert out["iterations"][0] > 1  # started from "nothing active": it had to iterate
    res = kkt_residuals(qp, out["x"], out["lam_a"], out["lam_x"])
    assert res["prim"] < 1e-9 and res["stat"] < 1e-8 and res["comp"] < 1e-8
    assert np.sum(np.abs(out["lam_x"][1:]) > 1e-8) > 0  # some bound is active
    ref = ca.conic("ref", "piqp", {"h": ca.DM(qp["h"]).sparsity(), "a": ca.DM(qp["a"]).sparsity()},
                   {"piqp": {"eps_abs": 1e-10, "eps_rel": 1e-12, "verbose": False}})(**qp)
    np.testing.assert_allclose(out["x"], np.asarray(ref["x"]).ravel(), atol=1e-6)


def test_the_right_guess_takes_one_linear_solve():
    qp = random_qp(0)
    first = solve(ActiveSetQP("proxqp", max_iter=30), qp, np.zeros(30), np.zeros(14))
    guess_x = np.sign(first["lam_x"]) * (np.abs(first["lam_x"]) > 1e-8)
    guess_a = np.sign(first["lam_a"]) * (np.abs(first["lam_a"]) > 1e-8)
    again = solve(ActiveSetQP("proxqp", max_iter=30), qp, guess_x, guess_a)
    assert again["iterations"][0] == 1
    np.testing.assert_allclose(again["x"], first["x"], atol=1e-10)


def test_unsettled_iterations_and_non_finite_data_go_to_the_fallback():
    qp = random_qp(1)
    fallback = solve(ActiveSetQP("proxqp", max_iter=1), qp, np.zeros(30), np.zeros(14))
    assert fallback["iterations"][0] == 0  # one iteration from a wrong guess cannot settle
    ref = ca.conic("ref", "proxqp", {"h": ca.DM(qp["h"]).sparsity(),
                                     "a": ca.DM(qp["a"]).sparsity()})(**qp)
    np.testing.assert_allclose(fallback["x"], np.asarray(ref["x"]).ravel(), atol=1e-9)
    bad = dict(qp, g=np.full(30, np.nan))
    out = solve(ActiveSetQP("proxqp"), bad, np.zeros(30), np.zeros(14))
    assert out["iterations"][0] == 0 and np.all(np.isnan(out["x"]))  # the caller rejects it


def test_a_qp_in_large_units_is_not_called_inaccurate():
    """The linear solves' accuracy test is relative to the right-hand side: the same QP in
    units 1e8 times larger (gradient and bounds scaled, so the solution scales) settles in
    the same iterations at the scaled solution, from no guess and from the right one."""
    qp = random_qp(2)
    n, m = qp["g"].size, qp["lba"].size
    big = {k: (v if k in ("h", "a") else 1e8 * v) for k, v in qp.items()}
    ref = solve(ActiveSetQP("proxqp", max_iter=30), qp, np.zeros(n), np.zeros(m))
    scaled = solve(ActiveSetQP("proxqp", max_iter=30), big, np.zeros(n), np.zeros(m))
    assert scaled["iterations"][0] == ref["iterations"][0] > 1
    np.testing.assert_allclose(scaled["x"], 1e8 * ref["x"], rtol=1e-9, atol=1e-6)
    guess_x = np.sign(ref["lam_x"]) * (np.abs(ref["lam_x"]) > 1e-8)
    guess_a = np.sign(ref["lam_a"]) * (np.abs(ref["lam_a"]) > 1e-8)
    again = solve(ActiveSetQP("proxqp", max_iter=30), big, guess_x, guess_a)
    assert again["iterations"][0] == 1


def test_settings_are_checked():
    for kwargs in (dict(max_iter=0), dict(tol=0.0), dict(residual_tol=np.nan),
                   dict(regularization=-1.0)):
        with pytest.raises(ValueError):
            ActiveSetQP("proxqp", **kwargs)
    with pytest.raises(ValueError, match="not available"):
        ActiveSetQP("no-such-qp")
    with pytest.raises(ValueError, match="not available"):
        resolve_qp_solver("active-set:no-such-qp")
    assert isinstance(resolve_qp_solver("active-set:piqp"), ActiveSetQP)
    assert resolve_qp_solver("osqp") == "osqp"


def test_rti_with_the_active_set_qp_follows_the_plugins_closed_loop():
    """The same RTI with the QP solved by the active-set iterations (from the shifted plan's
    active set) and by proxqp alone: the same closed loop to the plugin's tolerance."""
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="gp")
    plain = PseudospectralMPC.from_env(env, scheme=RTI(qp_solver="proxqp"))
    active = PseudospectralMPC.from_env(env, scheme=RTI(qp_solver="active-set:proxqp"))
    a, b = (rollout(env, agent, 0, max_steps=60) for agent in (plain, active))
    assert active.planner.counts.rti_steps == 59
    assert active.planner.counts.qp_fallbacks < 10
    assert active.planner.counts.rti_rejected == plain.planner.counts.rti_rejected
    assert b.cost == pytest.approx(a.cost, rel=1e-5)
