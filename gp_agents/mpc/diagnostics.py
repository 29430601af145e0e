"""Per-step diagnostics of the MPC: what each ``act`` call did, as records and as arrays."""

from __future__ import annotations

import enum
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["DEGRADED_FRACTION", "MIN_DEGRADED_REPLANS", "ControllerDegradedWarning", "StepRecord",
           "StepStatus", "records_to_arrays"]


class StepStatus(enum.StrEnum):
    """What one ``act`` call did: the only status vocabulary of the controller, its planners and
    the benchmark's report (compare with ``==``; never parse ``StepRecord.solver_status``).

    A string enum, so that it is stored in arrays and CSV files as its value.
    """

    REUSE = "reuse"
    """No replan: the action comes from the current plan."""
    SOLVED = "solved"
    """A converged solve (the solver's own status is in ``StepRecord.solver_status``)."""
    RTI = "RTI"
    """A real-time iteration step, accepted as it was."""
    RTI_RECOVERED = "RTI recovered"
    """A real-time iteration step whose constraint violation was too large, made acceptable by
    further SQP iterations within the recovery budget."""
    RTI_REJECTED = "RTI rejected"
    """A real-time iteration step rejected and replaced by a converged solve."""


class ControllerDegradedWarning(UserWarning):
    """An MPC fell back often in one episode (RTI steps rejected, solves failed or capped, old
    plans kept): its actions came from a weaker path than its scheme promises. Filter it with
    ``warnings.filterwarnings("ignore", category=ControllerDegradedWarning)``; the counts are
    :meth:`gp_agents.PseudospectralMPC.health`."""


DEGRADED_FRACTION = 0.1
"""An episode is *degraded* once more than this fraction of its replans (and at least
:data:`MIN_DEGRADED_REPLANS`) were rejected RTI steps, failed or capped solves or kept an older
plan (the real-time iteration's target: at most 10% of its steps rejected)."""
MIN_DEGRADED_REPLANS = 3
"""Fewest degraded replans that make an episode degraded (one cold-start hiccup is not)."""


@dataclass
class StepRecord:
    """Diagnostics of one :meth:`gp_agents.PseudospectralMPC.act` call.

    Attributes:
        step: control period index since the last reset.
        replanned: whether an OCP was solved in this call.
        success: solver success of that solve (True when not replanned).
        status: solver status string (``"reuse"`` when not replanned).
        iterations: NLP iterations (0 when not replanned), summed over this call's solves.
        solve_time: seconds spent in the NLP solver, summed likewise.
        act_time: seconds spent in the whole ``act`` call (learning update included).
        fallback: the applied control came from an older plan (or a constant one) because
            the solve failed.
        learner_samples: samples the learner has seen after this call's update.
        plan_t: (N,) times of the current plan's state points (relative to now).
        plan_x: (N, n) the current plan's states (the predicted trajectory).
        action: (m,) the applied action.
        solves: NLP solves in this call (retries and re-linearizations included).
        linearization_error: with a linearized learned term, the plan's largest expansion
            error as a fraction of its tolerance (NaN if the solve gave no finite plan; 0
            otherwise).
        preparation_time: seconds of ``act_time`` spent after the action was known (the
            ``"rti-split"`` scheme's learner update and preparation; 0 otherwise): the
            latency is ``act_time - preparation_time``.
        residual_on: the learned residual was in use after this call's update (False without
            a learner, and while a learner's nominal fallback has switched it off because it
            predicted the newest samples worse than the nominal model).
    """

    step: int
    replanned: bool
    success: bool
    status: str
    iterations: int
    solve_time: float
    act_time: float
    fallback: bool
    learner_samples: int
    plan_t: np.ndarray
    plan_x: np.ndarray
    action: np.ndarray
    solves: int = 0
    linearization_error: float = 0.0
    preparation_time: float = 0.0
    residual_on: bool = False


def records_to_arrays(records: list[StepRecord]) -> dict[str, np.ndarray]:
    """One array of length T per :class:`StepRecord` field (``{}`` for no records); ragged
    plans (``plan_t`` (T, N), ``plan_x`` (T, N, n)) are padded with NaN."""
    if not records:
        return {}
    out: dict[str, np.ndarray] = {}
    for f in fields(StepRecord):
        values = [getattr(r, f.name) for r in records]
        out[f.name] = _stack_ragged(values) if f.name in ("plan_t", "plan_x") else np.array(values)
    return out


def _stack_ragged(arrays: list[np.ndarray]) -> np.ndarray:
    if len({a.shape for a in arrays}) == 1:
        return np.stack(arrays)
    longest = max(a.shape[0] for a in arrays)
    out = np.full((len(arrays), longest, *arrays[0].shape[1:]), np.nan)
    for i, a in enumerate(arrays):
        out[i, : a.shape[0]] = a
    return out
