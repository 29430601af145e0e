"""Learner recipes: the configured learners this project's benchmarks use."""

from __future__ import annotations

from collections.abc import Sequence

from .change import ChangeDetector
from .fallback import NominalFallback
from .hyperparameters import HyperparameterBounds
from .incremental import IncrementalSSGP

__all__ = ["INPUT_SATURATION", "LENGTH_SCALE_FLOOR", "LINEAR_LENGTH_SCALE_FLOOR", "online_ssgp",
           "parametric_rls", "parametric_ssgp"]

LENGTH_SCALE_FLOOR = 1.0
"""Smallest length scale of :func:`online_ssgp`'s learner, in standard deviations of its
(standardized) inputs."""
LINEAR_LENGTH_SCALE_FLOOR = 5.0
"""The same with linear features (see :func:`online_ssgp`)."""
INPUT_SATURATION = 30.0
"""Standard deviations of the initial data at which the saturated recipe's learner saturates
its standardized inputs (``online_ssgp(input_saturation=INPUT_SATURATION)``): far enough out
that a swing-up's states stay unsaturated, near enough that a plan cannot exploit the learner
tens of standard deviations beyond its data. Not the :func:`online_ssgp` default: the paper's
recipe has no saturation."""


def online_ssgp(n_frequencies: int = 50, forgetting_factor: float = 0.995,
                random_state: int | None = 0,
                linear_features: bool | Sequence[int] | str = False,
                change_detector: ChangeDetector | None = None,
                nominal_fallback: NominalFallback | None = None,
                input_saturation: float | None = None) -> IncrementalSSGP:
    """The online learner of the paper's Algorithm 1, as this project's benchmarks use it.

    Its defaults are the paper's learner, the ``"paper"`` recipe's
    (:func:`gp_agents.make_mpc`). The learner that
    held across the robustness envelope needs the MPC's parameter sensitivities as inputs and
    is :func:`parametric_ssgp` (its docstring says why and what it measured).

    An :class:`~gp_agents.learners.IncrementalSSGP` whose hyperparameters come from the SSGP's
    own marginal likelihood on the initial data, with length scales of at least one standard
    deviation of the (standardized) inputs. Without that floor the likelihood's optimum on 200
    points in the quadrotor's 19 input dimensions sits at the bound (length scales 0.01): a
    model that fits noise and predicts no better than zero (test nMSE ~1.0), on which the NLP
    stops converging; with it the quadrotor test nMSE is ~1e-3 and the cart pole's is unchanged.

    With ``linear_features=True`` (the recipes with the parameter sensitivities as inputs: 35
    on the quadrotor) the floor is five standard deviations: under observation noise the
    one-sigma floor let the fit on the noisy initial data put length scales on the floor along
    inputs that hardly vary in those data (the quadrotor's cos(psi), std 2e-5), and the learned
    Jacobians reached thousands in physical units, and the quadrotor crashed under noise.

    Args:
        n_frequencies: ``r`` (``2r`` features per output).
        forgetting_factor: ``lambda``; 0.995 halves a sample's weight in ~140 steps (7 s).
        random_state: seeds the frequency draws.
        linear_features: append linear features of the inputs (:class:`~gp_agents.learners.
            SSGP`): ``True`` for every input, the input columns that get one, or
            ``"sensitivities"``: the parameter-sensitivity columns of the MPC the learner is
            given to (which needs ``Residual(sensitivities=True)`` and fills them in), the
            residual's explicit parametric part alone (:mod:`gp_agents.residual`).
        change_detector: restart from the new regime's samples when the system changes
            (:class:`~gp_agents.learners.ChangeDetector`).
        nominal_fallback: switch the residual off while it predicts the newest samples worse
            than zero, i.e. than the nominal model (:class:`~gp_agents.learners.NominalFallback`).
        input_saturation: saturate the standardized inputs at this many standard deviations
            (:class:`~gp_agents.learners.Standardizer`); None: no saturation.
    """
    return IncrementalSSGP(n_frequencies, forgetting_factor=forgetting_factor,
                           hyperparameters="ssgp", random_state=random_state,
                           linear_features=linear_features, change_detector=change_detector,
                           nominal_fallback=nominal_fallback,
                           input_saturation=input_saturation,
                           bounds=HyperparameterBounds(
                               length_scale=(LINEAR_LENGTH_SCALE_FLOOR if linear_features
                                             else LENGTH_SCALE_FLOOR, 100.0)))


def parametric_ssgp(sensitivity_columns: Sequence[int] | None = None, n_frequencies: int = 50,
                    forgetting_factor: float = 0.995, random_state: int | None = 0
                    ) -> IncrementalSSGP:
    """The learner of the ``"robust"`` recipe (:func:`gp_agents.make_mpc`), which held across
    randomized, changed and noisy systems: the residual's parametric part plus the SSGP around
    it, restarted on a change, off while it predicts worse than the nominal model, with
    saturated inputs.

    For an MPC with ``Residual(sensitivities=True)`` (the learner's last inputs are the nominal
    model's parameter sensitivities ``S = d f / d p``): :func:`online_ssgp` with linear features
    on those columns only (the parametric part ``dp' S(x, u)``,
    :class:`~gp_agents.learners.SSGP`), a :class:`~gp_agents.learners.ChangeDetector`, a
    :class:`~gp_agents.learners.NominalFallback` and inputs saturated at
    :data:`INPUT_SATURATION` standard deviations. Without ``sensitivity_columns`` the MPC the
    learner is given to fills in its own (``linear_features="sensitivities"``).

    Why linear features on the sensitivities only: on data from a narrow region, linear
    features on *every* input (the raw states and controls beside the sensitivities) are nearly
    collinear with the sensitivities, and the fit spreads its slope over them. Outside that
    region the raw-input terms extrapolate as an offset the physics does not have: near its
    goal the Dubins vehicle's learned model had it drift at 0.3 m/s while at rest (mostly from
    the cos(psi) column, 20 standard deviations outside its data), so it passed the goal,
    stopped facing away from it and stayed 0.13 m off. The Dubins rates are the sensitivities
    times ``dp`` exactly, so restricting the linear part to them removes the offset.

    Args:
        sensitivity_columns: the learner-input columns of the parameter sensitivities
            (non-empty; negative indices count from the end;
            ``agent.config.residual.model(agent.model).sensitivity_columns``), or None: the
            MPC's own.
        n_frequencies, forgetting_factor, random_state: as :func:`online_ssgp`.

    Raises:
        ValueError: an empty sequence of columns.
    """
    columns = _sensitivity_columns(sensitivity_columns, "parametric_ssgp")
    return online_ssgp(n_frequencies, forgetting_factor, random_state, linear_features=columns,
                       change_detector=ChangeDetector(), nominal_fallback=NominalFallback(),
                       input_saturation=INPUT_SATURATION)


def parametric_rls(sensitivity_columns: Sequence[int] | None = None,
                   forgetting_factor: float = 0.995) -> IncrementalSSGP:
    """The learner of the ``"parametric"`` recipe (:func:`gp_agents.make_mpc`), the grey-box
    baseline: online re-identification of the nominal model's parameters alone, the residual
    ``y = W' S(x, u)`` linear in the parameter sensitivities and nothing else (no GP).

    :func:`parametric_ssgp`'s parametric part without the SSGP around it: an
    :class:`~gp_agents.learners.IncrementalSSGP` with no Fourier features and linear features
    on the sensitivity columns, i.e. recursive least squares with the forgetting factor on
    standardized inputs and outputs, its prior (``sigma_n^2 / sigma_l^2`` ridge, both from the
    marginal likelihood of the initial data, kept from decaying by the cyclic refresh) making
    the first fits well posed. No change detector, nominal fallback or input saturation: the
    textbook estimator, whose forgetting alone tracks a changed system.

    Args:
        sensitivity_columns: as :func:`parametric_ssgp` (None: the MPC's own).
        forgetting_factor: ``lambda``, the robust recipe's 0.995 by default.

    Raises:
        ValueError: an empty sequence of columns.
    """
    columns = _sensitivity_columns(sensitivity_columns, "parametric_rls")
    return IncrementalSSGP(0, forgetting_factor=forgetting_factor, hyperparameters="ssgp",
                           linear_features=columns)


def _sensitivity_columns(columns: Sequence[int] | None, name: str) -> tuple[int, ...] | str:
    """``columns`` as a tuple, or ``"sensitivities"`` (the MPC's own) for None."""
    if columns is None:
        return "sensitivities"
    out = tuple(int(c) for c in columns)
    if not out:
        raise ValueError(f"{name} needs the learner-input columns of the parameter "
                         f"sensitivities, or None for the MPC's own (those of an MPC with "
                         f"Residual(sensitivities=True))")
    return out
