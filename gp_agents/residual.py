"""The semi-parametric model's learned part: the learner's inputs and targets.

Paper, "Problem Formulation": ``f_t(x, u) = f_p(x, u) + f_err(x, u)``, with ``f_err`` a GP
whose training targets are ``y = f_t(x, u) - f_p(x, u)``. The true ``f_t`` is never observed,
only transitions ``(x_k, u_k, x_{k+1})`` sampled every control period ``dt`` under zero-order
hold. :class:`ResidualModel` turns those into targets by asking which *constant* residual ``r``
on the uncertain components ``I`` (by default the model's ``dynamic_indices``: the accelerations)
makes the nominal model reproduce the observed transition:

    find r:  Phi_{p + S r}(x_k, u_k)[I] = x_{k+1}[I],        z_k = phi( (x_k + x_{k+1}) / 2, u_k )

where ``Phi_{p + S r}`` is the RK4 step of ``f_p + S r`` over ``dt`` (``S`` places ``r`` into the
state derivative) and ``phi`` the input feature map. It starts from the finite difference
``(x_{k+1} - Phi_p(x_k, u_k))[I] / dt`` and takes two Newton steps (the map is nearly linear in
``r``). The result is exact when ``f_err`` is constant over the period; otherwise it is the
period's effective residual, and taking the input at the period's midpoint makes it a second-order
estimate of ``f_err(z_k)``. (The plain finite difference also carries the drift of the nominal
path away from the true one within the period, ~8% RMS on the cart-pole accelerations.)
``tests/test_mpc.py`` measures the error against the oracle's true residual.

The default feature map replaces each angle by its sine and cosine (so wrapped observations and
unwrapped plans give the same input) and appends the control.

*Parameter sensitivities* (``sensitivities=True``): the input is extended by the structurally
nonzero entries of ``S(x, u) = d f_p[I] / d p`` at the nominal parameter values ``p`` (every
parameter of the model, including those whose nominal value is zero, such as the cart pole's
damping). If the truth is the nominal model's structure with other values ``p + dp``, then
``f_err = S(x, u) dp + O(|dp|^2)``: a learner with linear features in these inputs
(``IncrementalSSGP(linear_features=residual.sensitivity_columns)``; ``True`` puts them on every
input, which extrapolates as an offset, see :func:`gp_agents.parametric_ssgp`) holds an explicit
parametric part of the residual, a handful of weights per output that the data identify within a
few samples and that extrapolates with the physics, and its Fourier features model the rest
(second-order terms and effects outside the model's structure). ``tests/test_mpc.py`` fits
``S dp`` to the cart pole's true residual by least squares. The nominal model's structure is what
the controller knows already; only its values are wrong. The ``robust`` recipe
(:func:`gp_agents.make_mpc`) uses it; off by default, since the paper's recipe is without it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from gp_agents.pseudospectral.buffered import BufferedFunction
from gp_envs.model import ControlModel, rk4


class ResidualModel:
    """Maps between a :class:`ControlModel` and a learner's inputs and targets.

    The combined ODE the MPC plans with is :class:`gp_agents.mpc.planning_model.PlanningModel`.

    Args:
        model: the nominal model the residual corrects.
        uncertain_indices: state components that get a learned residual (default: the model's
            ``dynamic_indices``).
        input_indices: state components fed to the learner: indices, ``None`` (all), or
            ``"model"``: those the parametric nominal model's uncertain rates depend on
            (:meth:`model_inputs`).
        sensitivities: append the parameter sensitivities ``d f_p[I] / d p`` to the input
            (module docstring; names in :attr:`input_names`).
    """

    def __init__(self, model: ControlModel, uncertain_indices: Sequence[int] | None = None,
                 input_indices: Sequence[int] | str | None = None,
                 sensitivities: bool = False) -> None:
        n = model.n_states
        unc = tuple(model.dynamic_indices if uncertain_indices is None else uncertain_indices)
        if isinstance(input_indices, str):
            if input_indices != "model":
                raise ValueError(f"input_indices must be indices, None or 'model', "
                                 f"got {input_indices!r}")
            input_indices = self.model_inputs(model, unc)
            if not input_indices:
                raise ValueError("input_indices='model': the nominal model's uncertain rates "
                                 "depend on no state component; give the indices explicitly")
        inp = tuple(range(n) if input_indices is None else input_indices)
        for name, idx in (("uncertain_indices", unc), ("input_indices", inp)):
            if not idx or any(not 0 <= int(i) < n for i in idx) or len(set(idx)) != len(idx):
                raise ValueError(f"{name} must be distinct indices in [0, {n}), got {idx}")
        self.model = model
        self.uncertain_indices = tuple(int(i) for i in unc)
        self.input_indices = tuple(int(i) for i in inp)
        self.sensitivities = bool(sensitivities)
        self._sensitivity_entries: tuple[tuple[int, int], ...] = ()
        self._sensitivity_fn: ca.Function | None = None
        if sensitivities:
            self._sensitivity_entries, self._sensitivity_fn = self._build_sensitivities()
        x = ca.SX.sym("x", n)
        u = ca.SX.sym("u", model.n_controls)
        self._features_fn = ca.Function("phi", [x, u], [self.features(x, u)])
        z = self.features(x, u)
        dz = ca.jacobian(z, ca.vertcat(x, u))
        self._features_jac_fn = ca.Function("phi_jac", [x, u], [z, ca.densify(dz)])
        self._mapped: dict[tuple[str, int], BufferedFunction] = {}
        self.jacobian_columns = tuple(sorted({int(c) for c in dz.sparsity().get_col()}))
        """Columns of ``[x; u]`` the learner's input depends on (where the residual's Jacobian
        can be nonzero)."""
        self.n_inputs = int(self._features_fn.size1_out(0))
        self.n_outputs = len(self.uncertain_indices)
        self.selector = np.zeros((n, self.n_outputs))
        """(n, d_out) matrix placing the learned outputs into the state derivative."""
        for j, i in enumerate(self.uncertain_indices):
            self.selector[i, j] = 1.0
        # one RK4 period of f_nominal + S r, its mismatch on I and that mismatch's Jacobian in r
        r = ca.SX.sym("r", self.n_outputs)
        x_next = ca.SX.sym("x_next", n)
        f_nom = model.casadi_function()
        sel = ca.DM(self.selector)
        stepped = rk4(lambda xx: f_nom(xx, u) + ca.mtimes(sel, r), x, model.dt, model.substeps)
        mismatch = (stepped - x_next)[list(self.uncertain_indices)]
        newton = ca.Function("newton", [x, u, x_next, r], [mismatch, ca.jacobian(mismatch, r)])
        # the target: the finite difference, then two Newton steps, all in one function
        y = -newton(x, u, x_next, ca.DM.zeros(self.n_outputs))[0] / model.dt
        for _ in range(2):
            g, J = newton(x, u, x_next, y)
            y = y - ca.solve(J, g)
        self._target_fn = ca.Function("target", [x, u, x_next],
                                      [self.features(0.5 * (x + x_next), u), y])

    @staticmethod
    def model_inputs(model: ControlModel, uncertain_indices: Sequence[int]) -> tuple[int, ...]:
        """State components the uncertain rates of the *parametric* nominal model depend on.

        The structural dependence of ``f_nominal(x, u; params)`` with the parameters symbolic:
        the residual of wrong parameter values is a function of these components (and ``u``)
        only, e.g. not of the quadrotor's position or velocity. An effect outside the model's
        structure (drag on a drag-free model) may depend on others: then feed all components.

        Args:
            model: the nominal model. uncertain_indices: rows of ``f`` with a residual.

        Returns:
            Sorted state indices (empty if the rates depend on ``u`` only).
        """
        f = model.casadi_parametric_function()
        x = ca.SX.sym("x", model.n_states)
        u = ca.SX.sym("u", model.n_controls)
        p = ca.SX.sym("p", len(model.param_names))
        rows = ca.jacobian(f(x, u, p)[list(uncertain_indices)], x).sparsity()
        return tuple(sorted({int(c) for c in rows.get_col()}))

    def _build_sensitivities(self) -> tuple[tuple[tuple[int, int], ...], ca.Function]:
        """The ``(output j, parameter k)`` pairs where ``d f_p[I_j] / d p_k`` is structurally
        nonzero (output-major), and ``(x, u) -> those entries`` at the nominal values."""
        m = self.model
        x = ca.SX.sym("x", m.n_states)
        u = ca.SX.sym("u", m.n_controls)
        p = ca.SX.sym("p", len(m.param_names))
        S = ca.jacobian(m.casadi_parametric_function()(x, u, p)[list(self.uncertain_indices)], p)
        rows, cols = S.sparsity().get_triplet()
        entries = tuple(sorted((int(j), int(k)) for j, k in zip(rows, cols, strict=True)))
        if not entries:
            raise ValueError("sensitivities=True: the uncertain rates depend on no parameter of "
                             f"the {m.name} model")
        nominal = ca.DM([float(m.params[k]) for k in m.param_names])
        values = ca.substitute(ca.vertcat(*[S[j, k] for j, k in entries]), p, nominal)
        return entries, ca.Function("sensitivities", [x, u], [values])

    # ------------------------------------------------------------------ inputs
    @property
    def input_names(self) -> tuple[str, ...]:
        """(d_in,) names of the learner's input components, in order (``sin(theta)``, ``u0``,
        ``d(thetadot)/d(b2)``, ...)."""
        m = self.model
        angles = set(m.angle_indices)
        names = [m.state_names[i] for i in self.input_indices if i not in angles]
        names += [f"{f}({m.state_names[i]})" for i in self.input_indices if i in angles
                  for f in ("sin", "cos")]
        names += list(m.control_names)
        names += [f"d({m.state_names[self.uncertain_indices[j]]})/d({m.param_names[k]})"
                  for j, k in self._sensitivity_entries]
        return tuple(names)

    @property
    def sensitivity_columns(self) -> tuple[int, ...]:
        """Columns of the learner's input holding the parameter sensitivities (the last
        ones; empty without ``sensitivities``): e.g. a learner's ``linear_features`` for the
        residual's parametric part alone (:class:`~gp_agents.learners.SSGP`)."""
        k = len(self._sensitivity_entries)
        return tuple(range(self.n_inputs - k, self.n_inputs))

    def features(self, x: ca.SX | ca.MX, u: ca.SX | ca.MX) -> ca.SX | ca.MX:
        """Learner input ``z = phi(x, u)``: non-angle states, sin/cos of angles, the controls,
        then (with ``sensitivities``) the parameter sensitivities at the nominal values.

        Args:
            x: (n, 1) symbolic state. u: (m, 1) symbolic control.

        Returns:
            (d_in, 1) symbolic input.
        """
        angles = set(self.model.angle_indices)
        plain = [x[i] for i in self.input_indices if i not in angles]
        trig = [f(x[i]) for i in self.input_indices if i in angles for f in (ca.sin, ca.cos)]
        z = ca.vertcat(*plain, *trig, u)
        if self._sensitivity_fn is None:
            return z
        return ca.vertcat(z, self._sensitivity_fn(x, u))

    def inputs(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """Numeric learner inputs for states (N, n) and controls (N, m) -> (N, d_in)."""
        X = np.atleast_2d(np.asarray(X, float))
        U = np.atleast_2d(np.asarray(U, float))
        (Z,) = self._map(self._features_fn, X.shape[0])(X.T, U.T)
        return _rows(Z, X.shape[0])

    def input_function(self, jacobian: bool = False) -> ca.Function:
        """The input map as a CasADi Function, for compiled expressions: ``(x, u) -> z``
        (d_in,), or with ``jacobian`` ``(x, u) -> (z, dz/d[x; u])`` ((d_in, n + m), dense)."""
        return self._features_jac_fn if jacobian else self._features_fn

    def _map(self, fn: ca.Function, n: int) -> BufferedFunction:
        """``fn.map(n)`` called on numpy memory (outputs flat, column-major), built once per
        size (building a map costs more than evaluating it)."""
        key = (fn.name(), n)
        if key not in self._mapped:
            self._mapped[key] = BufferedFunction(fn.map(n))
        return self._mapped[key]

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_mapped"] = {}  # evaluation buffers are rebuilt on demand
        return state

    # ------------------------------------------------------------------ targets
    def targets(self, X: np.ndarray, U: np.ndarray, X_next: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Learner inputs and residual targets from observed transitions (see module doc).

        Args:
            X: (N, n) states at the start of each control period (as observed).
            U: (N, m) controls applied over the period.
            X_next: (N, n) states observed one period later.

        Returns:
            Z (N, d_in) inputs and Y (N, d_out) residual rates of the uncertain components.

        Raises:
            ValueError: on shape mismatches or non-finite values.
        """
        X = np.atleast_2d(np.asarray(X, float))
        U = np.atleast_2d(np.asarray(U, float))
        X_next = np.atleast_2d(np.asarray(X_next, float))
        n, m = self.model.n_states, self.model.n_controls
        if X.shape[1] != n or X_next.shape != X.shape or U.shape != (X.shape[0], m):
            raise ValueError(f"expected X, X_next (N, {n}) and U (N, {m}); "
                             f"got {X.shape}, {X_next.shape}, {U.shape}")
        for name, arr in (("X", X), ("U", U), ("X_next", X_next)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{name} contains NaN or inf")
        X_next = self.unwrap_like(X_next, X)
        N = X.shape[0]
        Z, Y = self._map(self._target_fn, N)(X.T, U.T, X_next.T)
        Z, Y = _rows(Z, N), _rows(Y, N)
        if not np.all(np.isfinite(Y)):
            raise ValueError("residual targets are not finite (a transition the nominal model "
                             "cannot reproduce with any constant residual?)")
        return Z, Y

    def unwrap_like(self, X: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """Shift angle components of ``X`` by multiples of 2 pi to be nearest ``reference``."""
        X = np.array(X, dtype=float, copy=True)
        for i in self.model.angle_indices:
            X[..., i] -= 2 * np.pi * np.round((X[..., i] - reference[..., i]) / (2 * np.pi))
        return X

    # ------------------------------------------------------------------ linearization
    def linearize(self, learner: Any, X: np.ndarray, U: np.ndarray, variance: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The learned residual's value and Jacobian in ``(x, u)`` at given points.

        ``mean(phi(x, u)) ~ mean(phi(xb, ub)) + J [x - xb; u - ub]``: the first-order model the
        MPC's ``learned_dynamics="linearized"`` mode plans with. Computed with the learner's own
        numeric ``predict`` and ``predict_gradient`` and the chain rule through the input map
        ``phi`` (whose Jacobian CasADi differentiates), for all points at once.

        Args:
            learner: a fitted learner (``predict``, ``predict_gradient``).
            X: (M, n) states. U: (M, m) controls.
            variance: also return the predictive variance (noise included).

        Returns:
            mean (M, d_out), J (M, d_out, n + m), and the variance (M, d_out) or None.
        """
        X = np.atleast_2d(np.asarray(X, float))
        U = np.atleast_2d(np.asarray(U, float))
        M, n, m = X.shape[0], self.model.n_states, self.model.n_controls
        if X.shape != (M, n) or U.shape != (M, m):
            raise ValueError(f"expected X (M, {n}) and U (M, {m}), got {X.shape}, {U.shape}")
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
            raise ValueError("linearize got a non-finite state or control")
        Z, dZ = self._map(self._features_jac_fn, M)(X.T, U.T)
        Z = _rows(Z, M)
        dZ = np.ascontiguousarray(dZ.reshape(M * (n + m), self.n_inputs).T)
        dZ = dZ.reshape(self.n_inputs, M, -1).transpose(1, 0, 2)  # (M, d_in, n+m)
        if variance:
            mean, std = learner.predict(Z, return_std=True)
            var = np.asarray(std) ** 2
        else:
            mean, var = learner.predict(Z), None
        grad = learner.predict_gradient(Z)  # (M, d_out, d_in)
        return np.asarray(mean), np.einsum("kid,kdj->kij", grad, dZ), var


def _rows(flat: np.ndarray, n: int) -> np.ndarray:
    """A mapped function's flat column-major (d, n) output as (n, d) rows, Fortran-ordered as
    the transpose of a DM's array was (the learners' results depend on the layout in the last
    bits: BLAS sums in another order)."""
    return np.asfortranarray(flat.reshape(n, -1))
