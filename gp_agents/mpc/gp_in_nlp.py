"""The learned residual inside the NLP: the GP's CasADi mean at every collocation node.

The paper's OCP ("Gauss Pseudospectral Optimal Control" with the semi-parametric model): the
learner's exported mean ``casadi_mean(phi(x, u), theta)`` is part of the dynamics constraint at
every node, its parameter vector ``theta`` (weights, frequencies, standardization) an NLP
parameter, so learning never rebuilds the solver. IPOPT then differentiates the GP twice per
iteration, which is most of an iteration's cost.
"""

from __future__ import annotations

from typing import Any, Literal

import casadi as ca
import numpy as np

from gp_agents.mpc.learned_term import LearnedTerm

__all__ = ["MAX_LEARNED_MODEL_SIZE", "GPInNLP"]

MAX_LEARNED_MODEL_SIZE = 50_000_000
"""Largest learned model :class:`GPInNLP` builds an NLP for: instructions of the learner's
CasADi mean at one node x learner inputs x collocation nodes (a proxy for the size of the
NLP's derivatives). Measured on this project's recipes: the SSGP quadrotor plan over the
whole episode (2.3e7) builds in ~1 GB; the exact GP on 200 points over the same plan (1.2e8)
exhausted 24 GB of memory while CasADi generated the constraint Jacobian, expanded or not."""


def not_fitted(err: Exception) -> RuntimeError:
    """The error an MPC gives when asked to plan with a learner that was never fitted."""
    return RuntimeError("the learner is not fitted: call agent.pretrain(collect_initial_data("
                        "env)) or fit the learner before the first act()")


class GPInNLP(LearnedTerm):
    """``r(x, u) = mean_GP(phi(x, u); theta)`` in the dynamics at every node.

    Args:
        hessian: ``"exact"``: the Lagrangian Hessian has the GP's second derivatives.
            ``"nominal"``: it has the nominal physics' only (the GP's values and first
            derivatives stay exact in the constraints and their Jacobian, so a converged plan is
            the same; the Newton steps are inexact and can stall).
    """

    name = "exact"

    def __init__(self, hessian: Literal["exact", "nominal"] = "exact") -> None:
        super().__init__()
        if hessian not in ("exact", "nominal"):
            raise ValueError(f"hessian must be 'exact' or 'nominal', got {hessian!r}")
        self.hessian = hessian

    def n_params(self) -> int:
        return int(self.param_values().size)

    def param_values(self) -> np.ndarray:
        try:
            values = self.learner.casadi_param_values(variance=self.variance)
            return np.asarray(values, float).ravel()
        except (ValueError, RuntimeError) as err:
            raise not_fitted(err) from err

    def check_size(self, n_collocation: int) -> None:
        size = self.model_size(n_collocation)
        if size > MAX_LEARNED_MODEL_SIZE:
            raise ValueError(
                f"the learned model is too large to plan with: {size:.2g} (mean instructions "
                f"x {self.residual.n_inputs} inputs x {n_collocation} nodes) > "
                f"MAX_LEARNED_MODEL_SIZE = {MAX_LEARNED_MODEL_SIZE:.2g}; its derivatives "
                "would not fit in memory. Use fewer nodes, fewer training points, an SSGP, "
                "or learned_dynamics='linearized' (the learner then stays outside the NLP).")

    def model_size(self, n_collocation: int) -> int:
        """Instructions of the learned mean at one node x learner inputs x ``n_collocation``."""
        z = ca.SX.sym("z", self.residual.n_inputs)
        theta = ca.SX.sym("theta", self.n_params())
        ops = ca.Function("learned_mean", [z, theta],
                          [self.learner.casadi_mean(z, theta)]).n_instructions()
        return int(ops) * self.residual.n_inputs * int(n_collocation)

    def rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any:
        return self.learner.casadi_mean(self.residual.features(x, u), theta)

    def hessian_rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any | None:
        return self.rates(x, u, theta, q) if self.hessian == "exact" else None

    @property
    def exact_hessian(self) -> bool:
        return self.hessian == "exact"

    def position_variance(self, x: Any, u: Any, theta: Any, q: Any) -> tuple[Any, Any] | None:
        unc = self.residual.uncertain_indices
        var = self.learner.casadi_variance(self.residual.features(x, u), theta)
        return var[unc.index(0)], var[unc.index(1)]
