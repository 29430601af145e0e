"""Hyperparameters of the squared-exponential ARD kernel, one set per output dimension.

Kernel (paper, Section "Gaussian Processes"; the noise is kept out of the kernel and added to the
diagonal of the training covariance only):

    k(z, z') = sigma_s^2 exp(-1/2 (z - z')^T W (z - z')),   W = diag(1 / ell^2),

with observation noise variance sigma_n^2. All values live in the *standardized* input/output
space of the learner that owns them (see :class:`~gp_agents.learners.standardization.Standardizer`).
Optimizers work on ``theta = [log ell (d_in), log sigma_s, log sigma_n]`` per output.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GPHyperparameters", "HyperparameterBounds"]


@dataclass(frozen=True)
class GPHyperparameters:
    """SE-ARD hyperparameters of ``d_out`` independent GPs.

    Attributes:
        length_scales: (d_out, d_in) ``ell``, > 0.
        signal_std: (d_out,) ``sigma_s``, > 0.
        noise_std: (d_out,) ``sigma_n``, > 0.
    """

    length_scales: np.ndarray
    signal_std: np.ndarray
    noise_std: np.ndarray

    def __post_init__(self) -> None:
        ls = np.atleast_2d(np.asarray(self.length_scales, dtype=float))
        sf = np.atleast_1d(np.asarray(self.signal_std, dtype=float))
        sn = np.atleast_1d(np.asarray(self.noise_std, dtype=float))
        if ls.ndim != 2 or sf.shape != (ls.shape[0],) or sn.shape != (ls.shape[0],):
            raise ValueError(
                "hyperparameter shapes must be length_scales (d_out, d_in), signal_std (d_out,),"
                f" noise_std (d_out,); got {ls.shape}, {sf.shape}, {sn.shape}"
            )
        for name, a in (("length_scales", ls), ("signal_std", sf), ("noise_std", sn)):
            if not (np.all(np.isfinite(a)) and np.all(a > 0)):
                raise ValueError(f"{name} must be finite and positive")
        object.__setattr__(self, "length_scales", ls)
        object.__setattr__(self, "signal_std", sf)
        object.__setattr__(self, "noise_std", sn)

    @property
    def d_out(self) -> int:
        """Number of outputs."""
        return int(self.length_scales.shape[0])

    @property
    def d_in(self) -> int:
        """Number of inputs."""
        return int(self.length_scales.shape[1])

    def log_params(self, j: int) -> np.ndarray:
        """(d_in + 2,) ``[log ell, log sigma_s, log sigma_n]`` of output ``j``."""
        return np.concatenate(
            [np.log(self.length_scales[j]), np.log([self.signal_std[j], self.noise_std[j]])]
        )

    @classmethod
    def from_log_params(cls, rows: list[np.ndarray]) -> GPHyperparameters:
        """Inverse of :meth:`log_params`; ``rows[j]`` is the (d_in + 2,) vector of output j."""
        t = np.exp(np.asarray(rows, dtype=float))
        return cls(t[:, :-2], t[:, -2], t[:, -1])

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for persistence (keys prefixed ``hyp_``)."""
        return {
            "hyp_length_scales": self.length_scales,
            "hyp_signal_std": self.signal_std,
            "hyp_noise_std": self.noise_std,
        }

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> GPHyperparameters:
        """Inverse of :meth:`to_arrays`."""
        return cls(data["hyp_length_scales"], data["hyp_signal_std"], data["hyp_noise_std"])


@dataclass(frozen=True)
class HyperparameterBounds:
    """Box bounds (standardized units) for marginal-likelihood optimization.

    The noise floor keeps the Gram matrices well conditioned on noise-free data (the residual
    of two deterministic models is noise free).

    Attributes:
        length_scale: (low, high) for every ``ell``.
        signal_std: (low, high) for ``sigma_s``.
        noise_std: (low, high) for ``sigma_n``.
        linear_std: (low, high) for ``sigma_l``, the prior std of the weights of an SSGP's
            linear features (used only by learners with linear features).
    """

    length_scale: tuple[float, float] = (1e-2, 1e2)
    signal_std: tuple[float, float] = (1e-2, 1e2)
    noise_std: tuple[float, float] = (1e-3, 1e1)
    linear_std: tuple[float, float] = (1e-3, 1e1)

    def __post_init__(self) -> None:
        for name in ("length_scale", "signal_std", "noise_std", "linear_std"):
            lo, hi = getattr(self, name)
            if not (0 < lo < hi < np.inf):
                raise ValueError(f"bounds for {name} must satisfy 0 < low < high < inf")

    def log_bounds(self, d_in: int) -> list[tuple[float, float]]:
        """L-BFGS-B bounds on ``[log ell (d_in), log sigma_s, log sigma_n]``."""
        lb = tuple(np.log(self.length_scale))
        return [lb] * d_in + [tuple(np.log(self.signal_std)), tuple(np.log(self.noise_std))]

    def initial_guesses(
        self, d_in: int, n_random: int, rng: np.random.Generator
    ) -> list[np.ndarray]:
        """Start points: a fixed default (ell = 1, sigma_s = 1, sigma_n = 0.1, clipped to the
        bounds) followed by ``n_random`` log-uniform draws from the central part of the box."""
        bounds = np.array(self.log_bounds(d_in))
        default = np.clip(np.r_[np.zeros(d_in), 0.0, np.log(0.1)], bounds[:, 0], bounds[:, 1])
        guesses = [default]
        # central part of the box: avoid starting on a bound where gradients vanish
        lo = np.maximum(bounds[:, 0], np.r_[np.full(d_in, np.log(0.2)), np.log(0.3), np.log(1e-2)])
        hi = np.minimum(bounds[:, 1], np.r_[np.full(d_in, np.log(5.0)), np.log(3.0), np.log(0.3)])
        hi = np.maximum(hi, lo)
        for _ in range(n_random):
            guesses.append(rng.uniform(lo, hi))
        return guesses

    def with_linear(
        self,
        guesses: list[np.ndarray],
        log_bounds: list[tuple[float, float]],
        rng: np.random.Generator,
    ) -> tuple[list[np.ndarray], list[tuple[float, float]]]:
        """Append ``log sigma_l`` to start points (default 1, then log-uniform in [0.1, 3],
        both clipped to the bounds) and bounds from :meth:`initial_guesses` / :meth:`log_bounds`."""
        lo, hi = np.log(self.linear_std)
        out = [np.r_[guesses[0], np.clip(0.0, lo, hi)]]
        for g in guesses[1:]:
            a, b = max(lo, np.log(0.1)), min(hi, np.log(3.0))
            out.append(np.r_[g, rng.uniform(a, max(a, b))])
        return out, [*log_bounds, (float(lo), float(hi))]
