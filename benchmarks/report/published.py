"""Published figures the report cites beside its own (never measured here)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PublishedAnchor:
    """A published data-efficiency figure on PILCO's cart pole, cited with its setup.

    Attributes:
        method: who. success: the reported success rate (NaN: not reported as a rate).
        trials: trials until that success, counting the first random one.
        interaction_s: interaction time until then, s, as the source counts it.
        source: the citation. setup: how its setup differs from this package's.
    """

    method: str
    success: float
    trials: int
    interaction_s: float
    source: str
    setup: str


PUBLISHED_ANCHORS: dict[str, tuple[PublishedAnchor, ...]] = {
    "pilco_cartpole": (
        PublishedAnchor(
            "GP-MPC", 0.9, 3, 9.0, "Kamthe & Deisenroth, AISTATS 2018 (as quoted in issue 44)",
            "no physics prior; GP with moment-matching uncertainty propagation in the plan; "
            "every transition added at once, replanned every step; whole trials counted "
            "(9 s over 3 trials suggests 3 s trials; here trials are 4 s, PILCO's MATLAB "
            "code); success = tip within 8 cm for 10 consecutive steps, as here"),
        PublishedAnchor(
            "PILCO (in GP-MPC's comparison)", float("nan"), 5, 15.0,
            "Kamthe & Deisenroth, AISTATS 2018 (as quoted in issue 44)",
            "no physics prior; a parametric policy learned between trials (no online "
            "learning within a trial); whole trials counted"),
        PublishedAnchor(
            "PILCO (real cart pole)", float("nan"), 0, 17.5,
            "Deisenroth & Rasmussen, ICML 2011",
            "the real hardware, not this simulation; no physics prior; a policy learned "
            "between trials; whole trials counted (trials count not given here)"),
    ),
}
"""The published anchors of the data-efficiency section, by system."""


@dataclass(frozen=True)
class PublishedReturn:
    """A published return on a DeepMind Control task, computed from its authors' result files.

    Attributes:
        method: who. steps: environment (physics) steps of interaction, action repeat
            included. mean, low, high: the return's mean, min and max over the published
            seeds. source: the file (repository, path, commit).
    """

    method: str
    steps: int
    mean: float
    low: float
    high: float
    source: str


_TDMPC2 = "nicklashansen/tdmpc2 at e9f5932, results/{}/cartpole-swingup.csv (3 seeds)"
PUBLISHED_RETURNS: dict[str, tuple[PublishedReturn, ...]] = {
    "dmc-cartpole": (
        PublishedReturn("TD-MPC2", 100_000, 839.4, 789.8, 867.9, _TDMPC2.format("tdmpc2")),
        PublishedReturn("TD-MPC2", 4_000_000, 877.2, 866.2, 883.0, _TDMPC2.format("tdmpc2")),
        PublishedReturn("TD-MPC", 100_000, 863.1, 850.7, 877.5, _TDMPC2.format("tdmpc")),
        PublishedReturn("TD-MPC", 4_000_000, 882.9, 882.9, 883.0, _TDMPC2.format("tdmpc")),
        PublishedReturn("SAC", 100_000, 835.0, 825.8, 844.8, _TDMPC2.format("sac")),
        PublishedReturn("SAC", 4_000_000, 825.5, 790.5, 855.2, _TDMPC2.format("sac")),
        PublishedReturn("DreamerV3", 100_000, 676.7, 637.2, 718.6, _TDMPC2.format("dreamerv3")),
        PublishedReturn("DreamerV3", 200_000, 795.6, 774.0, 811.9, _TDMPC2.format("dreamerv3")),
        PublishedReturn("DreamerV3", 3_900_000, 830.2, 820.9, 839.1,
                        _TDMPC2.format("dreamerv3")),
    ),
}
"""Published returns beside the own-env section's table, by benchmark env. The steps count
environment steps with TD-MPC2's action repeat of 2 included (its ``envs/dmcontrol.py``), so
100k steps are 50k agent decisions; returns are over DMC's 1000-step episodes."""
