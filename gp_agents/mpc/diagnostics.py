"""Per-step diagnostics of the MPC: what each ``act`` call did, as records and as arrays."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["DEGRADED_FRACTION", "MIN_DEGRADED_REPLANS", "WARN_AFTER_FRACTION",
           "ControllerDegradedWarning", "EpisodeHealth", "SolveCounts", "StepRecord", "StepStatus",
           "records_to_arrays"]


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
    plans kept): its actions came from a weaker path than its scheme promises. Issued once per
    episode, when the episode is degraded (:attr:`EpisodeHealth.degraded`) and at least
    :data:`WARN_AFTER_FRACTION` of the task's replans have been made, so that a hard first
    second (a cold start, a swing-up's first replans) does not raise it alone. Filter it with
    ``warnings.filterwarnings("ignore", category=ControllerDegradedWarning)``; the counts are
    :meth:`gp_agents.PseudospectralMPC.health`."""


DEGRADED_FRACTION = 0.1
"""An episode is *degraded* once more than this fraction of its replans (and at least
:data:`MIN_DEGRADED_REPLANS`) were rejected RTI steps, failed or capped solves or kept an older
plan (the real-time iteration's target: at most 10% of its steps rejected)."""
MIN_DEGRADED_REPLANS = 3
"""Fewest degraded replans that make an episode degraded (one cold-start hiccup is not)."""
WARN_AFTER_FRACTION = 0.25
"""Share of the task's replans (its duration over the replanning period) an episode must have
made before :class:`ControllerDegradedWarning` is issued: the degraded share is then measured
over a quarter of the task or more, not over its first few replans."""


@dataclass
class SolveCounts:
    """What an MPC's planners did since the agent was built (one object per agent, shared by
    every planner it builds, so a rebuild never resets it).

    Attributes:
        builds: planners built (the NLP transcribed and compiled).
        solves: converged NLP solves (retries and re-linearizations included).
        retries: retries from the cold-start guess after a failed warm solve.
        failures: replans whose converged solves all failed.
        fallbacks: replans that kept an older (or a constant) plan.
        capped: converged solves that ran into the iteration cap.
        rti_steps: real-time iteration steps taken (accepted, recovered or rejected).
        rti_recovered: RTI steps recovered by further SQP iterations within the budget.
        recovery_iterations: the QP solves those recoveries took.
        rti_rejected: RTI steps replaced by a converged solve.
        qp_fallbacks: active-set QPs that did not settle and took the fallback plugin.
        prepared: split-RTI feedback steps taken from a preparation.
        unprepared: warm split-RTI steps that took the one-call path instead.
        sqp_iterations: iterations of the SQP scheme (:class:`~gp_agents.mpc.settings.SQP`).
        sqp_fallbacks: SQP plans that did not converge within the budget and took the IPOPT
            fallback.
        nominal_plans: converged plans replaced by the nominal model's plan because their
            linearized learned term was too far from the learner at the plan (the term's
            ``nominal_above``).
    """

    builds: int = 0
    solves: int = 0
    retries: int = 0
    failures: int = 0
    fallbacks: int = 0
    capped: int = 0
    rti_steps: int = 0
    rti_recovered: int = 0
    recovery_iterations: int = 0
    rti_rejected: int = 0
    qp_fallbacks: int = 0
    prepared: int = 0
    unprepared: int = 0
    sqp_iterations: int = 0
    sqp_fallbacks: int = 0
    nominal_plans: int = 0


HEALTH_KEYS = ("replans", "rti_steps", "rti_recovered", "rti_recovery_iterations",
               "rti_rejected", "failed", "capped", "fallbacks", "degraded_replans")
"""The counts of :class:`EpisodeHealth` (and of :meth:`gp_agents.PseudospectralMPC.health`)."""


class EpisodeHealth:
    """How one episode's replans went, counted from their step records (module doc).

    Counts (:data:`HEALTH_KEYS`): ``replans``; ``rti_steps`` (RTI steps taken);
    ``rti_recovered`` (RTI steps whose constraint violation was too large and that further SQP
    iterations within the recovery budget made acceptable; ``rti_recovery_iterations``: those
    iterations); ``rti_rejected`` (RTI steps replaced by a converged solve, the last resort);
    ``failed`` (replans whose solve failed); ``capped`` (ending at the iteration cap);
    ``fallbacks`` (an older or constant plan kept); ``degraded_replans`` (replans with any of
    the last four).


    Args:
        task_replans: the replans a whole episode of the task makes (its duration over the
            replanning period): the degradation warning waits for
            :data:`WARN_AFTER_FRACTION` of them.
    """

    def __init__(self, task_replans: float = 1.0) -> None:
        self.counts: dict[str, int] = dict.fromkeys(HEALTH_KEYS, 0)
        self.warn_after = max(1, math.ceil(WARN_AFTER_FRACTION * float(task_replans) - 1e-9))
        self.warned = False

    def count(self, status: StepStatus, success: bool, capped: bool, fallback: bool,
              iterations: int) -> bool:
        """Count one replan: its status, solver success, whether its final solve ran into the
        iteration cap, whether an older plan was kept, and its iterations. Returns whether the
        degradation warning is due now (once per episode: degraded, and at least
        ``warn_after`` replans made)."""
        h = self.counts
        rejected = status == StepStatus.RTI_REJECTED
        recovered = status == StepStatus.RTI_RECOVERED
        h["replans"] += 1
        h["rti_steps"] += int(status in (StepStatus.RTI, StepStatus.RTI_RECOVERED,
                                         StepStatus.RTI_REJECTED))
        h["rti_recovered"] += int(recovered)
        h["rti_recovery_iterations"] += int(iterations) - 1 if recovered else 0
        h["rti_rejected"] += int(rejected)
        h["failed"] += int(not success)
        h["capped"] += int(capped)
        h["fallbacks"] += int(fallback)
        h["degraded_replans"] += int(rejected or not success or capped or fallback)
        due = not self.warned and self.degraded and h["replans"] >= self.warn_after
        self.warned = self.warned or due
        return due

    def message(self, who: str) -> str:
        """The degradation warning's text for the controller ``who``."""
        h = self.counts
        return (f"{who}: {h['degraded_replans']} of {h['replans']} replans so far this episode "
                f"took a fallback path (RTI steps rejected {h['rti_rejected']}, failed "
                f"{h['failed']}, capped {h['capped']}, older plan kept {h['fallbacks']}); "
                f"agent.health() has the counts")

    @property
    def degraded(self) -> bool:
        """More than :data:`DEGRADED_FRACTION` of the replans, and at least
        :data:`MIN_DEGRADED_REPLANS`, took a fallback path."""
        bad = self.counts["degraded_replans"]
        return bad >= MIN_DEGRADED_REPLANS and bad > DEGRADED_FRACTION * self.counts["replans"]


@dataclass
class StepRecord:
    """Diagnostics of one :meth:`gp_agents.PseudospectralMPC.act` call.

    Attributes:
        step: control period index since the last reset.
        replanned: whether an OCP was solved in this call.
        success: solver success of that solve (True when not replanned).
        status: what the call did (:class:`StepStatus`).
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
        solver_status: the NLP solver's own message for a converged solve (e.g. IPOPT's
            ``"Solve_Succeeded"``), for people to read; never parsed (``status`` and
            ``capped`` say what happened).
        capped: the call's final converged solve ran into its iteration cap.
        residual_on: the learned residual was in use in the current plan (False without a
            learner, while a learner's nominal fallback has switched it off because it
            predicted the newest samples worse than the nominal model, and for a nominal plan).
        nominal_plan: this call's plan is the nominal model's, taken because the linearized
            learned term was too far from the learner at the plan (the term's
            ``nominal_above``).
    """

    step: int
    replanned: bool
    success: bool
    status: StepStatus
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
    solver_status: str = ""
    capped: bool = False
    nominal_plan: bool = False


def records_to_arrays(records: list[StepRecord]) -> dict[str, np.ndarray]:
    """One array of length T per :class:`StepRecord` field (``{}`` for no records); ragged
    plans (``plan_t`` (T, N), ``plan_x`` (T, N, n)) are padded with NaN."""
    if not records:
        return {}
    out: dict[str, np.ndarray] = {}
    for f in fields(StepRecord):
        values = [getattr(r, f.name) for r in records]
        if f.name == "status":
            values = [str(v) for v in values]  # the enum's values, a plain string array
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
