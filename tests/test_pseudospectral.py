"""Tests of the Gauss pseudospectral core against independent (analytic or numpy) answers."""

from __future__ import annotations

import itertools
import shutil

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import brentq

from gp_agents.pseudospectral import (
    BufferedFunction,
    GaussPseudospectralSolver,
    InitialGuess,
    OptimalControlProblem,
    differentiation_matrix,
    interpolation_matrix,
    legendre_gauss,
    shift_solution,
    support_points,
)

G = 9.80665

# ---------------------------------------------------------------------------- analytic answers


def hager_state(t: np.ndarray) -> np.ndarray:
    """y*(t) = (2 e^{3t} + e^3) / (e^{3t/2} (2 + e^3))."""
    e3 = np.exp(3.0)
    return (2.0 * np.exp(3.0 * t) + e3) / (np.exp(1.5 * t) * (2.0 + e3))


def hager_control(t: np.ndarray) -> np.ndarray:
    """u*(t) = ydot*(t) - y*(t)/2, with ydot* differentiated by hand."""
    e3 = np.exp(3.0)
    # y* = (2 e^{1.5t} + e^3 e^{-1.5t}) / (2 + e^3)
    ydot = (3.0 * np.exp(1.5 * t) - 1.5 * e3 * np.exp(-1.5 * t)) / (2.0 + e3)
    return ydot - 0.5 * hager_state(t)


HAGER_J = (np.exp(3.0) - 1.0) / (np.exp(3.0) + 2.0)


def hager_problem(**kwargs: object) -> OptimalControlProblem:
    return OptimalControlProblem(
        n_states=1,
        n_controls=1,
        dynamics=lambda x, u: 0.5 * x + u,
        running_cost=lambda x, u: 0.5 * (u**2 + 2.0 * x**2),
        x0=[1.0],
        t0=0.0,
        tf=1.0,
        **kwargs,
    )


def brachistochrone_time(dx: float, dy: float) -> float:
    """Minimum time along the cycloid from rest through a horizontal dx and a drop dy (> 0).

    Cycloid x = r (phi - sin phi), drop = r (1 - cos phi); T = phi_f sqrt(r / g).
    """
    phi = brentq(lambda f: (f - np.sin(f)) / (1.0 - np.cos(f)) - dx / dy, 1e-3, 2 * np.pi - 1e-3)
    r = dy / (1.0 - np.cos(phi))
    return float(phi * np.sqrt(r / G))


def brachistochrone_dynamics(x: ca.SX, u: ca.SX) -> ca.SX:
    """States (x, y, v), y up; control theta measured from the downward vertical."""
    return ca.vertcat(x[2] * ca.sin(u[0]), -x[2] * ca.cos(u[0]), G * ca.cos(u[0]))


def parametric_brachistochrone() -> OptimalControlProblem:
    """Free-time brachistochrone whose target (x, y) is the parameter p (2,)."""
    return OptimalControlProblem(
        n_states=3,
        n_controls=1,
        n_params=2,
        dynamics=brachistochrone_dynamics,
        terminal_cost=lambda x0, xf, tf: tf,
        boundary_constraints=lambda x0, xf, tf, p: xf[:2] - p,
        tf=None,
        tf_bounds=(0.1, 10.0),
        tf_guess=2.0,
        u_lb=0.0,
        u_ub=np.pi,
    )


def bryson_denham_problem(ell: float) -> OptimalControlProblem:
    return OptimalControlProblem(
        n_states=2,
        n_controls=1,
        dynamics=lambda x, u: ca.vertcat(x[1], u[0]),
        running_cost=lambda x, u: 0.5 * u[0] ** 2,
        x0=[0.0, 1.0],
        xf=[0.0, -1.0],
        x_ub=[ell, np.inf],
        tf=1.0,
    )


def bryson_denham_position(t: np.ndarray, ell: float) -> np.ndarray:
    """Optimal x*(t) for l <= 1/6 (Bryson & Ho 1975, sec. 3.11)."""
    t = np.asarray(t, dtype=float)
    s = np.minimum(t, 1.0 - t)
    return np.where(s < 3 * ell, ell * (1.0 - (1.0 - s / (3 * ell)) ** 3), ell)


# ---------------------------------------------------------------------------- nodes, matrices


@pytest.mark.parametrize("K", [1, 2, 3, 7, 10, 25, 60, 100])
def test_legendre_gauss_matches_numpy(K: int) -> None:
    tau, w = legendre_gauss(K)
    tau_ref, w_ref = np.polynomial.legendre.leggauss(K)
    np.testing.assert_allclose(tau, tau_ref, rtol=0, atol=1e-14)
    # numpy's end weights carry ~2e-12 relative error at K = 60 (ours agree with 40-digit
    # mpmath to 1e-16), hence the tolerance
    np.testing.assert_allclose(w, w_ref, rtol=1e-11, atol=1e-15)
    assert np.all(np.diff(tau) > 0) and abs(w.sum() - 2.0) < 1e-13


@pytest.mark.parametrize("K", [1, 4, 9])
def test_quadrature_exact_to_degree_2k_minus_1(K: int) -> None:
    tau, w = legendre_gauss(K)
    for deg in range(2 * K):
        exact = (1.0 - (-1.0) ** (deg + 1)) / (deg + 1)
        assert abs(w @ tau**deg - exact) < 1e-13


@pytest.mark.parametrize("K", [1, 2, 5, 10, 20, 40, 60])
def test_differentiation_matrix_exact_for_degree_k(K: int) -> None:
    rng = np.random.default_rng(K)
    D = differentiation_matrix(K)
    assert D.shape == (K, K + 1)
    np.testing.assert_allclose(D.sum(axis=1), 0.0, atol=1e-12)
    pts, (tau, _) = support_points(K), legendre_gauss(K)
    for deg in range(K + 1):
        c = np.zeros(K + 1)
        c[deg] = 1.0
        ref = np.polynomial.legendre.legval(tau, np.polynomial.legendre.legder(c))
        err = np.max(np.abs(D @ np.polynomial.legendre.legval(pts, c) - ref))
        assert err < 1e-12 * max(1.0, np.abs(ref).max()) * K
    # a random polynomial of degree K in the monomial basis, on a shifted variable
    coef = rng.standard_normal(K + 1)
    p = np.polynomial.Polynomial(coef)
    scale = max(1.0, np.abs(p.deriv()(tau)).max())
    assert np.max(np.abs(D @ p(pts) - p.deriv()(tau))) < 1e-12 * scale * K


def test_interpolation_reproduces_polynomials() -> None:
    K = 12
    pts = support_points(K)
    p = np.polynomial.Polynomial(np.random.default_rng(0).standard_normal(K + 1))
    t = np.linspace(-1, 1, 101)
    np.testing.assert_allclose(interpolation_matrix(pts, t) @ p(pts), p(t), atol=1e-11)
    # exact rows at the nodes themselves
    L = interpolation_matrix(pts, pts)
    np.testing.assert_array_equal(L, np.eye(K + 1))


# ---------------------------------------------------------------------------- Hager


def test_hager_spectral_convergence_and_costate() -> None:
    errors_J, errors_x = [], []
    for K in (2, 4, 6, 8, 10):
        sol = GaussPseudospectralSolver(hager_problem(), n_nodes=K).solve()
        assert sol.success, sol.status
        errors_J.append(abs(sol.cost - HAGER_J))
        errors_x.append(np.max(np.abs(sol.x[:, 0] - hager_state(sol.t))))
        if K >= 6:
            # costate lambda*(t) = -u*(t), from the KKT multipliers (Garg 2010 mapping)
            lam_err = np.max(np.abs(sol.costate[:, 0] + hager_control(sol.t_nodes)))
            assert lam_err < 1e-5 * 10.0 ** (-(K - 6))
            assert abs(sol.costate_initial[0] + hager_control(0.0)) < 1e-6
            assert abs(sol.costate_final[0] + hager_control(1.0)) < 1e-10
    # exponential decrease: every +2 nodes gains > 2 orders of magnitude until round-off
    for a, b in itertools.pairwise(errors_x):
        assert b < max(a / 100.0, 1e-12)
    assert errors_J[0] > 1e-4  # K = 2 is genuinely inaccurate, so the test can fail
    assert errors_J[-1] < 1e-9 and errors_x[-1] < 1e-9


def test_hager_interpolants_and_initial_control() -> None:
    sol = GaussPseudospectralSolver(hager_problem(), n_nodes=12).solve()
    t = np.linspace(0.0, 1.0, 57)
    np.testing.assert_allclose(sol.state(t)[:, 0], hager_state(t), atol=1e-11)
    np.testing.assert_allclose(sol.control(t)[:, 0], hager_control(t), atol=1e-9)
    assert sol.state(0.3).shape == (1,)
    np.testing.assert_allclose(sol.x_final, hager_state(np.array([1.0])), atol=1e-12)
    # the control at t0 (no LG node there): extrapolation vs. first node
    u0 = sol.initial_control()
    assert abs(u0[0] - hager_control(0.0)) < 1e-9
    assert abs(sol.initial_control("first_node")[0] - sol.u[0, 0]) == 0.0
    with pytest.raises(ValueError, match="method"):
        sol.initial_control("nearest")  # type: ignore[arg-type]


def test_initial_control_clipped_to_bounds() -> None:
    # u* (t0) = -1.1 without bounds; with u >= -1 the extrapolated value is clipped
    sol = GaussPseudospectralSolver(hager_problem(u_lb=-1.0, u_ub=1.0), n_nodes=10).solve()
    assert sol.success
    assert sol.initial_control()[0] >= -1.0
    assert sol.initial_control(clip=False)[0] < -1.0 + 1e-3


def test_hager_multiple_intervals() -> None:
    sol = GaussPseudospectralSolver(hager_problem(), n_nodes=6, n_intervals=4).solve()
    assert sol.success
    assert abs(sol.cost - HAGER_J) < 1e-10
    assert sol.x.shape == (4 * 7 + 1, 1) and sol.u.shape == (24, 1)
    np.testing.assert_allclose(sol.x[:, 0], hager_state(sol.t), atol=1e-8)
    np.testing.assert_allclose(sol.costate[:, 0], -hager_control(sol.t_nodes), atol=1e-6)
    t = np.linspace(0, 1, 41)
    np.testing.assert_allclose(sol.state(t)[:, 0], hager_state(t), atol=1e-7)
    np.testing.assert_allclose(sol.x_nodes, sol.state(sol.t_nodes), atol=1e-12)
    np.testing.assert_allclose(sol.x_nodes[:, 0], hager_state(sol.t_nodes), atol=1e-8)


def test_shift_solution_holds_beyond_horizon() -> None:
    sol = GaussPseudospectralSolver(hager_problem(), n_nodes=12).solve()
    guess = shift_solution(sol, 0.25)
    assert isinstance(guess, InitialGuess) and guess.tf == sol.tf
    inside = sol.t + 0.25 <= 1.0
    np.testing.assert_allclose(guess.x[inside, 0], hager_state(sol.t[inside] + 0.25), atol=1e-10)
    np.testing.assert_allclose(guess.x[~inside, 0], sol.x_final[0], atol=0)
    inside_u = sol.t_nodes + 0.25 <= sol.t_nodes[-1]
    np.testing.assert_allclose(
        guess.u[inside_u, 0], hager_control(sol.t_nodes[inside_u] + 0.25), atol=1e-8
    )
    np.testing.assert_allclose(guess.u[~inside_u, 0], sol.u[-1, 0], atol=0)
    np.testing.assert_allclose(sol.shift(0.0).x, sol.x, rtol=0, atol=1e-13)
    with pytest.raises(ValueError):
        sol.shift(-1.0)


# ---------------------------------------------------------------------------- brachistochrone


def test_brachistochrone_free_final_time() -> None:
    problem = OptimalControlProblem(
        n_states=3,
        n_controls=1,
        dynamics=brachistochrone_dynamics,
        terminal_cost=lambda x0, xf, tf: tf,
        x0=[0.0, 10.0, 0.0],
        xf_lb=[10.0, 5.0, -np.inf],
        xf_ub=[10.0, 5.0, np.inf],
        tf=None,
        tf_bounds=(0.1, 10.0),
        tf_guess=2.0,
        u_lb=0.0,
        u_ub=np.pi,
    )
    sol = GaussPseudospectralSolver(problem, n_nodes=20).solve()
    assert sol.success, sol.status
    assert abs(sol.tf - 1.8016031) < 1e-6
    assert abs(sol.tf - brachistochrone_time(10.0, 5.0)) < 1e-6
    assert abs(sol.cost - sol.tf) < 1e-12
    np.testing.assert_allclose(sol.x_final[:2], [10.0, 5.0], atol=1e-8)
    # energy: v = sqrt(2 g (y0 - y)) along the whole path
    np.testing.assert_allclose(sol.x[:, 2], np.sqrt(2 * G * (10.0 - sol.x[:, 1])), atol=1e-6)
    assert sol.t[-1] == sol.tf and sol.t_nodes[-1] < sol.tf


def test_approximate_hessian_changes_the_path_not_the_solution() -> None:
    """``hessian_dynamics``: the Lagrangian Hessian of another model, the constraints of the
    true one. The same model gives IPOPT's exact run; a wrong one (gravity 20% low in the
    second derivatives) other iterates but the same optimum, still the cycloid's time. (Far
    cruder Hessians converge slowly or not at all: 0.5 g takes ~1,000 iterations, 0 none.)"""
    def problem(hessian_dynamics: object) -> OptimalControlProblem:
        return OptimalControlProblem(
            n_states=3, n_controls=1, dynamics=brachistochrone_dynamics,
            hessian_dynamics=hessian_dynamics, terminal_cost=lambda x0, xf, tf: tf,
            x0=[0.0, 10.0, 0.0], xf_lb=[10.0, 5.0, -np.inf], xf_ub=[10.0, 5.0, np.inf],
            tf=None, tf_bounds=(0.1, 10.0), tf_guess=2.0, u_lb=0.0, u_ub=np.pi)

    def crude(x: ca.SX, u: ca.SX) -> ca.SX:
        return ca.vertcat(x[2] * ca.sin(u[0]), -x[2] * ca.cos(u[0]), 0.8 * G * ca.cos(u[0]))

    exact = GaussPseudospectralSolver(problem(None), n_nodes=20).solve()
    same = GaussPseudospectralSolver(problem(brachistochrone_dynamics), n_nodes=20).solve()
    other = GaussPseudospectralSolver(problem(crude), n_nodes=20).solve()
    assert exact.success and same.success and other.success
    assert same.iterations == exact.iterations
    np.testing.assert_allclose(same.x, exact.x, atol=1e-10)
    assert other.iterations != exact.iterations
    assert abs(other.tf - brachistochrone_time(10.0, 5.0)) < 1e-6
    np.testing.assert_allclose(other.x, exact.x, atol=1e-6)
    with pytest.raises(ValueError, match="hessian_dynamics"):
        problem(lambda x, u: ca.vertcat(x[0], x[1]))


def test_parametric_resolve_warm_start_matches_cold() -> None:
    solver = GaussPseudospectralSolver(parametric_brachistochrone(), n_nodes=16)
    first = solver.solve(p=[10.0, 5.0], x0=[0.0, 10.0, 0.0])
    assert first.success
    assert abs(first.tf - brachistochrone_time(10.0, 5.0)) < 1e-6
    # new target and new initial state: no rebuild, parameters and bounds only
    p_new, x0_new = [10.5, 5.0], [0.0, 10.2, 0.0]
    cold = solver.solve(p=p_new, x0=x0_new)
    warm = solver.solve(p=p_new, x0=x0_new, initial_guess=first)
    assert cold.success and warm.success
    expected = brachistochrone_time(10.5, 5.2)
    assert abs(cold.tf - expected) < 1e-6 and abs(warm.tf - expected) < 1e-6
    np.testing.assert_allclose(warm.x, cold.x, atol=1e-6)
    np.testing.assert_allclose(warm.x[0], x0_new, atol=0)
    assert warm.iterations <= cold.iterations
    # a guess sampled from an interpolant (different K) works too
    other = GaussPseudospectralSolver(parametric_brachistochrone(), n_nodes=10)
    resampled = other.solve(p=p_new, x0=x0_new, initial_guess=first)
    assert resampled.success and abs(resampled.tf - expected) < 1e-5


# ---------------------------------------------------------------------------- path constraints


def test_bryson_denham_state_constrained_several_intervals() -> None:
    ell = 1.0 / 9.0
    j_star = 4.0 / (9.0 * ell)
    # mesh boundaries at the junctions 3l and 1 - 3l, and a mesh that does not see them
    for S, K, tol in ((3, 8, 1e-5), (8, 10, 1e-3)):
        solver = GaussPseudospectralSolver(bryson_denham_problem(ell), n_nodes=K, n_intervals=S)
        sol = solver.solve()
        assert sol.success, sol.status
        assert abs(sol.cost - j_star) < tol, (S, K, sol.cost)
        assert np.all(sol.x[:, 0] <= ell + 1e-7)
        np.testing.assert_allclose(sol.x[:, 0], bryson_denham_position(sol.t, ell), atol=30 * tol)
    # a single global interval is visibly worse on this non-smooth solution
    single = GaussPseudospectralSolver(bryson_denham_problem(ell), n_nodes=10).solve()
    assert abs(single.cost - j_star) > 1e-3


def test_nonlinear_path_constraint_obstacle_as_parameter() -> None:
    """Min-energy double integrator in the plane around a circular obstacle (centre = p)."""
    radius = 0.3

    def dynamics(x: ca.SX, u: ca.SX) -> ca.SX:
        return ca.vertcat(x[2], x[3], u[0], u[1])

    problem = OptimalControlProblem(
        n_states=4,
        n_controls=2,
        n_params=2,
        dynamics=dynamics,
        running_cost=lambda x, u: 0.5 * ca.sumsqr(u),
        path_constraints=lambda x, u, p: ca.sumsqr(x[:2] - p) - radius**2,
        path_lb=0.0,
        path_ub=np.inf,
        x0=[0.0, 0.0, 0.0, 0.0],
        xf=[2.0, 0.0, 0.0, 0.0],
        tf=1.0,
    )
    solver = GaussPseudospectralSolver(problem, n_nodes=12, n_intervals=2)
    far = solver.solve(p=[1.0, 5.0])  # obstacle far away: the straight line is optimal
    # rest-to-rest: u = 6 d / T^2 (1 - 2 t / T), 1/2 int u^2 = 6 d^2 / T^3 = 24
    assert far.success and abs(far.cost - 24.0) < 1e-9
    for centre in ([1.0, 0.05], [1.0, -0.05]):
        sol = solver.solve(
            p=centre,
            initial_guess=InitialGuess(
                t=[0.0, 0.5, 1.0],
                x=[[0, 0, 0, 0], [1.0, -np.sign(centre[1]) * 0.5, 0, 0], [2, 0, 0, 0]],
                t_u=[0.0, 1.0],
                u=[[0, 0], [0, 0]],
            ),
        )
        assert sol.success, sol.status
        node_pos = sol.state(sol.t_nodes)[:, :2]
        clearance = np.linalg.norm(node_pos - np.asarray(centre), axis=1) - radius
        assert clearance.min() > -1e-6 and clearance.min() < 1e-4  # active, respected
        assert sol.cost > far.cost + 1.0
        # detours on the side away from the centre offset
        assert np.sign(sol.x[len(sol.x) // 2, 1]) == -np.sign(centre[1])


# ---------------------------------------------------------------------------- failures, inputs


def test_infeasible_problem_reports_failure() -> None:
    problem = hager_problem(u_lb=-0.1, u_ub=0.1, xf=[5.0])
    sol = GaussPseudospectralSolver(problem, n_nodes=8).solve()
    assert not sol.success
    assert "Infeasible" in sol.status


def test_nan_in_evaluation_reports_failure() -> None:
    problem = OptimalControlProblem(
        n_states=1,
        n_controls=1,
        dynamics=lambda x, u: ca.log(x) + u,
        running_cost=lambda x, u: u**2,
        x0=[-1.0],
    )
    for name in ("ipopt", "sqpmethod"):
        sol = GaussPseudospectralSolver(problem, n_nodes=5, solver=name).solve()
        assert not sol.success and isinstance(sol.status, str) and sol.status


def test_max_iterations_reports_failure() -> None:
    solver = GaussPseudospectralSolver(
        parametric_brachistochrone(), n_nodes=10, solver_options={"ipopt": {"max_iter": 3}}
    )
    sol = solver.solve(p=[10.0, 5.0], x0=[0.0, 10.0, 0.0])
    assert not sol.success and sol.status == "Maximum_Iterations_Exceeded"
    assert sol.iterations == 3


def test_bad_input_raises_value_error() -> None:
    with pytest.raises(ValueError, match="lb > ub"):
        hager_problem(u_lb=1.0, u_ub=-1.0)
    with pytest.raises(ValueError, match=r"dynamics must return shape \(2,\)"):
        OptimalControlProblem(
            n_states=2, n_controls=1, dynamics=lambda x, u: x[0] + u, running_cost=lambda x, u: u**2
        )
    with pytest.raises(ValueError, match="x_lb"):
        hager_problem(x_lb=[0.0, 1.0])
    with pytest.raises(ValueError, match="running_cost"):
        OptimalControlProblem(n_states=1, n_controls=1, dynamics=lambda x, u: u)
    with pytest.raises(ValueError, match="tf"):
        hager_problem().__class__(
            n_states=1, n_controls=1, dynamics=lambda x, u: u, running_cost=lambda x, u: u**2, tf=-1
        )
    with pytest.raises(ValueError, match="NaN"):
        hager_problem(x_ub=[np.nan])
    with pytest.raises(ValueError, match="n_nodes"):
        GaussPseudospectralSolver(hager_problem(), n_nodes=0)
    with pytest.raises(ValueError, match="mesh"):
        GaussPseudospectralSolver(hager_problem(), mesh=[0.0, 0.7, 0.5, 1.0])
    with pytest.raises(ValueError, match="not available"):
        GaussPseudospectralSolver(hager_problem(), solver="no_such_solver")
    with pytest.raises(ValueError, match="K"):
        legendre_gauss(0)
    solver = GaussPseudospectralSolver(parametric_brachistochrone(), n_nodes=5)
    with pytest.raises(ValueError, match="pass p"):
        solver.solve()
    with pytest.raises(ValueError, match="2 entries"):
        solver.solve(p=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="NaN"):
        solver.solve(p=[np.nan, 5.0])
    with pytest.raises(ValueError, match="NaN"):
        solver.solve(p=[10.0, 5.0], x0=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="3 entries"):
        solver.solve(p=[10.0, 5.0], x0=[0.0, 1.0])
    with pytest.raises(ValueError, match="NaN"):
        InitialGuess(t=[0.0, 1.0], x=[[0.0], [np.nan]], t_u=[0.0], u=[[0.0]])


# ---------------------------------------------------------------------------- solver options


def test_casadi_function_dynamics_and_sqpmethod() -> None:
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    f = ca.Function("f", [x, u], [0.5 * x + u])
    problem = OptimalControlProblem(
        n_states=1,
        n_controls=1,
        dynamics=f,
        running_cost=lambda x, u: 0.5 * (u**2 + 2.0 * x**2),
        x0=[1.0],
    )
    for qpsol in ("qrqp", "osqp"):
        if not ca.has_conic(qpsol):
            continue
        sol = GaussPseudospectralSolver(
            problem, n_nodes=10, solver="sqpmethod", solver_options={"qpsol": qpsol}
        ).solve()
        assert sol.success, (qpsol, sol.status)
        tol = 1e-9 if qpsol == "qrqp" else 1e-5
        assert abs(sol.cost - HAGER_J) < tol
        np.testing.assert_allclose(sol.costate[:, 0], -hager_control(sol.t_nodes), atol=1e-3)


@pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None, reason="no cc")
def test_jit_compiled_solver_matches() -> None:
    sol = GaussPseudospectralSolver(hager_problem(), n_nodes=10, jit=True).solve()
    assert sol.success and abs(sol.cost - HAGER_J) < 1e-9


def test_node_parameters_time_varying_dynamics() -> None:
    """Per-node parameters q_k = t_k give ydot = u + t: min 1/2 int_0^1 u^2 dt with y(0) = 0,
    y(1) = 1 has the constant optimum u* = 1 - int_0^1 t dt = 1/2 and J* = 1/8."""
    problem = OptimalControlProblem(
        n_states=1, n_controls=1, n_node_params=1,
        dynamics=lambda x, u, p, q: u + q, running_cost=lambda x, u: 0.5 * u**2,
        t0=0.0, tf=1.0, x0=[0.0], xf=[1.0])
    solver = GaussPseudospectralSolver(problem, n_nodes=6)
    t = solver.node_times()
    sol = solver.solve(node_params=t[:, None])
    assert sol.success
    assert abs(sol.cost - 0.125) < 1e-10
    np.testing.assert_allclose(sol.u.ravel(), 0.5, atol=1e-8)
    np.testing.assert_allclose(sol.state(t).ravel(), 0.5 * t + 0.5 * t**2, atol=1e-8)
    # a constant q = 0.5 at every node gives the same cost, another q another one
    assert abs(solver.solve(node_params=np.full(t.size, 0.5)).cost - 0.125) < 1e-10
    assert abs(solver.solve(node_params=np.zeros(t.size)).cost - 0.5) < 1e-10
    with pytest.raises(ValueError, match="node_params"):
        solver.solve()
    with pytest.raises(ValueError, match="node_params"):
        solver.solve(node_params=np.zeros((t.size + 1, 1)))
    with pytest.raises(ValueError, match="NaN"):
        solver.solve(node_params=np.full((t.size, 1), np.nan))



# ---------------------------------------------------------------------------- held controls
def sampled_data_hager(n_periods: int) -> tuple[float, np.ndarray]:
    """Hager's problem with the control held constant over n equal periods, solved without any
    collocation: exact flow of ydot = y/2 + u per period, cost by adaptive quadrature, the n
    controls by BFGS."""
    from scipy.integrate import quad
    from scipy.optimize import minimize

    h = 1.0 / n_periods

    def cost(u: np.ndarray) -> float:
        y0, total = 1.0, 0.0
        for uk in u:
            def y(t: float, y0: float = y0, uk: float = uk) -> float:
                return np.exp(0.5 * t) * y0 + 2.0 * (np.exp(0.5 * t) - 1.0) * uk
            total += quad(lambda t, y=y, uk=uk: 0.5 * (uk**2 + 2.0 * y(t) ** 2), 0.0, h,
                          epsabs=1e-13, epsrel=1e-13)[0]
            y0 = y(h)
        return total

    res = minimize(cost, np.zeros(n_periods), method="BFGS", options={"gtol": 1e-10})
    return float(res.fun), res.x


def test_held_intervals_solve_the_sampled_data_problem() -> None:
    """Every interval held: the NLP is the zero-order-hold (sampled-data) problem, whose optimum
    is computed independently from the exact flow (no collocation)."""
    J, u = sampled_data_hager(4)
    solver = GaussPseudospectralSolver(hager_problem(), n_nodes=4, n_intervals=4,
                                       hold=[True] * 4)
    sol = solver.solve()
    assert sol.success and solver.n_control_decisions == 4
    assert sol.cost == pytest.approx(J, rel=1e-8)
    held = sol.u[:, 0].reshape(4, 4)
    np.testing.assert_allclose(held, np.repeat(u[:, None], 4, axis=1), atol=1e-5)
    # the control interpolant is that constant inside each period, even between the nodes
    t = np.linspace(0.0, 0.999, 37)
    np.testing.assert_allclose(sol.control(t)[:, 0], u[np.floor(t * 4).astype(int)], atol=1e-5)
    # and the polynomial-control optimum is lower (it is the continuous problem's)
    assert HAGER_J < J


def test_mixed_mesh_first_period_held_then_lg() -> None:
    """A held first period then one LG interval (the receding-horizon layout), per-interval node
    counts: the held control is one value; the rest converges to the continuous optimum as the
    held period shrinks."""
    costs = []
    for first in (0.2, 0.05, 0.01):
        solver = GaussPseudospectralSolver(hager_problem(), n_nodes=[3, 14],
                                           mesh=[0.0, first, 1.0], hold=[True, False])
        sol = solver.solve()
        assert sol.success and sol.nodes_per_interval == (3, 14)
        assert solver.n_points == 4 + 15 + 1 and solver.n_collocation == 17
        assert np.ptp(sol.u[:3, 0]) < 1e-12
        costs.append(sol.cost)
    assert costs[0] > costs[1] > costs[2] > HAGER_J
    assert costs[2] == pytest.approx(HAGER_J, rel=1e-4)
    # a shifted warm start of a mixed mesh re-solves to the same plan from its own solution
    again = solver.solve(initial_guess=sol)
    assert again.success and again.iterations <= 2
    np.testing.assert_allclose(again.x, sol.x, atol=1e-8)


def test_node_indices_pick_the_solutions_node_states_and_controls() -> None:
    """``node_indices`` (for compiled steps that evaluate node-wise functions of w) on a mixed
    mesh with two-dimensional states: ``w[ix]``, ``w[iu]`` are ``x_nodes`` and ``u``."""
    solver = GaussPseudospectralSolver(bryson_denham_problem(1 / 9), n_nodes=[3, 5, 4],
                                       mesh=[0.0, 0.1, 0.5, 1.0], hold=[True, False, False])
    sol = solver.solve()
    ix, iu = solver.node_indices()
    assert ix.shape == (12, 2) and iu.shape == (12, 1)
    np.testing.assert_array_equal(sol.nlp_x[ix], sol.x_nodes)
    np.testing.assert_array_equal(sol.nlp_x[iu], sol.u)
    assert len(set(iu[:3, 0])) == 1 and len(set(iu[3:, 0])) == 9  # the held period: one column


def test_buffered_function_equals_the_plain_call() -> None:
    """A Function called on numpy memory (its buffer interface) gives what the DM call gives,
    matrices read column-major; wrong inputs and sparse outputs are refused."""
    a, b = ca.MX.sym("a", 3, 2), ca.MX.sym("b", 4)
    fn = ca.Function("f", [a, b], [ca.mtimes(a.T, b[:3]) * b[3], ca.sin(a)])
    buffered = BufferedFunction(fn)
    rng = np.random.default_rng(0)
    A, B = rng.standard_normal((3, 2)), rng.standard_normal(4)
    out = buffered(A, B)
    ref = fn(A, B)
    np.testing.assert_array_equal(out[0], np.asarray(ref[0]).ravel(order="F"))
    np.testing.assert_array_equal(out[1], np.asarray(ref[1]).ravel(order="F"))
    out[0][:] = np.nan  # results are copies: the next call is unaffected
    np.testing.assert_array_equal(buffered(A, B)[1], np.sin(A).ravel(order="F"))
    import pickle

    np.testing.assert_array_equal(pickle.loads(pickle.dumps(buffered))(A, B)[0],
                                  np.asarray(ref[0]).ravel(order="F"))
    with pytest.raises(ValueError, match="needs 4 numbers"):
        buffered(A, B[:3])
    with pytest.raises(ValueError, match="takes 2 inputs"):
        buffered(A)
    with pytest.raises(ValueError, match="sparse"):
        BufferedFunction(ca.Function("g", [b], [ca.diag(b)]))
    # by names, with a solver's statistics: min (x0 - p)^2 + (x1 - 1)^2 s.t. -1 <= x0 + x1 <= 1
    x, p = ca.MX.sym("x", 2), ca.MX.sym("p")
    solver = BufferedFunction(ca.nlpsol("s", "ipopt", {"x": x, "p": p, "g": x[0] + x[1],
                                                       "f": (x[0] - p) ** 2 + (x[1] - 1) ** 2},
                                        {"ipopt.print_level": 0, "print_time": False}))
    for target, expected in ((3.0, [1.5, -0.5]), (-1.0, [-1.0, 1.0])):
        res = solver.call(p=target, lbg=-1.0, ubg=1.0)
        np.testing.assert_allclose(res["x"], expected, atol=1e-7)
        assert solver.stats()["return_status"] == "Solve_Succeeded"
    with pytest.raises(ValueError, match="no inputs"):
        solver.call(q=1.0)


def test_path_constraints_hold_at_held_interval_ends() -> None:
    """The end point of a held interval (a control period's boundary) satisfies the path
    constraint, not just the nodes inside it: y >= 0.6 where the unconstrained optimum dips
    to ~0.57 near the end."""
    problem = hager_problem(path_constraints=lambda x, u: 0.6 - x[0])
    solver = GaussPseudospectralSolver(problem, n_nodes=3, n_intervals=5, hold=[True] * 5)
    sol = solver.solve()
    assert sol.success
    ends = sol.x[[4 * (s + 1) for s in range(5)], 0]  # X_{s+1,0} and X_f
    assert np.all(ends >= 0.6 - 1e-7)
    assert np.min(np.abs(ends - 0.6)) < 1e-6  # active at some boundary
    with pytest.raises(ValueError, match="hold"):
        GaussPseudospectralSolver(hager_problem(), n_nodes=3, n_intervals=2, hold=[True])
    with pytest.raises(ValueError, match="n_nodes"):
        GaussPseudospectralSolver(hager_problem(), n_nodes=[3, 0])
