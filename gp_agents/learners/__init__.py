"""GP residual learners: ``f_err(x, u) = f_true(x, u) - f_nominal(x, u)``.

Paper sections "Gaussian Processes", "Sparse Spectrum Gaussian Processes" and "Online model
learning". Three learners with a scikit-learn-like API and a common CasADi export contract:

* :class:`ExactGP` -- full GP with SE-ARD kernel and marginal-likelihood hyperparameters;
* :class:`SSGP` -- sparse spectrum GP (random Fourier features) fitted in batch;
* :class:`IncrementalSSGP` -- SSGP with ``O(r^2)`` Cholesky updates and exponential forgetting.
"""

from ._validation import NotFittedError
from .change import ChangeDetector
from .exact_gp import ExactGP
from .fallback import NominalFallback
from .hyperparameters import GPHyperparameters, HyperparameterBounds
from .incremental import IncrementalSSGP
from .recipes import (
    INPUT_SATURATION,
    LENGTH_SCALE_FLOOR,
    LINEAR_LENGTH_SCALE_FLOOR,
    online_ssgp,
    parametric_rls,
    parametric_ssgp,
)
from .ssgp import SSGP
from .standardization import Standardizer

__all__ = [
    "INPUT_SATURATION",
    "LENGTH_SCALE_FLOOR",
    "LINEAR_LENGTH_SCALE_FLOOR",
    "SSGP",
    "ChangeDetector",
    "ExactGP",
    "GPHyperparameters",
    "HyperparameterBounds",
    "IncrementalSSGP",
    "NominalFallback",
    "NotFittedError",
    "Standardizer",
    "online_ssgp",
    "parametric_rls",
    "parametric_ssgp",
]
