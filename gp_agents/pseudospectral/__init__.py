"""Gauss (Legendre-Gauss) pseudospectral optimal control on CasADi.

Paper section "Gauss Pseudospectral Optimal Control" (with the standard LG reading of Benson et
al. 2006 and Garg et al. 2010, reference errata note 5). Independent of any env or learner.

* :mod:`~gp_agents.pseudospectral.nodes`: LG nodes/weights, differentiation matrix,
  barycentric Lagrange interpolation.
* :mod:`~gp_agents.pseudospectral.problem`: :class:`OptimalControlProblem` (Bolza problem).
* :mod:`~gp_agents.pseudospectral.transcription`: :class:`GaussPseudospectralSolver` (parametric
  NLP built once, re-solved with new parameters and warm starts).
* :mod:`~gp_agents.pseudospectral.solution`: :class:`OCPSolution`, :class:`InitialGuess`,
  :func:`shift_solution`.
* :mod:`~gp_agents.pseudospectral.buffered`: :class:`BufferedFunction` (a CasADi Function
  called on numpy memory, for compiled steps called every control period).
"""

from gp_agents.pseudospectral.buffered import BufferedFunction
from gp_agents.pseudospectral.nodes import (
    barycentric_weights,
    differentiation_matrix,
    interpolation_matrix,
    lagrange_interpolate,
    legendre_gauss,
    legendre_polynomial,
    support_points,
)
from gp_agents.pseudospectral.problem import OptimalControlProblem
from gp_agents.pseudospectral.solution import InitialGuess, OCPSolution, shift_solution
from gp_agents.pseudospectral.transcription import (
    IPOPT_WARM_START_OPTIONS,
    GaussPseudospectralSolver,
    default_solver_options,
)

__all__ = [
    "IPOPT_WARM_START_OPTIONS",
    "BufferedFunction",
    "GaussPseudospectralSolver",
    "InitialGuess",
    "OCPSolution",
    "OptimalControlProblem",
    "barycentric_weights",
    "default_solver_options",
    "differentiation_matrix",
    "interpolation_matrix",
    "lagrange_interpolate",
    "legendre_gauss",
    "legendre_polynomial",
    "shift_solution",
    "support_points",
]
