"""The grey-box baseline: recursive least squares on the parameter sensitivities alone
(``parametric_rls``, ``IncrementalSSGP`` with no Fourier features) and the ``"parametric"``
recipe."""

from __future__ import annotations

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest

import gp_envs  # noqa: F401  (registers the envs)
from gp_agents import collect_initial_data, make_mpc
from gp_agents.learners import SSGP, IncrementalSSGP, parametric_rls
from gp_agents.mpc.recipes import RECIPES

COLS = (3, 4, 5)


def _data(n: int, seed: int = 0, noise: float = 0.01):
    rng = np.random.default_rng(seed)
    Z = rng.normal(size=(n, 6))
    W = np.array([[0.3, -1.0], [1.5, -1.2], [-0.5, 1.4]])
    return Z, Z[:, 3:] @ W + noise * rng.normal(size=(n, 2)), W


def _batch_weights(learner: IncrementalSSGP, Z: np.ndarray, Y: np.ndarray, lam: float
                   ) -> np.ndarray:
    """The weighted ridge solution, computed independently, in standardized units; the prior
    as the learner's (``prior_diagonal``) over the sensitivity columns."""
    s, hyp = learner.standardizer_, learner.hyperparameters_
    Zs, Ys = s.transform_inputs(Z), s.transform_outputs(Y)
    w = lam ** np.arange(len(Z) - 1, -1, -1, dtype=float)
    out = []
    for j in range(2):
        F = learner.linear_std_[j] * Zs[:, list(COLS)]
        P = learner.prior_diagonal()[j][list(COLS)]
        A = (F * w[:, None]).T @ F + np.diag(P)
        out.append(np.linalg.solve(A, (F * w[:, None]).T @ Ys[:, j]))
    assert hyp is not None
    return np.array(out)


def test_zero_frequencies_need_linear_features():
    Z, Y, _ = _data(20)
    with pytest.raises(ValueError, match="n_frequencies"):
        SSGP(0).fit(Z, Y)
    with pytest.raises(ValueError, match="n_frequencies"):
        IncrementalSSGP(-1, linear_features=COLS).fit(Z, Y)


@pytest.mark.parametrize("lam", [1.0, 0.99])
def test_incremental_equals_batch_least_squares(lam):
    Z, Y, _ = _data(200)
    learner = parametric_rls(COLS, forgetting_factor=lam).fit(Z[:50], Y[:50])
    for k in range(50, 200, 30):
        learner.update(Z[k:k + 30], Y[k:k + 30])
    W = learner.weights_
    assert W.shape == (2, 6)
    np.testing.assert_array_equal(W[:, :3], 0.0)  # no weight off the sensitivity columns
    np.testing.assert_allclose(W[:, 3:], _batch_weights(learner, Z, Y, lam), rtol=1e-8,
                               atol=1e-10)


def test_forgetting_tracks_a_change():
    Z, Y, W = _data(400)
    Y2 = Z[:, 3:] @ (2.0 * W)
    slopes = {}
    for lam in (1.0, 0.97):
        learner = parametric_rls(COLS, forgetting_factor=lam).fit(Z[:100], Y[:100])
        learner.update(Z[100:300], Y[100:300]).update(Z[300:], Y2[300:])
        Zt = np.random.default_rng(1).normal(size=(200, 6))
        slopes[lam] = np.sqrt(np.mean((learner.predict(Zt) - Zt[:, 3:] @ (2.0 * W)) ** 2))
    assert slopes[0.97] < 0.5 * slopes[1.0]


def test_casadi_export_equals_predict():
    Z, Y, _ = _data(120)
    learner = parametric_rls(COLS).fit(Z[:60], Y[:60]).update(Z[60:], Y[60:])
    theta = learner.casadi_param_values()
    assert learner.casadi_param_size() == theta.size
    z, th = ca.MX.sym("z", 6), ca.MX.sym("theta", theta.size)
    f = ca.Function("f", [z, th], [learner.casadi_mean(z, th), learner.casadi_variance(z, th)])
    Zb = ca.MX.sym("Z", 6, 5)
    mean, grads = learner.casadi_mean_gradient_batch(Zb, th)
    fb = ca.Function("fb", [Zb, th], [mean, learner.casadi_mean_batch(Zb, th),
                                      learner.casadi_variance_batch(Zb, th), *grads])
    m, s = learner.predict(Z[:5], return_std=True)
    G = learner.predict_gradient(Z[:5])
    for k in range(5):
        mk, vk = f(Z[k], theta)
        np.testing.assert_allclose(np.array(mk).ravel(), m[k], atol=1e-12)
        np.testing.assert_allclose(np.array(vk).ravel(), s[k] ** 2, rtol=1e-10)
    out = [np.array(o) for o in fb(Z[:5].T, theta)]
    np.testing.assert_allclose(out[0].T, m, atol=1e-12)
    np.testing.assert_allclose(out[1].T, m, atol=1e-12)
    np.testing.assert_allclose(out[2].T, s ** 2, rtol=1e-10)
    for j in range(2):
        np.testing.assert_allclose(out[3 + j].T, G[:, j, :], atol=1e-12)
    assert learner.casadi_mean_param_values().size == learner.casadi_mean_param_size()


def test_recipe_is_listed_and_binds_the_sensitivity_columns():
    assert "parametric" in RECIPES
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online", randomize=0.1)
    agent = make_mpc(env, "parametric")
    assert isinstance(agent.learner, IncrementalSSGP) and agent.learner.n_frequencies == 0
    cols = agent.config.residual.model(agent.model).sensitivity_columns
    assert tuple(agent.learner.linear_features) == tuple(cols)
    env.close()


def test_recipe_pretrains_and_acts():
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online", randomize=0.1)
    agent = make_mpc(env, "parametric").pretrain(collect_initial_data(env, 100, seed=0))
    obs, _ = env.reset(seed=0)
    agent.reset()
    for _ in range(3):
        action = agent.act(obs)
        assert np.all(np.isfinite(action))
        obs, *_ = env.step(action)
    env.close()


def test_learned_residual_error_falls_in_family():
    """A truth that differs from the nominal model only in its parameter values (a randomized
    cart pole): the parametric residual's error on held-out transitions falls as data come."""
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online", randomize=0.1)
    agent = make_mpc(env, "parametric")
    data = collect_initial_data(env, 400, seed=3)
    X, U, Xn = data.X, data.U, data.X_next
    Zt, Yt = agent._residual.targets(X[300:], U[300:], Xn[300:])
    errors = []
    for n in (10, 40, 300):
        agent.learner.fit(*agent._residual.targets(X[:n], U[:n], Xn[:n]))
        errors.append(float(np.sqrt(np.mean((agent.learner.predict(Zt) - Yt) ** 2))))
    zero = float(np.sqrt(np.mean(Yt ** 2)))
    assert errors[2] < errors[0] and errors[2] < 0.2 * zero, (errors, zero)
    env.close()
