"""Incremental Sparse Spectrum GP with exponential forgetting (paper, Section "Online model
learning"; errata note 4; Gijsberts & Metta 2013).

State per output ``j`` after ``n`` samples (standardized units, ``phi_i = phi(z_i)``)::

    A_n = P_n + sum_{i=1..n} lambda^(n-i) phi_i phi_i^T,     A_n = R_n^T R_n  (R upper)
    b_n =       sum_{i=1..n} lambda^(n-i) phi_i y_i,          w = R^{-1} (R^{-T} b)

*Scaling.* Data enter with weight 1 (``A <- lambda A + phi phi^T``), not ``(1 - lambda)`` as in
the paper: the two differ only by the factor ``1/(1 - lambda)`` on the prior's relative weight,
and the unscaled form makes ``lambda = 1`` exactly the batch SSGP (``A = Phi Phi^T +
sigma_n^2 I``) and keeps the prior at its Bayesian weight ``sigma_n^2`` for every ``lambda``.

*Prior.* Forgetting the prior as well (``P_n = lambda^n sigma_n^2 I``) lets ``A`` become singular
once the data stop exciting every feature (e.g. while the controller holds the pole upright).
Keeping ``P_n = sigma_n^2 I`` exactly would need a full-rank update per sample. Instead the
prior is re-injected one coordinate at a time (cyclic "dynamic regularization", Gay 1996):
at sample ``n`` the ``m = prior_refresh`` coordinates at positions ``(n-1) m, ..., n m - 1``
(mod ``D = 2r``) are restored to ``sigma_n^2``, and the others decay with ``lambda``. Hence
exactly

    P_n = sigma_n^2 diag(lambda^(a_1(n)), ..., lambda^(a_D(n))),

where ``a_k(n)`` is the number of samples since coordinate ``k`` was last restored (``n`` if
never; see :func:`prior_ages`). Every ``a_k <= ceil(D/m) - 1`` once ``n >= ceil(D/m)``, so

    sigma_n^2 lambda^(ceil(D/m) - 1) I <= P_n <= sigma_n^2 I

for all ``n``: the smallest eigenvalue of ``A`` never decays, whatever the data. With ``m >= D``
the prior is exactly ``sigma_n^2 I`` (at ``O(r^3)`` per sample); ``lambda = 1`` needs no refresh.

*Update.* A batch of ``p`` samples is one factor update: ``R <- chol(lambda^p R^T R + B^T B)``
with the rows ``B = [sqrt(lambda^(p-1-i)) phi_i^T ; sqrt(delta_k) e_k^T]`` (data, then the
restored prior amounts ``delta_k``), done by :func:`cholesky_add_rows` in ``O((p + m p) r^2)``;
``b <- lambda^p b + sum_i lambda^(p-1-i) phi_i y_i``. Hyperparameters, frequencies and the
standardization are frozen at :meth:`IncrementalSSGP.fit`, so the CasADi parameter vector keeps
its size.

*Change detection* (``change_detector=ChangeDetector()``, :mod:`gp_agents.learners.change`):
samples are then added one at a time, each after its one-step prediction error (standardized)
went to the detector; when the detector declares a change, the state is rebuilt by the batch
formula from the run of samples that declared it alone (``n`` restarts at the run's length;
``n_samples_seen_`` keeps counting every sample, ``n_changes_`` counts the changes). At
:meth:`IncrementalSSGP.fit` the detector's history is seeded with the leave-one-out errors of
the last fitted samples, ``(y_i - mean_i) / (1 - h_i)`` with ``h_i = lambda^(n-i) phi_i^T
A^{-1} phi_i`` (the exact leave-one-out error of the weighted Bayesian linear regression).

*Nominal fallback* (``nominal_fallback=NominalFallback()``, :mod:`gp_agents.learners.fallback`):
samples likewise go in one at a time, each after its one-step error and the zero residual's went
to the fallback; while the fallback is off (the learner predicts the newest samples worse than
zero) :meth:`~IncrementalSSGP.predict` and :meth:`~IncrementalSSGP.predict_gradient` return a
zero mean and gradient and the CasADi parameters carry zero weights and output offsets, so
``casadi_mean`` is zero too; the variance and the learning are unchanged.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.linalg import cholesky

from ._validation import check_training_data
from .change import ChangeDetector
from .cholesky_update import cholesky_add_rows
from .fallback import NominalFallback
from .hyperparameters import GPHyperparameters, HyperparameterBounds
from .ssgp import SSGP, HyperparameterSource
from .standardization import Standardizer

__all__ = ["IncrementalSSGP", "prior_ages"]

_FORMAT_VERSION = 1


def prior_ages(n: int, n_features: int, refresh: int) -> np.ndarray:
    """Samples since each prior coordinate was last restored, after ``n`` samples.

    Refresh positions run ``0, 1, 2, ...``; sample ``t`` (1-based) restores positions
    ``(t-1) m .. t m - 1``, position ``q`` being coordinate ``q mod D``.

    Args:
        n: samples processed so far (>= 0).
        n_features: ``D``.
        refresh: ``m`` coordinates restored per sample (>= 1).

    Returns:
        (D,) integer ages ``a_k(n)`` (``n`` for a coordinate never restored).
    """
    k = np.arange(n_features)
    if n == 0:
        return np.zeros(n_features, dtype=np.int64)
    q_last = n * refresh - 1
    q_k = q_last - np.mod(q_last - k, n_features)  # last position that hit coordinate k
    return np.where(q_k < 0, n, n - (q_k // refresh + 1)).astype(np.int64)


class IncrementalSSGP(SSGP):
    """SSGP updated online in ``O(r^2)`` per sample, with forgetting factor ``lambda``.

    Args:
        n_frequencies: ``r`` (``2r`` features per output); 0 with ``linear_features``: the
            linear features alone, recursive least squares with forgetting (:class:`SSGP`).
        forgetting_factor: ``lambda`` in (0, 1]; 1 keeps every sample with equal weight.
        prior_refresh: prior coordinates restored per sample (``m`` in the module docstring).
        hyperparameters: as in :class:`SSGP`, as are ``bounds``, ``n_restarts``, ``max_iter``,
            ``max_optimization_samples``, ``normalize``, ``random_state``,
            ``linear_features``, ``linear_std`` and ``input_saturation`` (used once, by
            :meth:`fit`; with linear features the state has ``2r + d_in`` coordinates).
        change_detector: a :class:`ChangeDetector` (copied at :meth:`fit`), or None: restart
            from the new regime's samples when the learned function changes (module
            docstring).
        nominal_fallback: a :class:`NominalFallback` (copied at :meth:`fit`), or None: switch
            the residual off while it predicts the newest samples worse than zero (module
            docstring; :attr:`residual_on_`).

    Fitted attributes: those of :class:`SSGP`, with ``n_samples_seen_`` counting every sample
    since :meth:`fit` (initial batch included), ``n_state_samples_`` those in the current
    state (fewer after a change) and ``n_changes_`` the changes declared.
    """

    def __init__(
        self,
        n_frequencies: int = 100,
        *,
        forgetting_factor: float = 1.0,
        prior_refresh: int = 1,
        hyperparameters: HyperparameterSource = "ssgp",
        bounds: HyperparameterBounds | None = None,
        n_restarts: int = 2,
        max_iter: int = 200,
        max_optimization_samples: int | None = 2000,
        normalize: bool = True,
        random_state: int | None = 0,
        linear_features: bool | Sequence[int] | str = False,
        linear_std: float = 1.0,
        change_detector: ChangeDetector | None = None,
        nominal_fallback: NominalFallback | None = None,
        input_saturation: float | None = None,
    ) -> None:
        super().__init__(
            n_frequencies,
            hyperparameters=hyperparameters,
            bounds=bounds,
            n_restarts=n_restarts,
            max_iter=max_iter,
            max_optimization_samples=max_optimization_samples,
            normalize=normalize,
            random_state=random_state,
            linear_features=linear_features,
            linear_std=linear_std,
            input_saturation=input_saturation,
        )
        self.forgetting_factor = forgetting_factor
        self.prior_refresh = prior_refresh
        self.change_detector = change_detector
        self.nominal_fallback = nominal_fallback

    def _check_config(self) -> tuple[float, int]:
        lam = float(self.forgetting_factor)
        if not (0.0 < lam <= 1.0):
            raise ValueError(f"forgetting_factor must be in (0, 1], got {lam}")
        m = int(self.prior_refresh)
        if m < 1:
            raise ValueError(f"prior_refresh must be >= 1, got {m}")
        return lam, m

    # ------------------------------------------------------------------ fitting
    def fit(self, Z: np.ndarray, Y: np.ndarray) -> IncrementalSSGP:
        """Choose hyperparameters/frequencies/standardization on ``Z`` (N, d_in), ``Y``
        (N, d_out) and set the state to the batch formula over these ``N`` samples (the same
        state ``N`` sequential updates from the prior would reach). Returns ``self``."""
        self._check_config()
        if self.change_detector is not None and not isinstance(self.change_detector,
                                                                ChangeDetector):
            raise TypeError("change_detector must be a ChangeDetector or None, got "
                            f"{type(self.change_detector).__name__}")
        if self.nominal_fallback is not None and not isinstance(self.nominal_fallback,
                                                                NominalFallback):
            raise TypeError("nominal_fallback must be a NominalFallback or None, got "
                            f"{type(self.nominal_fallback).__name__}")
        super().fit(Z, Y)
        self._reset_detector()
        if self.detector_ is not None:  # typical errors of this system (change.py)
            self.detector_.seed(self._loo_errors(Z[-int(self.detector_.history):],
                                                 Y[-int(self.detector_.history):], len(Z)))
        return self

    def _loo_errors(self, Z: np.ndarray, Y: np.ndarray, n: int) -> np.ndarray:
        """(p, d_out) leave-one-out errors (standardized) of the last p of the n fitted samples:
        ``(y_i - mean_i) / (1 - h_i)``, ``h_i = lambda^(n-i) phi_i^T A^{-1} phi_i``."""
        std = self.standardizer_
        assert std is not None
        lam, _ = self._check_config()
        Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
        weight = lam ** np.arange(len(Z) - 1, -1, -1, dtype=float)
        mean, var = self._predict_std(Zs, return_var=True)  # var = sn^2 (1 + phi^T A^-1 phi)
        noise = self.hyperparameters_.noise_std[None, :] ** 2
        h = weight[:, None] * (var / noise - 1.0)
        return (Ys - mean) / np.maximum(1.0 - h, 1e-12)

    def _reset_detector(self) -> None:
        self.fallback_: NominalFallback | None = None
        if self.nominal_fallback is not None:
            self.fallback_ = self.nominal_fallback.clone()
            self.fallback_.reset()
        self.n_changes_ = 0
        self.detector_: ChangeDetector | None = None
        if self.change_detector is not None:
            self.detector_ = self.change_detector.clone()
            self.detector_.reset(self.n_outputs_)
        self._run: list[tuple[np.ndarray, np.ndarray]] = []

    def _set_state(self, chol: list[np.ndarray], b: np.ndarray, n_seen: int,
                   n_state: int | None = None) -> None:
        super()._set_state(chol, b, n_seen)
        self.n_state_samples_ = n_seen if n_state is None else int(n_state)

    def _batch_state(
        self, F: np.ndarray, y: np.ndarray, noise_std: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Batch formula of the module docstring for one output, ``n = N`` samples."""
        lam, m = self._check_config()
        n, D = F.shape
        decay = lam ** np.arange(n - 1, -1, -1, dtype=float)  # lambda^(n-i), i = 1..n
        Fw = F * np.sqrt(decay)[:, None]
        A = Fw.T @ Fw
        A[np.diag_indices(D)] += noise_std**2 * lam ** prior_ages(n, D, m).astype(float)
        R = cholesky(A, lower=False, check_finite=False)
        return np.asfortranarray(R), F.T @ (decay * y)

    # ------------------------------------------------------------------ online update
    def update(self, Z: np.ndarray, Y: np.ndarray) -> IncrementalSSGP:
        """Add ``p`` samples ``Z`` (p, d_in), ``Y`` (p, d_out) in order (the last is newest).

        Costs ``O(p r^2)`` per output. On any error the previous state is left untouched.
        With a change detector the samples go in one at a time (module docstring), and an
        error leaves those before the failing sample added.
        Returns ``self``.
        """
        self._check_fitted()
        self._check_config()
        Z, Y = check_training_data(Z, Y, self.n_features_in_, self.n_outputs_)
        std = self.standardizer_
        assert std is not None
        Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
        detector, fallback = getattr(self, "detector_", None), getattr(self, "fallback_", None)
        if detector is None and fallback is None:
            self._add(Zs, Ys)
            return self
        zero = std.y_mean / std.y_std  # standardized error of the zero residual: ys + this
        for zs, ys in zip(Zs, Ys, strict=True):
            # the sample's features, computed once: its prediction and its factor update
            features = [self._features(zs[None], j) for j in range(self.n_outputs_)]
            W = self.weights_
            error = ys - np.array([(F @ w)[0] for F, w in zip(features, W, strict=True)])
            if fallback is not None:
                fallback.step(error, ys + zero)
            self._add(zs[None], ys[None], features)
            if detector is not None:
                self._detect(zs, ys, error)
        return self

    # ------------------------------------------------------------------ nominal fallback
    @property
    def residual_on_(self) -> bool:
        """Whether the learned residual is used (always, without a nominal fallback)."""
        fallback = getattr(self, "fallback_", None)
        return True if fallback is None else bool(fallback.on_)

    def predict(self, Z: np.ndarray, return_std: bool = False
                ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """As :meth:`SSGP.predict`; a zero mean while the residual is off (module docstring)."""
        out = super().predict(Z, return_std=return_std)
        if self.residual_on_:
            return out
        return (np.zeros_like(out[0]), out[1]) if return_std else np.zeros_like(out)

    def predict_gradient(self, Z: np.ndarray) -> np.ndarray:
        """As :meth:`SSGP.predict_gradient`; zero while the residual is off."""
        G = super().predict_gradient(Z)
        return G if self.residual_on_ else np.zeros_like(G)

    def _standardizer_blocks(self) -> list[tuple[str, np.ndarray]]:
        blocks = super()._standardizer_blocks()
        if self.residual_on_:
            return blocks
        return [(n, np.zeros_like(v) if n == "y_mean" else v) for n, v in blocks]

    def _casadi_blocks(self, variance: bool = True) -> list[tuple[str, np.ndarray]]:
        blocks = super()._casadi_blocks(variance)
        if self.residual_on_:
            return blocks
        return [(n, np.zeros_like(v) if n.startswith("w_") else v) for n, v in blocks]

    def _detect(self, zs: np.ndarray, ys: np.ndarray, error: np.ndarray) -> None:
        """Pass one sample's error to the detector; on a change rebuild the state from the run
        of surprising samples that declared it."""
        det = self.detector_
        assert det is not None
        changed = det.step(error)
        self._run = [*self._run, (zs, ys)] if det.n_surprising_ else []
        if not changed:
            return
        Zr, Yr = np.array([z for z, _ in self._run]), np.array([y for _, y in self._run])
        hyp = self.hyperparameters_
        assert hyp is not None
        chol, b = [], []
        for j in range(self.n_outputs_):
            R, bj = self._batch_state(self._features(Zr, j), Yr[:, j], float(hyp.noise_std[j]))
            chol.append(R)
            b.append(bj)
        self._set_state(chol, np.array(b), self.n_samples_seen_, n_state=len(self._run))
        self.n_changes_ += 1
        det.reset(self.n_outputs_)
        self._run = []

    def _add(self, Zs: np.ndarray, Ys: np.ndarray,
             features: list[np.ndarray] | None = None) -> None:
        """The factor update of the module docstring for standardized samples (p, d_in),
        (p, d_out); ``features``: their feature rows per output if already computed."""
        lam, m = self._check_config()
        hyp = self.hyperparameters_
        assert hyp is not None
        p = Zs.shape[0]
        n0 = self.n_state_samples_
        D = self._chol[0].shape[0]
        decay = lam ** np.arange(p - 1, -1, -1, dtype=float)
        if lam < 1.0:
            a0 = prior_ages(n0, D, m) + p  # ages if nothing were restored
            a1 = prior_ages(n0 + p, D, m)
            restored = np.flatnonzero(a1 != a0)
            old = lam ** a0[restored].astype(float)
            new = lam ** a1[restored].astype(float)
        else:
            restored = np.zeros(0, dtype=np.int64)
        new_b = np.empty_like(self.b_)
        rows = []
        for j in range(self.n_outputs_):
            F = self._features(Zs, j) if features is None else features[j]
            Bj = F * np.sqrt(decay)[:, None]
            if restored.size:
                E = np.zeros((restored.size, D))
                E[np.arange(restored.size), restored] = hyp.noise_std[j] * np.sqrt(new - old)
                Bj = np.vstack([Bj, E])
            rows.append(Bj)
            new_b[j] = lam**p * self.b_[j] + F.T @ (decay * Ys[:, j])
        # Everything that can fail is checked before the factors are touched: the rows are
        # bounded (|phi| = sigma_s, plus sigma_l |z| for linear features), so the updated
        # factors are finite whenever these are.
        if not (np.isfinite(new_b.sum()) and np.isfinite(sum(B.sum() for B in rows))):
            raise FloatingPointError("update produced non-finite values; state left unchanged")
        new_chol = [
            cholesky_add_rows(R, B, np.sqrt(lam**p)) for R, B in zip(self._chol, rows, strict=True)
        ]
        diagonals = np.array([R.diagonal() for R in new_chol])
        if not (np.isfinite(diagonals.sum()) and np.all(diagonals != 0)):
            raise FloatingPointError("update produced a singular factor; state left unchanged")
        self._set_state(new_chol, new_b, self.n_samples_seen_ + p, n_state=n0 + p)

    def prior_diagonal(self) -> np.ndarray:
        """(d_out, 2r) current prior ``P_n`` diagonal, in standardized units."""
        self._check_fitted()
        lam, m = self._check_config()
        hyp = self.hyperparameters_
        assert hyp is not None
        D = self._chol[0].shape[0]
        ages = prior_ages(self.n_state_samples_, D, m).astype(float)
        return hyp.noise_std[:, None] ** 2 * lam ** ages[None, :]

    # ------------------------------------------------------------------ persistence
    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the full learner state (settings and fitted state) to an ``.npz`` file. A
        change detector's and a nominal fallback's settings are written, not their error
        histories: a loaded learner's start afresh (the residual on)."""
        self._check_fitted()
        std, hyp = self.standardizer_, self.hyperparameters_
        assert std is not None and hyp is not None
        rs = self.random_state
        data: dict[str, np.ndarray] = {
            "format_version": np.array(_FORMAT_VERSION),
            "n_frequencies": np.array(int(self.n_frequencies)),
            "forgetting_factor": np.array(float(self.forgetting_factor)),
            "prior_refresh": np.array(int(self.prior_refresh)),
            "normalize": np.array(bool(self.normalize)),
            "random_state": np.array(-1 if rs is None else int(rs)),
            "n_samples_seen": np.array(int(self.n_samples_seen_)),
            "n_state_samples": np.array(int(self.n_state_samples_)),
            "change_detector": (np.zeros(0) if self.change_detector is None else np.array(
                [float(v) for v in self.change_detector.get_params().values()])),
            "nominal_fallback": (np.zeros(0) if self.nominal_fallback is None else np.array(
                [float(self.nominal_fallback.memory)])),
            "n_changes": np.array(int(getattr(self, "n_changes_", 0))),
            "base_frequencies": self.base_frequencies_,
            "linear_std": (np.zeros(0) if self.linear_std_ is None else self.linear_std_),
            "linear_mask": (np.zeros(0) if self.linear_mask_ is None else self.linear_mask_),
            "cholesky_factor": np.stack(self._chol),  # raw factors: bit-exact round trip
            "b": self.b_,
            **std.to_arrays(),
            **hyp.to_arrays(),
        }
        with open(Path(path), "wb") as fh:
            np.savez(fh, **data)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> IncrementalSSGP:
        """Recreate a learner written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
        if int(data["format_version"]) != _FORMAT_VERSION:
            raise ValueError(f"unsupported file format version {int(data['format_version'])}")
        hyp = GPHyperparameters.from_arrays(data)
        rs = int(data["random_state"])
        obj = cls(
            int(data["n_frequencies"]),
            forgetting_factor=float(data["forgetting_factor"]),
            prior_refresh=int(data["prior_refresh"]),
            hyperparameters=hyp,
            normalize=bool(data["normalize"]),
            random_state=None if rs < 0 else rs,
        )
        lin = np.asarray(data.get("linear_std", np.zeros(0)), dtype=float)
        mask = np.asarray(data.get("linear_mask", np.ones(hyp.d_in)), dtype=float)
        obj.linear_features = (lin.size > 0 and (
            True if np.all(mask == 1.0) else tuple(int(c) for c in np.flatnonzero(mask))))
        std = Standardizer.from_arrays(data)
        obj.input_saturation = std.input_saturation if std.saturates else None
        obj._install(std, hyp, np.asarray(data["base_frequencies"]),
                     lin if lin.size else None)
        chol = [np.asfortranarray(R) for R in np.asarray(data["cholesky_factor"], dtype=float)]
        n_seen = int(data["n_samples_seen"])
        obj._set_state(chol, np.asarray(data["b"], dtype=float), n_seen,
                       n_state=int(data.get("n_state_samples", n_seen)))
        detector = np.asarray(data.get("change_detector", np.zeros(0)), dtype=float)
        if detector.size:
            ratio, patience, history = detector
            obj.change_detector = ChangeDetector(float(ratio), int(patience), int(history))
        fallback = np.asarray(data.get("nominal_fallback", np.zeros(0)), dtype=float)
        if fallback.size:
            obj.nominal_fallback = NominalFallback(float(fallback[0]))
        obj._reset_detector()
        obj.n_changes_ = int(data.get("n_changes", 0))
        return obj
