"""Tests of the GP residual learners (gp_agents.learners).

Independent checks: dense textbook formulas (np.linalg.solve / inv, no Cholesky), finite
differences, a known 1-D function, a step-by-step simulation of the forgetting schedule.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.linalg import cholesky, solve_triangular

from gp_agents.learners import (
    SSGP,
    ChangeDetector,
    ExactGP,
    GPHyperparameters,
    IncrementalSSGP,
    NominalFallback,
    NotFittedError,
)
from gp_agents.learners.cholesky_update import cholesky_add_rows, positive_diagonal, solve_upper
from gp_agents.learners.exact_gp import exact_gp_nlml
from gp_agents.learners.ssgp import ssgp_nlml


def _target(Z: np.ndarray) -> np.ndarray:
    """A smooth 2-output test function of 3 inputs."""
    return np.c_[np.sin(1.5 * Z[:, 0]) * Z[:, 1], np.cos(Z[:, 2]) + 0.3 * Z[:, 0] ** 2]


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(42)
    Z = rng.uniform(-2.0, 2.0, (120, 3)) * [1.0, 3.0, 0.5] + [0.0, 1.0, -2.0]
    Y = _target(Z) * [1.0, 10.0] + 0.02 * rng.standard_normal((120, 2))
    Zt = rng.uniform(-1.5, 1.5, (40, 3)) * [1.0, 3.0, 0.5] + [0.0, 1.0, -2.0]
    return Z, Y, Zt, _target(Zt) * [1.0, 10.0]


@pytest.fixture(scope="module")
def exact_gp(data) -> ExactGP:
    Z, Y, _, _ = data
    return ExactGP(n_restarts=1, random_state=0).fit(Z, Y)


def _central_diff(f, x: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """Central finite-difference gradient of a scalar function."""
    return np.array([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))])


def _hyp(d_in: int, d_out: int, ell: float = 1.0, sf: float = 1.0, sn: float = 0.1):
    return GPHyperparameters(
        np.full((d_out, d_in), ell) * (1.0 + 0.2 * np.arange(d_in)),
        np.full(d_out, sf),
        np.full(d_out, sn),
    )


# ---------------------------------------------------------------------------- exact GP
def test_exact_gp_matches_dense_formula(data):
    Z, Y, Zt, _ = data
    hyp = _hyp(3, 2, ell=1.3, sf=0.9, sn=0.2)
    gp = ExactGP(optimize=False, hyperparameters=hyp, normalize=False).fit(Z, Y)
    mean, std = gp.predict(Zt, return_std=True)
    for j in range(2):
        ell, sf, sn = hyp.length_scales[j], hyp.signal_std[j], hyp.noise_std[j]

        def k(A, B, ell=ell, sf=sf):
            diff = (A[:, None, :] - B[None, :, :]) / ell
            return sf**2 * np.exp(-0.5 * np.sum(diff**2, axis=2))

        Ky = k(Z, Z) + sn**2 * np.eye(len(Z))
        Ks = k(Zt, Z)
        m = Ks @ np.linalg.solve(Ky, Y[:, j])
        v = sf**2 + sn**2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(Ky, Ks.T))
        np.testing.assert_allclose(mean[:, j], m, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(std[:, j] ** 2, v, rtol=1e-7, atol=1e-10)
        lml = -0.5 * Y[:, j] @ np.linalg.solve(Ky, Y[:, j]) - 0.5 * np.linalg.slogdet(Ky)[1]
        lml -= 0.5 * len(Z) * np.log(2 * np.pi)
        assert gp.log_marginal_likelihood_[j] == pytest.approx(lml, rel=1e-9)


def test_exact_gp_learns_known_1d_function():
    rng = np.random.default_rng(0)
    Z = rng.uniform(-3.0, 3.0, (80, 1))
    noise = 0.05
    Y = np.sin(2.0 * Z) + noise * rng.standard_normal(Z.shape)
    gp = ExactGP(n_restarts=2, random_state=1).fit(Z, Y)
    Zt = np.linspace(-2.8, 2.8, 200)[:, None]
    mean, std = gp.predict(Zt, return_std=True)
    rmse = np.sqrt(np.mean((mean - np.sin(2.0 * Zt)) ** 2))
    assert rmse < 0.03
    # learned noise (original units) close to the truth; std includes the noise
    sn = gp.hyperparameters_.noise_std[0] * gp.standardizer_.y_std[0]
    assert 0.5 * noise < sn < 2.0 * noise
    assert np.all(std >= sn * (1 - 1e-9))
    # far from the data the predictive std returns to the prior
    far = gp.predict(np.array([[50.0]]), return_std=True)[1][0, 0]
    sf = gp.hyperparameters_.signal_std[0] * gp.standardizer_.y_std[0]
    assert far == pytest.approx(np.hypot(sf, sn), rel=1e-6)
    assert gp.n_samples_seen_ == 80


@pytest.mark.parametrize("which", ["exact", "ssgp"])
def test_nlml_gradients_match_finite_differences(which, data):
    Z, Y, _, _ = data
    Zs = (Z - Z.mean(0)) / Z.std(0)
    y = (Y[:, 1] - Y[:, 1].mean()) / Y[:, 1].std()
    theta = np.r_[np.log([0.7, 1.3, 2.0]), np.log(0.8), np.log(0.2)]
    base = np.random.default_rng(3).standard_normal((3, 40))
    if which == "exact":
        fun = lambda t: exact_gp_nlml(t, Zs, y)  # noqa: E731
    else:
        fun = lambda t: ssgp_nlml(t, Zs, y, base)  # noqa: E731
    _, grad = fun(theta)
    fd = _central_diff(lambda t: fun(t)[0], theta)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)


def test_exact_gp_optimization_improves_likelihood(data, exact_gp):
    Z, Y, _, _ = data
    default = ExactGP(optimize=False, hyperparameters=_hyp(3, 2)).fit(Z, Y)
    assert np.all(exact_gp.log_marginal_likelihood_ > default.log_marginal_likelihood_)


@pytest.mark.parametrize("kind", ["exact", "ssgp", "incremental"])
def test_predict_gradient_matches_finite_differences(kind, data, exact_gp):
    Z, Y, Zt, _ = data
    if kind == "exact":
        model = exact_gp
    elif kind == "ssgp":
        model = SSGP(50, hyperparameters=exact_gp).fit(Z, Y)
    else:
        model = IncrementalSSGP(50, forgetting_factor=0.95, hyperparameters=exact_gp).fit(Z, Y)
    G = model.predict_gradient(Zt[:5])
    assert G.shape == (5, 2, 3)
    for n in range(5):
        for i in range(2):
            fd = _central_diff(lambda z, i=i: model.predict(z[None, :])[0, i], Zt[n], 1e-4)
            np.testing.assert_allclose(G[n, i], fd, rtol=1e-5, atol=1e-5 * np.abs(G).max())


# ---------------------------------------------------------------------------- SSGP
def test_ssgp_matches_dense_weight_space_formula(data):
    Z, Y, Zt, _ = data
    hyp = _hyp(3, 2, ell=1.1, sf=1.2, sn=0.15)
    model = SSGP(30, hyperparameters=hyp, normalize=False, random_state=7).fit(Z, Y)
    mean, std = model.predict(Zt, return_std=True)
    for j in range(2):
        omega = model.base_frequencies_[j] / hyp.length_scales[j][:, None]

        def phi(A, omega=omega, sf=hyp.signal_std[j]):
            U = omega.T @ A.T  # (r, N)
            return sf / np.sqrt(omega.shape[1]) * np.vstack([np.cos(U), np.sin(U)])

        Phi = phi(Z)
        A = Phi @ Phi.T + hyp.noise_std[j] ** 2 * np.eye(60)
        w = np.linalg.solve(A, Phi @ Y[:, j])
        Ps = phi(Zt)
        np.testing.assert_allclose(model.weights_[j], w, rtol=1e-8, atol=1e-9)
        np.testing.assert_allclose(mean[:, j], w @ Ps, rtol=1e-8, atol=1e-9)
        var = hyp.noise_std[j] ** 2 * (1 + np.einsum("in,ij,jn->n", Ps, np.linalg.inv(A), Ps))
        np.testing.assert_allclose(std[:, j] ** 2, var, rtol=1e-7)


def test_ssgp_converges_to_exact_gp(data, exact_gp):
    Z, Y, Zt, _ = data
    m_ex, s_ex = exact_gp.predict(Zt, return_std=True)
    scale = Y.std(0)
    errs, std_errs = [], []
    for r in (10, 100, 1500):
        m, s = (
            SSGP(r, hyperparameters=exact_gp, random_state=1).fit(Z, Y).predict(Zt, return_std=True)
        )
        errs.append(np.sqrt(np.mean(((m - m_ex) / scale) ** 2)))
        std_errs.append(np.max(np.abs(s - s_ex) / scale))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 0.03
    assert std_errs[2] < std_errs[0]


def test_ssgp_own_marginal_likelihood(data):
    Z, Y, Zt, Yt = data
    model = SSGP(40, hyperparameters="ssgp", n_restarts=1, random_state=0).fit(Z, Y)
    nmse = np.mean((model.predict(Zt) - Yt) ** 2, axis=0) / np.var(Yt, axis=0)
    assert np.all(nmse < 0.05)
    # optimum is at least as good as the default start
    Zs = model.standardizer_.transform_inputs(Z)
    Ys = model.standardizer_.transform_outputs(Y)
    for j in range(2):
        opt = ssgp_nlml(
            model.hyperparameters_.log_params(j), Zs, Ys[:, j], model.base_frequencies_[j]
        )
        start = ssgp_nlml(np.r_[0, 0, 0, 0, np.log(0.1)], Zs, Ys[:, j], model.base_frequencies_[j])
        assert opt[0] <= start[0]


def test_ssgp_hyperparameters_exact_string(data, exact_gp):
    Z, Y, Zt, _ = data
    a = SSGP(20, hyperparameters="exact", n_restarts=1, random_state=0).fit(Z, Y)
    b = SSGP(20, hyperparameters=exact_gp, random_state=0).fit(Z, Y)
    np.testing.assert_allclose(a.predict(Zt), b.predict(Zt), rtol=1e-6, atol=1e-8)


# ---------------------------------------------------------------------------- incremental
def test_cholesky_add_rows():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((40, 12))
    A = X.T @ X + np.eye(12)
    B = rng.standard_normal((3, 12))
    R = cholesky_add_rows(cholesky(A), B, scale=np.sqrt(0.9))
    assert np.all(np.tril(R, -1) == 0)
    R = positive_diagonal(R)
    np.testing.assert_allclose(R, cholesky(0.9 * A + B.T @ B), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("order", ["F", "C"])
def test_solve_upper_is_scipys_triangular_solve_to_the_bit(order):
    rng = np.random.default_rng(1)
    X = rng.standard_normal((60, 20))
    R = np.array(cholesky(X.T @ X + np.eye(20)), order=order)
    for b in (rng.standard_normal(20), rng.standard_normal((20, 3))):
        for transpose in (False, True):
            expected = solve_triangular(R, b, trans="T" if transpose else "N",
                                        check_finite=False)
            assert np.array_equal(solve_upper(R, b, transpose=transpose), expected)
    np.testing.assert_allclose(R @ solve_upper(R, b), b, rtol=1e-10, atol=1e-10)
    with pytest.raises(np.linalg.LinAlgError):
        solve_upper(np.zeros((3, 3)), np.ones(3))


def _simulated_prior_ages(n: int, D: int, m: int) -> np.ndarray:
    """Step-by-step simulation of the refresh schedule (independent of prior_ages)."""
    ages = np.zeros(D, dtype=int)
    pos = 0
    for _ in range(n):
        ages += 1
        for _ in range(m):
            ages[pos % D] = 0
            pos += 1
    return ages


def _batch_reference(model: IncrementalSSGP, Z, Y, lam: float, m: int):
    """Dense batch formula: A = sn^2 diag(lam^ages) + sum_i lam^(n-i) phi_i phi_i^T."""
    std, hyp = model.standardizer_, model.hyperparameters_
    Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
    n = len(Z)
    wts = lam ** np.arange(n - 1, -1, -1, dtype=float)
    W = []
    for j in range(model.n_outputs_):
        omega = model.base_frequencies_[j] / hyp.length_scales[j][:, None]
        U = Zs @ omega
        F = hyp.signal_std[j] / np.sqrt(omega.shape[1]) * np.hstack([np.cos(U), np.sin(U)])
        D = F.shape[1]
        ages = _simulated_prior_ages(n, D, m)
        A = F.T @ (wts[:, None] * F) + np.diag(hyp.noise_std[j] ** 2 * lam**ages)
        W.append(np.linalg.solve(A, F.T @ (wts * Ys[:, j])))
    return np.array(W)


@pytest.mark.parametrize(("lam", "m"), [(1.0, 1), (0.97, 1), (0.9, 3), (0.95, 100)], ids=str)
def test_incremental_equals_batch(lam, m, data, exact_gp):
    Z, Y, Zt, _ = data
    n0 = 30
    model = IncrementalSSGP(
        15, forgetting_factor=lam, prior_refresh=m, hyperparameters=exact_gp, random_state=3
    ).fit(Z[:n0], Y[:n0])
    # mixed single-sample and batch updates
    i = n0
    for p in (1, 1, 7, 1, 25, 1, 2):
        model.update(Z[i : i + p], Y[i : i + p])
        i += p
    model.update(Z[i:], Y[i:])
    assert model.n_samples_seen_ == len(Z)
    W_ref = _batch_reference(model, Z, Y, lam, m)
    np.testing.assert_allclose(model.weights_, W_ref, rtol=1e-8, atol=1e-8 * np.abs(W_ref).max())
    # the same learner fitted on everything at once (batch path) agrees too
    batch = IncrementalSSGP(
        15, forgetting_factor=lam, prior_refresh=m, hyperparameters=exact_gp, random_state=3
    ).fit(Z, Y)
    # tolerance relative to the predictions' scale: rank-1 updates and one batch Cholesky round
    # differently (2e-10 absolute on predictions of size ~5 was seen with this machine's BLAS)
    expected = batch.predict(Zt)
    np.testing.assert_allclose(model.predict(Zt), expected, rtol=1e-8,
                               atol=1e-10 * np.abs(expected).max())
    np.testing.assert_allclose(
        model.predict(Zt, return_std=True)[1], batch.predict(Zt, return_std=True)[1], rtol=1e-8
    )
    if lam == 1.0:  # no forgetting: the ordinary batch SSGP
        ssgp = SSGP(15, hyperparameters=exact_gp, random_state=3).fit(Z, Y)
        np.testing.assert_allclose(model.predict(Zt), ssgp.predict(Zt), rtol=1e-8,
                                   atol=1e-10 * np.abs(expected).max())


def test_prior_stays_bounded_over_1e5_updates():
    """1e5 single-sample updates with lambda < 1, the last 6e4 on one repeated input (the data
    part of A has rank 1 there): the factor tracks the dense recursion and A stays
    well conditioned."""
    rng = np.random.default_rng(0)
    lam, r, sn = 0.99, 5, 0.1
    hyp = GPHyperparameters(np.array([[0.8, 1.5]]), np.array([1.0]), np.array([sn]))
    model = IncrementalSSGP(r, forgetting_factor=lam, hyperparameters=hyp, normalize=False)
    model.fit(rng.uniform(-1, 1, (10, 2)), rng.standard_normal((10, 1)))
    D = 2 * r
    omega = model.omega_[0]
    A = model.cholesky_factor_[0].T @ model.cholesky_factor_[0]
    n_upd = 100_000
    Zn = rng.uniform(-1, 1, (n_upd, 2))
    Zn[40_000:] = [0.3, -0.2]
    Yn = np.sin(Zn[:, :1]) + 0.01 * rng.standard_normal((n_upd, 1))
    F = np.hstack([np.cos(Zn @ omega), np.sin(Zn @ omega)]) / np.sqrt(r)
    pos = 10  # refresh position after the 10 fitted samples (m = 1)
    ages = _simulated_prior_ages(10, D, 1)
    worst_cond = 0.0
    for i in range(n_upd):
        model.update(Zn[i : i + 1], Yn[i : i + 1])
        # dense recursion of the stated formula, in the test
        A = lam * A + np.outer(F[i], F[i])
        ages += 1
        k = pos % D
        A[k, k] += sn**2 * (1.0 - lam ** ages[k])
        ages[k] = 0
        pos += 1
        if i % 10_000 == 9_999:
            R = model.cholesky_factor_[0]
            np.testing.assert_allclose(R.T @ R, A, rtol=0, atol=1e-10 * np.abs(A).max())
            ev = np.linalg.eigvalsh(A)
            assert ev[0] >= sn**2 * lam ** (D - 1) * (1 - 1e-9)
            worst_cond = max(worst_cond, ev[-1] / ev[0])
    assert model.n_samples_seen_ == 10 + n_upd
    np.testing.assert_allclose(model.prior_diagonal()[0], sn**2 * lam**ages, rtol=1e-12)
    # bound: lambda_max <= sum_i lam^i |phi|^2 + sn^2 = 1 / (1 - lam) + sn^2
    assert worst_cond <= (1.0 / (1.0 - lam) + sn**2) / (sn**2 * lam ** (D - 1))
    assert np.all(np.isfinite(model.weights_))
    z0 = np.array([[0.3, -0.2]])
    assert model.predict(z0)[0, 0] == pytest.approx(np.sin(0.3), abs=0.01)


def test_save_load_roundtrip(tmp_path, data, exact_gp):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(
        12, forgetting_factor=0.98, prior_refresh=2, hyperparameters=exact_gp, random_state=5
    ).fit(Z[:50], Y[:50])
    model.update(Z[50:80], Y[50:80])
    path = tmp_path / "ssgp.npz"
    model.save(path)
    loaded = IncrementalSSGP.load(path)
    assert loaded.n_samples_seen_ == model.n_samples_seen_ == 80
    assert loaded.forgetting_factor == 0.98 and loaded.prior_refresh == 2
    np.testing.assert_array_equal(loaded.casadi_param_values(), model.casadi_param_values())
    m1, s1 = model.predict(Zt, return_std=True)
    m2, s2 = loaded.predict(Zt, return_std=True)
    np.testing.assert_array_equal(m1, m2)
    np.testing.assert_array_equal(s1, s2)
    model.update(Z[80:], Y[80:])
    loaded.update(Z[80:], Y[80:])
    np.testing.assert_array_equal(model.predict(Zt), loaded.predict(Zt))


# ---------------------------------------------------------------------------- CasADi export
@pytest.mark.parametrize("sym", [ca.SX, ca.MX], ids=["SX", "MX"])
@pytest.mark.parametrize("kind", ["exact", "ssgp", "incremental"])
def test_casadi_export_matches_predict(kind, sym, data, exact_gp):
    Z, Y, Zt, _ = data
    if kind == "exact":
        model = ExactGP(optimize=False, hyperparameters=exact_gp.hyperparameters_).fit(
            Z[:40], Y[:40]
        )
    elif kind == "ssgp":
        model = SSGP(20, hyperparameters=exact_gp).fit(Z, Y)
    else:
        model = IncrementalSSGP(20, forgetting_factor=0.97, hyperparameters=exact_gp).fit(
            Z[:60], Y[:60]
        )
    P = model.casadi_param_size()
    z = sym.sym("z", 3)
    theta = sym.sym("theta", P)
    mean = model.casadi_mean(z, theta)
    var = model.casadi_variance(z, theta)
    assert mean.shape == (2, 1) and var.shape == (2, 1)
    fn = ca.Function("gp", [z, theta], [mean, var, ca.jacobian(mean, z)])

    def check() -> None:
        assert model.casadi_param_values().shape == (P,)
        _check_export(fn, model, Zt[:6])

    check()
    if kind == "incremental":  # the same Function keeps working after updates
        model.update(Z[60:61], Y[60:61])
        model.update(Z[61:], Y[61:])
        assert model.casadi_param_size() == P
        check()


@pytest.mark.parametrize("kind", ["exact", "ssgp", "incremental", "linear"])
def test_batch_export_matches_predict_at_every_column(kind, data, exact_gp):
    """``casadi_mean_batch`` / ``casadi_variance_batch`` (matrix operations over points, the
    SSGPs' own; the exact GP's the per-column default) against ``predict``, and the mean-only
    parameter vector (``variance=False``): the same mean, the variance blocks left zero."""
    Z, Y, Zt, _ = data
    model = {
        "exact": lambda: ExactGP(optimize=False, hyperparameters=exact_gp.hyperparameters_
                                 ).fit(Z[:40], Y[:40]),
        "ssgp": lambda: SSGP(20, hyperparameters=exact_gp).fit(Z, Y),
        "incremental": lambda: IncrementalSSGP(20, forgetting_factor=0.97,
                                               hyperparameters=exact_gp).fit(Z[:60], Y[:60]),
        "linear": lambda: IncrementalSSGP(12, forgetting_factor=0.98, linear_features=True,
                                          n_restarts=0, random_state=2).fit(Z[:60], Y[:60]),
    }[kind]()
    if kind in ("incremental", "linear"):
        model.update(Z[60:70], Y[60:70])
    Zq = Zt[:7]
    P = model.casadi_param_size()
    Zs, theta = ca.MX.sym("Z", 3, Zq.shape[0]), ca.MX.sym("theta", P)
    fn = ca.Function("batch", [Zs, theta], [model.casadi_mean_batch(Zs, theta),
                                            model.casadi_variance_batch(Zs, theta)])
    mean, std = model.predict(Zq, return_std=True)
    full, lean = model.casadi_param_values(), model.casadi_param_values(variance=False)
    for values in (full, lean):
        m, _ = fn(Zq.T, values)
        np.testing.assert_allclose(np.asarray(m).T, mean, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(np.asarray(fn(Zq.T, full)[1]).T, std**2, rtol=1e-8, atol=1e-12)
    assert lean.shape == full.shape and np.count_nonzero(lean) < np.count_nonzero(full)
    np.testing.assert_array_equal(lean[lean != 0], full[lean != 0])
    with pytest.raises(ValueError, match="rows"):
        model.casadi_mean_batch(ca.MX.sym("Z", 2, 4), theta)
    # the mean-only vector (the variance's blocks left out): the same mean, fewer numbers
    compact = model.casadi_mean_param_values()
    assert compact.shape == (model.casadi_mean_param_size(),)
    assert compact.size < P and np.count_nonzero(compact) == np.count_nonzero(lean)
    tc = ca.MX.sym("theta", compact.size)
    mean_fn = ca.Function("mean", [Zs, tc], [model.casadi_mean_batch(Zs, tc)])
    np.testing.assert_allclose(np.asarray(mean_fn(Zq.T, compact)).T, mean, rtol=1e-10,
                               atol=1e-10)
    z1 = ca.MX.sym("z", 3)
    one = ca.Function("one", [z1, tc], [model.casadi_mean(z1, tc)])
    np.testing.assert_allclose(np.asarray(one(Zq[0], compact)).ravel(), mean[0], rtol=1e-10,
                               atol=1e-10)
    with pytest.raises(KeyError):  # the variance needs the full vector
        model.casadi_variance_batch(Zs, tc)
    with pytest.raises(ValueError, match="theta must have shape"):
        model.casadi_mean_batch(Zs, ca.MX.sym("theta", compact.size + 1))


@pytest.mark.parametrize("kind", ["exact", "ssgp", "incremental", "linear", "masked",
                                  "saturated"])
def test_batch_mean_gradient_matches_predict_gradient(kind, data, exact_gp):
    """``casadi_mean_gradient_batch`` (the SSGPs' analytic gradient of the random features;
    the exact GP's by AD) against ``predict`` and ``predict_gradient`` at every column, with
    the full and the mean-only parameter vectors."""
    Z, Y, Zt, _ = data
    model = {
        "exact": lambda: ExactGP(optimize=False, hyperparameters=exact_gp.hyperparameters_
                                 ).fit(Z[:40], Y[:40]),
        "ssgp": lambda: SSGP(20, hyperparameters=exact_gp).fit(Z, Y),
        "incremental": lambda: IncrementalSSGP(20, forgetting_factor=0.97,
                                               hyperparameters=exact_gp).fit(Z[:60], Y[:60]),
        "linear": lambda: IncrementalSSGP(12, forgetting_factor=0.98, linear_features=True,
                                          n_restarts=0, random_state=2).fit(Z[:60], Y[:60]),
        "masked": lambda: IncrementalSSGP(12, linear_features=[0, 2], n_restarts=0,
                                          random_state=2).fit(Z[:60], Y[:60]),
        "saturated": lambda: IncrementalSSGP(12, linear_features=[1], input_saturation=1.5,
                                             n_restarts=0, random_state=2).fit(Z[:60], Y[:60]),
    }[kind]()
    if isinstance(model, IncrementalSSGP):
        model.update(Z[60:70], Y[60:70])
    Zq = np.vstack([Zt[:6], Zt[6:7] * 4.0])  # the last point far out (saturated inputs)
    for values in (model.casadi_param_values(), model.casadi_mean_param_values()):
        Zs, theta = ca.MX.sym("Z", 3, Zq.shape[0]), ca.MX.sym("theta", values.size)
        mean, grads = model.casadi_mean_gradient_batch(Zs, theta)
        fn = ca.Function("mg", [Zs, theta], [mean, *grads])
        out = fn(Zq.T, values)
        np.testing.assert_allclose(np.asarray(out[0]).T, model.predict(Zq), rtol=1e-10,
                                   atol=1e-10)
        G = model.predict_gradient(Zq)  # (N, d_out, d_in)
        for j, g in enumerate(out[1:]):
            np.testing.assert_allclose(np.asarray(g).T, G[:, j, :], rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------------------- bad inputs
def _learners(exact_gp):
    return [
        ExactGP(n_restarts=0),
        SSGP(10, hyperparameters=exact_gp),
        IncrementalSSGP(10, hyperparameters=exact_gp),
    ]


def test_bad_training_data(data, exact_gp):
    Z, Y, _, _ = data
    Zn = Z.copy()
    Zn[3, 1] = np.nan
    Yi = Y.copy()
    Yi[5, 0] = np.inf
    for model in _learners(exact_gp):
        for bad_Z, bad_Y, msg in [
            (Zn, Y, "NaN or infinite"),
            (Z, Yi, "NaN or infinite"),
            (Z[:, 0], Y, "2-D"),
            (Z, Y[:-1], "rows"),
            (Z[:0], Y[:0], "zero rows"),
            ([["a", "b", "c"]], [[1.0, 2.0]], "numeric"),
        ]:
            with pytest.raises(ValueError, match=msg):
                model.fit(bad_Z, bad_Y)


def test_predict_and_update_before_fit(exact_gp):
    for model in _learners(exact_gp):
        with pytest.raises(NotFittedError, match="not fitted"):
            model.predict(np.zeros((1, 3)))
        with pytest.raises(NotFittedError):
            model.casadi_param_values()
        with pytest.raises(NotFittedError):
            model.casadi_mean(ca.SX.sym("z", 3), ca.SX.sym("t", 5))
    with pytest.raises(NotFittedError):
        IncrementalSSGP(5).update(np.zeros((1, 3)), np.zeros((1, 2)))
    assert issubclass(NotFittedError, ValueError)


def test_bad_settings(data, exact_gp):
    Z, Y, _, _ = data
    with pytest.raises(ValueError, match="forgetting_factor"):
        IncrementalSSGP(5, forgetting_factor=0.0, hyperparameters=exact_gp).fit(Z, Y)
    with pytest.raises(ValueError, match="forgetting_factor"):
        IncrementalSSGP(5, forgetting_factor=1.5, hyperparameters=exact_gp).fit(Z, Y)
    with pytest.raises(ValueError, match="hyperparameters must be"):
        SSGP(5, hyperparameters="bogus").fit(Z, Y)
    with pytest.raises(NotFittedError):
        SSGP(5, hyperparameters=ExactGP()).fit(Z, Y)
    with pytest.raises(ValueError, match="dimensions"):
        SSGP(5, hyperparameters=exact_gp).fit(Z[:, :2], Y)
    with pytest.raises(ValueError, match="requires hyperparameters"):
        ExactGP(optimize=False).fit(Z, Y)
    with pytest.raises(ValueError, match="positive"):
        GPHyperparameters(np.ones((1, 2)), np.ones(1), np.zeros(1))


def test_wrong_shapes_at_prediction(data, exact_gp):
    _, _, Zt, _ = data
    with pytest.raises(ValueError, match="columns"):
        exact_gp.predict(Zt[:, :2])
    with pytest.raises(ValueError, match="2-D"):
        exact_gp.predict(Zt[0])
    with pytest.raises(ValueError, match="NaN"):
        exact_gp.predict_gradient(np.full((1, 3), np.nan))
    P = exact_gp.casadi_param_size()
    with pytest.raises(ValueError, match="z must have shape"):
        exact_gp.casadi_mean(ca.SX.sym("z", 2), ca.SX.sym("t", P))
    with pytest.raises(ValueError, match="theta must have shape"):
        exact_gp.casadi_mean(ca.SX.sym("z", 3), ca.SX.sym("t", P + 1))


def test_failed_update_leaves_state_intact(data, exact_gp):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(10, forgetting_factor=0.95, hyperparameters=exact_gp).fit(
        Z[:50], Y[:50]
    )
    model.update(Z[50:60], Y[50:60])
    before = (
        model.cholesky_factor_.copy(),
        model.b_.copy(),
        model.n_samples_seen_,
        model.predict(Zt),
        model.casadi_param_values(),
    )
    Yn = Y[60:70].copy()
    Yn[-1, 1] = np.nan
    for bad_Z, bad_Y in [
        (Z[60:70], Yn),
        (Z[60:70, :2], Y[60:70]),
        (Z[60:70], Y[60:70, :1]),
        (Z[60:70], Y[60:69]),
        (Z[60:60], Y[60:60]),
    ]:
        with pytest.raises(ValueError):
            model.update(bad_Z, bad_Y)
        np.testing.assert_array_equal(model.cholesky_factor_, before[0])
        np.testing.assert_array_equal(model.b_, before[1])
        assert model.n_samples_seen_ == before[2]
        np.testing.assert_array_equal(model.predict(Zt), before[3])
        np.testing.assert_array_equal(model.casadi_param_values(), before[4])
    # a numerically impossible update (overflowing features) is rejected atomically as well
    model.standardizer_ = type(model.standardizer_)(
        model.standardizer_.z_mean,
        model.standardizer_.z_std,
        model.standardizer_.y_mean,
        np.full(2, 1e-310),
    )
    with (
        pytest.raises(FloatingPointError),
        np.errstate(over="ignore", invalid="ignore", divide="ignore"),
    ):
        model.update(Z[60:61], Y[60:61] * 1e300)
    np.testing.assert_array_equal(model.cholesky_factor_, before[0])
    assert model.n_samples_seen_ == before[2]


# ---------------------------------------------------------------------------- linear features
def test_ssgp_nlml_linear_gradient_matches_finite_differences(data):
    Z, Y, _, _ = data
    Zs = (Z - Z.mean(0)) / Z.std(0)
    y = (Y[:, 1] - Y[:, 1].mean()) / Y[:, 1].std()
    theta = np.r_[np.log([0.7, 1.3, 2.0]), np.log(0.8), np.log(0.2), np.log(0.6)]
    base = np.random.default_rng(3).standard_normal((3, 40))
    fun = lambda t: ssgp_nlml(t, Zs, y, base, linear=True)  # noqa: E731
    _, grad = fun(theta)
    assert grad.shape == (6,)
    fd = _central_diff(lambda t: fun(t)[0], theta)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("columns", [True, (0, 2), (-1,)], ids=["all", "0,2", "-1"])
def test_ssgp_linear_features_match_dense_formula(data, columns):
    """Weight-space SSGP with the features [phi_SE(z); sigma_l z] (only the selected columns of
    z with ``linear_features=<columns>``): dense textbook formula on exactly those features."""
    Z, Y, Zt, _ = data
    hyp = _hyp(3, 2, ell=1.5, sf=0.8, sn=0.1)
    model = SSGP(10, hyperparameters=hyp, linear_features=columns, linear_std=0.7,
                 random_state=1).fit(Z, Y)
    std = model.standardizer_
    Zs, Ys, Zts = std.transform_inputs(Z), std.transform_outputs(Y), std.transform_inputs(Zt)
    keep = [0, 1, 2] if columns is True else [c % 3 for c in columns]
    np.testing.assert_array_equal(np.flatnonzero(model.linear_mask_), keep)

    def feats(X, j):
        U = X @ (model.base_frequencies_[j] / hyp.length_scales[j][:, None])
        return np.hstack([0.8 / np.sqrt(10) * np.cos(U), 0.8 / np.sqrt(10) * np.sin(U),
                          0.7 * X[:, keep]])

    for j in range(2):
        F = feats(Zs, j)
        A = F.T @ F + 0.01 * np.eye(F.shape[1])
        w = np.linalg.solve(A, F.T @ Ys[:, j])
        Ft = feats(Zts, j)
        mean = std.inverse_mean(np.c_[Ft @ w, Ft @ w])[:, j]
        var = 0.01 * (1 + np.einsum("ij,ji->i", Ft, np.linalg.inv(A) @ Ft.T)) * std.y_std[j] ** 2
        m, s = model.predict(Zt, return_std=True)
        np.testing.assert_allclose(m[:, j], mean, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s[:, j] ** 2, var, rtol=1e-8)
        # the unselected columns' weights are exactly zero, so is their gradient share
        unselected = [c for c in range(3) if c not in keep]
        assert np.all(model.weights_[j][20:][unselected] == 0.0)
    assert model.weights_.shape == (2, 23)


@pytest.mark.parametrize("columns", [(), (3,), (-4,), (0, 0), (1, -2)], ids=str)
def test_linear_feature_columns_are_checked(data, columns):
    Z, Y, _, _ = data
    with pytest.raises(ValueError, match="linear_features"):
        SSGP(5, hyperparameters=_hyp(3, 2, ell=1.0, sf=1.0, sn=0.1),
             linear_features=columns).fit(Z, Y)


def test_ssgp_nlml_gradient_with_linear_columns(data):
    """The marginal likelihood's analytic gradient with a column mask, against central
    differences; and the mask of every column is the plain linear block."""
    Z, Y, _, _ = data
    Zs = (Z - Z.mean(0)) / Z.std(0)
    y = (Y[:, 0] - Y[:, 0].mean()) / Y[:, 0].std()
    theta = np.r_[np.log([0.9, 1.1, 1.7]), np.log(0.6), np.log(0.3), np.log(0.8)]
    base = np.random.default_rng(4).standard_normal((3, 30))
    mask = np.array([0.0, 1.0, 0.0])
    fun = lambda t: ssgp_nlml(t, Zs, y, base, linear=mask)  # noqa: E731
    _, grad = fun(theta)
    fd = _central_diff(lambda t: fun(t)[0], theta)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5)
    full, plain = ssgp_nlml(theta, Zs, y, base, linear=np.ones(3)), ssgp_nlml(
        theta, Zs, y, base, linear=True)
    assert full[0] == plain[0]
    np.testing.assert_array_equal(full[1], plain[1])


def test_linear_features_extrapolate_linear_residual():
    """A damping-like residual y = -3 v (plus a bump) learned on |v| <= 1: with linear features
    the prediction at v = 4 is close to -12."""
    rng = np.random.default_rng(0)
    Z = rng.uniform(-1, 1, (150, 2))
    Y = (-3.0 * Z[:, 0] + 0.3 * np.sin(3 * Z[:, 1]))[:, None] + 0.01 * rng.standard_normal((150, 1))
    zq = np.array([[4.0, 0.0]])
    kw = dict(forgetting_factor=1.0, random_state=0)
    lin = IncrementalSSGP(30, linear_features=True, **kw).fit(Z, Y)
    assert lin.linear_std_ is not None and lin.linear_std_.shape == (1,)
    assert lin.predict(zq)[0, 0] == pytest.approx(-12.0, abs=1.0)


@pytest.mark.parametrize(("lam", "m"), [(1.0, 1), (0.97, 1), (0.95, 100)], ids=str)
def test_incremental_linear_equals_batch(lam, m, data, exact_gp):
    Z, Y, Zt, _ = data
    kw = dict(forgetting_factor=lam, prior_refresh=m, hyperparameters=exact_gp,
              linear_features=True, linear_std=0.5, random_state=3)
    model = IncrementalSSGP(15, **kw).fit(Z[:30], Y[:30])
    i = 30
    for p in (1, 7, 1, 25):
        model.update(Z[i : i + p], Y[i : i + p])
        i += p
    model.update(Z[i:], Y[i:])
    batch = IncrementalSSGP(15, **kw).fit(Z, Y)
    assert model.weights_.shape == (2, 33)
    expected = batch.predict(Zt)
    np.testing.assert_allclose(model.predict(Zt), expected, rtol=1e-8,
                               atol=1e-10 * np.abs(expected).max())
    np.testing.assert_allclose(
        model.predict(Zt, return_std=True)[1], batch.predict(Zt, return_std=True)[1], rtol=1e-8
    )
    # dense reference of the forgetting recursion over [phi_SE; sigma_l z]
    std, hyp = model.standardizer_, model.hyperparameters_
    Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
    wts = lam ** np.arange(len(Z) - 1, -1, -1, dtype=float)
    for j in range(2):
        U = Zs @ model.omega_[j]
        F = np.hstack([hyp.signal_std[j] / np.sqrt(15) * np.hstack([np.cos(U), np.sin(U)]),
                       0.5 * Zs])
        ages = _simulated_prior_ages(len(Z), F.shape[1], m)
        A = F.T @ (wts[:, None] * F) + np.diag(hyp.noise_std[j] ** 2 * lam**ages)
        w = np.linalg.solve(A, F.T @ (wts * Ys[:, j]))
        # the normal equations are ill-conditioned (cond(A) ~ 1e7-1e9 here): both solutions
        # carry an error of about cond(A) * eps, so that is the tolerance, not a fixed one
        tol = 10 * np.linalg.cond(A) * np.finfo(float).eps * np.abs(w).max()
        assert np.abs(model.weights_[j] - w).max() <= tol


def _check_export(fn: ca.Function, model, Z: np.ndarray) -> None:
    """The exported ``fn(z, theta) -> (mean, variance, d mean / dz)`` with the model's current
    parameter values against its NumPy prediction, variance and gradient at each row of Z."""
    tv = model.casadi_param_values()
    m, sd = model.predict(Z, return_std=True)
    G = model.predict_gradient(Z)
    for n in range(len(Z)):
        cm, cv, cj = (np.asarray(a) for a in fn(Z[n], tv))
        np.testing.assert_allclose(cm.ravel(), m[n], rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(cv.ravel(), sd[n] ** 2, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(cj, G[n], rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("columns", [True, (1,)], ids=["all", "column 1"])
@pytest.mark.parametrize("sym", [ca.SX, ca.MX], ids=["SX", "MX"])
def test_casadi_export_linear_features(sym, columns, data):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, forgetting_factor=0.98, linear_features=columns,
                            n_restarts=0, random_state=2).fit(Z[:60], Y[:60])
    P = model.casadi_param_size()
    z, theta = sym.sym("z", 3), sym.sym("theta", P)
    mean = model.casadi_mean(z, theta)
    fn = ca.Function("gp", [z, theta], [mean, model.casadi_variance(z, theta),
                                        ca.jacobian(mean, z)])

    def check() -> None:
        _check_export(fn, model, Zt[:6])

    check()
    model.update(Z[60:61], Y[60:61])
    model.update(Z[61:], Y[61:])
    assert model.casadi_param_size() == P
    check()
    # gradient against finite differences of predict
    z0 = Zt[3]
    step = [model.predict((z0 + 1e-6 * e)[None])[0] - model.predict((z0 - 1e-6 * e)[None])[0]
            for e in np.eye(3)]
    fd = np.stack(step, axis=1) / 2e-6
    np.testing.assert_allclose(model.predict_gradient(z0[None])[0], fd, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("columns", [True, (0, -1)], ids=["all", "0,-1"])
def test_save_load_roundtrip_linear(tmp_path, data, columns):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, forgetting_factor=0.98, linear_features=columns, n_restarts=0,
                            random_state=5).fit(Z[:50], Y[:50])
    model.update(Z[50:80], Y[50:80])
    path = tmp_path / "ssgp_linear.npz"
    model.save(path)
    loaded = IncrementalSSGP.load(path)
    assert loaded.linear_features
    np.testing.assert_array_equal(loaded.linear_mask_, model.linear_mask_)
    np.testing.assert_array_equal(loaded.linear_std_, model.linear_std_)
    np.testing.assert_array_equal(loaded.casadi_param_values(), model.casadi_param_values())
    np.testing.assert_array_equal(model.predict(Zt), loaded.predict(Zt))
    loaded.update(Z[80:], Y[80:])
    model.update(Z[80:], Y[80:])
    np.testing.assert_array_equal(model.predict(Zt), loaded.predict(Zt))


# ---------------------------------------------------------------------------- input saturation
def test_input_saturation_is_a_dense_tanh_of_the_standardized_inputs(data):
    """The saturated model is the plain one on inputs ``s tanh(z_s / s)``: the dense weight-space
    formula on those, bounded linear features far outside the data, and the identity at s=inf."""
    Z, Y, Zt, _ = data
    hyp = _hyp(3, 2, ell=1.5, sf=0.8, sn=0.1)
    kw = dict(hyperparameters=hyp, linear_features=True, linear_std=0.7, random_state=1)
    sat = SSGP(10, input_saturation=2.0, **kw).fit(Z, Y)
    std = sat.standardizer_
    assert std.saturates and std.input_saturation == 2.0

    def squash(X):
        return 2.0 * np.tanh(((X - std.z_mean) / std.z_std) / 2.0)

    def feats(X, j):
        U = X @ (sat.base_frequencies_[j] / hyp.length_scales[j][:, None])
        return np.hstack([0.8 / np.sqrt(10) * np.cos(U), 0.8 / np.sqrt(10) * np.sin(U), 0.7 * X])

    far = Zt * 50.0  # tens of standard deviations out
    for j in range(2):
        F = feats(squash(Z), j)
        w = np.linalg.solve(F.T @ F + 0.01 * np.eye(F.shape[1]),
                            F.T @ std.transform_outputs(Y)[:, j])
        mean = std.inverse_mean(np.c_[feats(squash(far), j) @ w] * np.ones((1, 2)))[:, j]
        np.testing.assert_allclose(sat.predict(far)[:, j], mean, rtol=1e-9, atol=1e-9)
    # bounded: a query 1000x farther out predicts what one at the saturation level does
    np.testing.assert_allclose(sat.predict(far * 1000.0), sat.predict(np.sign(far) * 1e9),
                               rtol=1e-9)
    plain = SSGP(10, **kw).fit(Z, Y)
    inf = SSGP(10, input_saturation=np.inf, **kw).fit(Z, Y)
    assert not plain.standardizer_.saturates
    np.testing.assert_array_equal(inf.predict(far), plain.predict(far))
    np.testing.assert_array_equal(inf.predict_gradient(far), plain.predict_gradient(far))
    assert np.abs(plain.predict(far)).max() > 10 * np.abs(sat.predict(far)).max()


@pytest.mark.parametrize("sym", [ca.SX, ca.MX], ids=["SX", "MX"])
def test_casadi_export_with_input_saturation(sym, data):
    """CasADi mean, variance and Jacobian equal predict / predict_gradient (chain rule through
    the saturation), the batch export too; the gradient matches finite differences."""
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, forgetting_factor=0.98, linear_features=True, n_restarts=0,
                            input_saturation=1.5, random_state=2).fit(Z[:60], Y[:60])
    Zq = np.vstack([Zt[:4], 3.0 * Zt[4:7]])  # inside and outside the saturation's knee
    P = model.casadi_param_size()
    z, theta = sym.sym("z", 3), sym.sym("theta", P)
    mean = model.casadi_mean(z, theta)
    fn = ca.Function("gp", [z, theta], [mean, model.casadi_variance(z, theta),
                                        ca.jacobian(mean, z)])
    _check_export(fn, model, Zq)
    model.update(Z[60:], Y[60:])
    _check_export(fn, model, Zq)
    Zb, tb = ca.MX.sym("Z", 3, len(Zq)), ca.MX.sym("theta", P)
    batch = ca.Function("b", [Zb, tb], [model.casadi_mean_batch(Zb, tb)])
    np.testing.assert_allclose(np.asarray(batch(Zq.T, model.casadi_param_values())).T,
                               model.predict(Zq), rtol=1e-10, atol=1e-10)
    for z0 in Zq:
        step = [model.predict((z0 + 1e-6 * e)[None])[0] - model.predict((z0 - 1e-6 * e)[None])[0]
                for e in np.eye(3)]
        np.testing.assert_allclose(model.predict_gradient(z0[None])[0],
                                   np.stack(step, axis=1) / 2e-6, rtol=1e-5, atol=1e-6)


def test_save_load_roundtrip_input_saturation(tmp_path, data):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, forgetting_factor=0.98, linear_features=True, n_restarts=0,
                            input_saturation=3.0, random_state=5).fit(Z[:50], Y[:50])
    model.update(Z[50:80], Y[50:80])
    model.save(tmp_path / "sat.npz")
    loaded = IncrementalSSGP.load(tmp_path / "sat.npz")
    assert loaded.input_saturation == 3.0 and loaded.standardizer_.input_saturation == 3.0
    np.testing.assert_array_equal(model.predict(5 * Zt), loaded.predict(5 * Zt))
    plain = IncrementalSSGP(12, n_restarts=0, random_state=5).fit(Z[:50], Y[:50])
    plain.save(tmp_path / "plain.npz")
    assert IncrementalSSGP.load(tmp_path / "plain.npz").input_saturation is None


@pytest.mark.parametrize("bad", [0.0, -1.0, np.nan, "x"])
def test_bad_input_saturation(bad, data, exact_gp):
    Z, Y, _, _ = data
    with pytest.raises((ValueError, TypeError)):
        SSGP(5, input_saturation=bad, n_restarts=0).fit(Z, Y)
    with pytest.raises(ValueError, match="ExactGP"):
        SSGP(5, hyperparameters=exact_gp, input_saturation=3.0).fit(Z, Y)


# ---------------------------------------------------------------------------- change detection
def test_change_detector_declares_a_persistent_change_only():
    rng = np.random.default_rng(0)
    det = ChangeDetector(ratio=10.0, patience=3, history=20)
    det.reset(2)
    quiet = lambda: 0.01 * np.abs(rng.standard_normal(2))  # noqa: E731
    assert det.threshold() is None  # nothing is surprising before history // 2 errors
    assert not det.step([5.0, 5.0])
    assert not any(det.step(quiet()) for _ in range(60))
    limit = det.threshold()
    assert limit is not None and np.all(limit > 0)
    # one surprising sample (a new region of the state space) declares nothing
    assert not det.step([0.0, 2 * limit[1]])
    assert not det.step(quiet())
    assert det.n_surprising_ == 0
    # a persistent change: the third surprising sample in a row declares it
    big = 2 * limit
    assert [det.step(big) for _ in range(3)] == [False, False, True]
    with pytest.raises(ValueError, match="2 finite numbers"):
        det.step([np.nan, 0.0])
    with pytest.raises(ValueError, match="2 finite numbers"):
        det.step([0.0, 0.0, 0.0])
    for bad in (dict(ratio=1.0), dict(patience=0), dict(patience=1.5), dict(history=1)):
        with pytest.raises(ValueError):
            ChangeDetector(**bad).reset(1)
    assert ChangeDetector(ratio=5.0).clone().get_params() == dict(ratio=5.0, patience=3,
                                                                  history=40)


def test_incremental_restarts_from_the_new_regime(data, exact_gp):
    """A stream from the fitted function, then from a shifted one: one change is declared, and
    the state is then exactly the batch formula over the shifted samples alone (with their
    own forgetting weights and prior ages); without a detector the old data stay."""
    Z, Y, Zt, Yt = data
    shift = np.array([3.0, 30.0])
    lam, m = 0.99, 1
    kw = dict(forgetting_factor=lam, prior_refresh=m, hyperparameters=exact_gp, random_state=3)
    model = IncrementalSSGP(15, change_detector=ChangeDetector(), **kw).fit(Z[:60], Y[:60])
    plain = IncrementalSSGP(15, **kw).fit(Z[:60], Y[:60])
    for i in range(60, 90):  # the same function: nothing declared
        model.update(Z[i : i + 1], Y[i : i + 1])
    assert model.n_changes_ == 0
    model.update(Z[90:], Y[90:] + shift)  # one call, samples taken one at a time
    plain.update(Z[60:90], Y[60:90])
    plain.update(Z[90:], Y[90:] + shift)
    assert model.n_changes_ == 1
    assert model.n_samples_seen_ == len(Z) and model.n_state_samples_ == len(Z) - 90
    W_ref = _batch_reference(model, Z[90:], Y[90:] + shift, lam, m)
    np.testing.assert_allclose(model.weights_, W_ref, rtol=1e-8, atol=1e-8 * np.abs(W_ref).max())
    np.testing.assert_allclose(model.prior_diagonal(),
                               plain.hyperparameters_.noise_std[:, None] ** 2
                               * lam ** _simulated_prior_ages(len(Z) - 90, 30, m)[None, :])
    err_model = np.abs(model.predict(Zt) - (Yt + shift)).mean(axis=0)
    err_plain = np.abs(plain.predict(Zt) - (Yt + shift)).mean(axis=0)
    assert np.all(err_model < 0.5 * err_plain)


def test_detector_history_is_seeded_with_exact_leave_one_out_errors(data, exact_gp):
    """The errors seeding the detector at a fit against refitting without each sample (the
    dense weighted formula with sample i removed from A and b), and a change right after the
    fit (the system changed between data collection and control) is caught at once."""
    Z, Y, _, _ = data
    lam = 0.98
    det = ChangeDetector(history=12)
    model = IncrementalSSGP(15, forgetting_factor=lam, prior_refresh=100,
                            hyperparameters=exact_gp, change_detector=det,
                            random_state=3).fit(Z[:60], Y[:60])
    std, hyp = model.standardizer_, model.hyperparameters_
    Zs, Ys = std.transform_inputs(Z[:60]), std.transform_outputs(Y[:60])
    wts = lam ** np.arange(59, -1, -1, dtype=float)
    expected = np.empty((12, 2))
    for j in range(2):
        F = model._features(Zs, j)
        A = F.T @ (wts[:, None] * F) + np.diag(hyp.noise_std[j] ** 2 * np.ones(F.shape[1]))
        b = F.T @ (wts * Ys[:, j])
        for k, i in enumerate(range(48, 60)):
            w = np.linalg.solve(A - wts[i] * np.outer(F[i], F[i]), b - wts[i] * F[i] * Ys[i, j])
            expected[k, j] = abs(Ys[i, j] - F[i] @ w)
    seeded = np.array(model.detector_._errors).T
    np.testing.assert_allclose(seeded, expected, rtol=1e-7, atol=1e-10)
    model.update(Z[60:64], Y[60:64] + np.array([3.0, 30.0]))
    # declared at the third shifted sample (patience 3), which the fourth then joins
    assert model.n_changes_ == 1 and model.n_state_samples_ == 4


def test_save_load_roundtrip_change_detector(tmp_path, data, exact_gp):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, forgetting_factor=0.99, hyperparameters=exact_gp,
                            change_detector=ChangeDetector(ratio=8.0, patience=2, history=10),
                            random_state=5).fit(Z[:60], Y[:60])
    model.update(Z[60:80], Y[60:80])
    model.update(Z[80:], Y[80:] + np.array([3.0, 30.0]))
    assert model.n_changes_ == 1
    path = tmp_path / "ssgp_detector.npz"
    model.save(path)
    loaded = IncrementalSSGP.load(path)
    assert loaded.change_detector.get_params() == model.change_detector.get_params()
    assert (loaded.n_changes_, loaded.n_state_samples_) == (1, model.n_state_samples_)
    np.testing.assert_array_equal(model.predict(Zt), loaded.predict(Zt))
    with pytest.raises(TypeError, match="ChangeDetector"):
        IncrementalSSGP(12, change_detector="auto").fit(Z, Y)


def test_nominal_fallback_averages_squared_errors():
    """``NominalFallback.step``: exponential averages of the summed squared errors (hand
    computed), on while the learner's is at most zero's; bad settings and inputs raise."""
    fb = NominalFallback(memory=0.5)
    fb.reset()
    assert fb.on_ and fb.step([3.0, 0.0], [1.0, 1.0]) is False  # 9 > 2
    assert (fb.learned_error_, fb.zero_error_) == (9.0, 2.0)
    assert fb.step([0.0, 0.0], [4.0, 0.0]) is True  # 0.5 * 9 + 0.5 * 0 <= 0.5 * 2 + 0.5 * 16
    assert (fb.learned_error_, fb.zero_error_) == (4.5, 9.0) and fb.on_ is True
    assert NominalFallback(0.0).clone().get_params() == {"memory": 0.0}
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(ValueError, match="memory"):
            NominalFallback(bad).reset()
    with pytest.raises(ValueError, match="finite"):
        fb.step([1.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        fb.step([np.nan, 0.0], [1.0, 2.0])


def test_nominal_fallback_switches_the_residual_off_and_keeps_learning(data, exact_gp):
    """A learner fitted on one function, then fed samples of the *negated* one (the system
    changed: the old model is worse than none): the residual goes off, so predict, its
    gradient and the CasADi mean are zero, the variance is unchanged; the state is exactly the
    plain learner's (learning went on); fed more of the new function it comes back on and then
    predicts exactly as the plain learner."""
    Z, Y, Zt, _ = data
    kw = dict(forgetting_factor=0.9, hyperparameters=exact_gp, random_state=3)
    model = IncrementalSSGP(15, nominal_fallback=NominalFallback(), **kw).fit(Z[:60], Y[:60])
    plain = IncrementalSSGP(15, **kw).fit(Z[:60], Y[:60])
    assert model.residual_on_
    np.testing.assert_array_equal(model.predict(Zt), plain.predict(Zt))
    off_at = None
    for i in range(60, 120):
        model.update(Z[i:i + 1], -Y[i:i + 1])
        plain.update(Z[i:i + 1], -Y[i:i + 1])
        if off_at is None and not model.residual_on_:
            off_at = i
            mean, std = model.predict(Zt, return_std=True)
            assert np.all(mean == 0.0) and np.all(model.predict_gradient(Zt) == 0.0)
            np.testing.assert_allclose(std, plain.predict(Zt, return_std=True)[1], rtol=1e-12)
            z = ca.MX.sym("z", 3)
            theta = model.casadi_param_values()
            f = ca.Function("f", [z], [model.casadi_mean(z, ca.DM(theta))])
            assert np.all(np.asarray(f(Zt[0])) == 0.0)
            np.testing.assert_array_equal(model.weights_, plain.weights_)
        if off_at is not None and model.residual_on_:
            break
    assert off_at == 60  # the first negated sample already shows the old model is worse
    assert model.residual_on_, "never came back on after learning the new function"
    np.testing.assert_array_equal(model.predict(Zt), plain.predict(Zt))
    z = ca.MX.sym("z", 3)
    f = ca.Function("f", [z], [model.casadi_mean(z, ca.DM(model.casadi_param_values()))])
    np.testing.assert_allclose(np.asarray(f(Zt[0])).ravel(), plain.predict(Zt[:1])[0],
                               rtol=1e-9, atol=1e-9)


def test_save_load_roundtrip_nominal_fallback(tmp_path, data, exact_gp):
    Z, Y, Zt, _ = data
    model = IncrementalSSGP(12, hyperparameters=exact_gp, random_state=5,
                            nominal_fallback=NominalFallback(memory=0.6)).fit(Z[:60], Y[:60])
    model.update(Z[60:80], Y[60:80])
    path = tmp_path / "ssgp_fallback.npz"
    model.save(path)
    loaded = IncrementalSSGP.load(path)
    assert loaded.nominal_fallback.get_params() == {"memory": 0.6} and loaded.residual_on_
    np.testing.assert_array_equal(model.predict(Zt), loaded.predict(Zt))
    with pytest.raises(TypeError, match="NominalFallback"):
        IncrementalSSGP(12, nominal_fallback="auto").fit(Z, Y)


def test_online_ssgp_length_scales_respect_the_recipes_floors():
    """``online_ssgp``: length scales of at least one input standard deviation, five with
    linear features; on these noisy data the likelihood wants shorter ones (the one-sigma
    fit with linear features goes below five), so the floor is what binds."""
    from gp_agents import online_ssgp
    from gp_agents.learners import (
        LENGTH_SCALE_FLOOR,
        LINEAR_LENGTH_SCALE_FLOOR,
        HyperparameterBounds,
    )

    rng = np.random.default_rng(0)
    Z = rng.normal(size=(200, 6))
    Z[:, 5] = 1.0 + 1e-5 * rng.normal(size=200)  # an input that hardly varies
    Y = np.c_[np.sin(Z[:, 0]), 0.5 * Z[:, 1]] + 0.3 * rng.normal(size=(200, 2))
    plain = online_ssgp(20).fit(Z, Y).hyperparameters_.length_scales
    linear = online_ssgp(20, linear_features=True).fit(Z, Y).hyperparameters_.length_scales
    one_sigma = IncrementalSSGP(20, hyperparameters="ssgp", random_state=0,
                                linear_features=True,
                                bounds=HyperparameterBounds(length_scale=(1.0, 100.0)))
    loose = one_sigma.fit(Z, Y).hyperparameters_.length_scales
    assert plain.min() >= LENGTH_SCALE_FLOOR * (1 - 1e-9)
    assert linear.min() >= LINEAR_LENGTH_SCALE_FLOOR * (1 - 1e-9)
    assert loose.min() < LINEAR_LENGTH_SCALE_FLOOR


def test_parametric_ssgp_is_the_saturated_learner_with_linear_features_on_given_columns(data):
    """``parametric_ssgp(columns)``: linear features on those columns only, with the change
    detector, the nominal fallback and the input saturation; no columns is an error."""
    from gp_agents.learners import INPUT_SATURATION, parametric_ssgp

    Z, Y, _, _ = data
    model = parametric_ssgp((-1,), n_frequencies=8).fit(Z, Y)
    np.testing.assert_array_equal(model.linear_mask_, [0.0, 0.0, 1.0])
    assert model.change_detector is not None and model.nominal_fallback is not None
    assert model.standardizer_.input_saturation == INPUT_SATURATION
    with pytest.raises(ValueError, match="sensitivities"):
        parametric_ssgp(())
