"""How every controller and every state or control looks in the report's figures.

:data:`STYLES` is the one table mapping each recipe of :data:`benchmarks.controllers.CONTROLLERS`
(an alias is drawn as the controller it stands for) to a fixed :class:`Style`, used by every
figure of :mod:`benchmarks.report`, so that a controller
has the same colour, line style and marker everywhere. The conventions:

- the colour names the *model* a controller plans with (nominal, oracle, offline GP, SSGP and
  each SSGP speed variant, the SSGP with its residual linearized) or the RL algorithm;
- the line style names the *scheme*: solid receding-horizon MPC and RL policies, dashed
  episodic (planned once, open loop), dash-dot real-time iteration;
- every recipe has its own marker (the sample-efficiency plot draws points only);
- the nominal MPC is drawn thick and underneath, the oracle thin and on top, so that the
  nominal stays visible where the two coincide.

:func:`unit` gives the unit of every state and control of every registered system, from its
physics module (``STATE_UNITS``, ``CONTROL_UNITS``), for axis labels. A recipe missing here
makes the report raise (and ``tests/test_report_plots.py`` fail) rather than draw a look-alike
line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from benchmarks.controllers import ALIASES

RECEDING, EPISODIC, RTI, WARM_DUALS = "-", "--", "-.", ":"
"""Line styles of the three schemes."""
SQP_SCHEME = (0, (5, 1, 1, 1, 1, 1))
"""Line style of the SQP scheme (dash-dot-dot: converged, on the RTI's machinery)."""


@dataclass(frozen=True)
class Style:
    """How one controller is drawn.

    Attributes:
        color: matplotlib colour.
        linestyle: matplotlib line style (:data:`RECEDING`, :data:`EPISODIC`, :data:`RTI`,
            :data:`WARM_DUALS`).
        marker: matplotlib marker, unique per recipe.
        linewidth: line width in points.
        zorder: drawing order (higher on top).
    """

    color: str
    linestyle: str
    marker: str
    linewidth: float = 1.3
    zorder: float = 3.0

    def line(self, n_points: int, markers: int = 8) -> dict[str, Any]:
        """Keyword arguments of ``Axes.plot`` / ``Axes.step`` for a line of ``n_points`` points
        with this style: about ``markers`` markers along it, staggered per recipe so that the
        markers of coinciding lines do not hide one another."""
        every = max(1, n_points // markers)
        offset = (_ORDER.get(self.marker, 0) * max(1, every // 5)) % every
        return {"color": self.color, "ls": self.linestyle, "marker": self.marker,
                "markevery": (offset, every), "lw": self.linewidth, "zorder": self.zorder,
                "ms": 5, "markerfacecolor": "none" if self.linestyle == EPISODIC else self.color}

    def point(self) -> dict[str, Any]:
        """Keyword arguments of ``Axes.plot`` for a single marker with this style."""
        return {"color": self.color, "ls": "", "marker": self.marker, "ms": 8,
                "zorder": self.zorder}


# Okabe-Ito (colour-blind safe) first, then a few of matplotlib's tab10 for the rest
_NOMINAL = "#0072B2"  # blue
_ORACLE = "#000000"  # black
_GP = "#E69F00"  # orange
_SSGP = "#009E73"  # bluish green
_SSGP_LINEARIZED = "#CC79A7"  # reddish purple
_SSGP_NOMINAL_HESSIAN = "#56B4E9"  # sky blue
_SSGP_MODEL_INPUTS = "#D55E00"  # vermillion
_SSGP_LINEARIZED_MODEL_INPUTS = "#8C564B"  # brown
_SSGP_SENSITIVITIES = "#F0E442"  # yellow
_SSGP_LINEARIZED_SENSITIVITIES = "#17BECF"  # cyan
_SSGP_ADAPTIVE = "#2CA02C"  # green
_SSGP_LINEARIZED_ADAPTIVE = "#7F7F7F"  # grey
_SSGP_LINEARIZED_GUARDED = "#D62728"  # red
_SSGP_LINEARIZED_SATURATED = "#393B79"  # dark indigo
_SSGP_LINEARIZED_PARAMETRIC = "#AEC7E8"  # light blue
_SAC = "#9467BD"  # purple
_PPO = "#BCBD22"  # olive
_TQC = "#E377C2"  # pink
_BLACKBOX = "#8C6D31"  # dark olive brown: the no-prior model
_PARAMETRIC_RLS = "#98DF8A"  # light green: the parametric part alone, no GP
_GUARDED = "#FF9896"  # light red: the robust recipe with the plan-level nominal fallback
_EXACT = "#C49C94"  # light brown: the robust recipe with the learned residual itself in the NLP
_LINEARIZED_EVERYWHERE = "#7B4173"  # dark magenta: the robust recipe linearized on every env

STYLES: dict[str, Style] = {
    # nominal: thick and underneath; oracle: thin and on top (the two often coincide)
    "nominal-mpc": Style(_NOMINAL, RECEDING, "o", linewidth=2.2, zorder=2.0),
    "nominal-episodic": Style(_NOMINAL, EPISODIC, "s", linewidth=2.2, zorder=2.0),
    "nominal-mpc-rti": Style(_NOMINAL, RTI, "p", linewidth=2.2, zorder=2.0),
    "nominal-mpc-warm-duals": Style(_NOMINAL, WARM_DUALS, "4", linewidth=2.2, zorder=2.0),
    "oracle-mpc": Style(_ORACLE, RECEDING, "x", linewidth=1.0, zorder=5.0),
    "oracle-episodic": Style(_ORACLE, EPISODIC, "+", linewidth=1.0, zorder=5.0),
    "oracle-mpc-rti": Style(_ORACLE, RTI, "1", linewidth=1.0, zorder=5.0),
    "oracle-mpc-rti-split": Style(_ORACLE, RTI, "$O$", linewidth=1.0, zorder=5.0),
    "oracle-mpc-warm-duals": Style(_ORACLE, WARM_DUALS, "3", linewidth=1.0, zorder=5.0),
    "gp-mpc": Style(_GP, RECEDING, "D"),
    "gp-episodic": Style(_GP, EPISODIC, "d"),
    "ssgp-mpc": Style(_SSGP, RECEDING, "^"),
    "ssgp-episodic": Style(_SSGP, EPISODIC, "<"),
    "ssgp-mpc-nominal-hessian": Style(_SSGP_NOMINAL_HESSIAN, RECEDING, ">"),
    "ssgp-mpc-model-inputs": Style(_SSGP_MODEL_INPUTS, RECEDING, "P"),
    "ssgp-mpc-linearized": Style(_SSGP_LINEARIZED, RECEDING, "v"),
    "ssgp-mpc-linearized-model-inputs": Style(_SSGP_LINEARIZED_MODEL_INPUTS, RECEDING, "h"),
    "ssgp-mpc-sensitivities": Style(_SSGP_SENSITIVITIES, RECEDING, "H"),
    "ssgp-mpc-linearized-sensitivities": Style(_SSGP_LINEARIZED_SENSITIVITIES, RECEDING, "2"),
    "ssgp-mpc-adaptive": Style(_SSGP_ADAPTIVE, RECEDING, "$a$"),
    "ssgp-mpc-linearized-adaptive": Style(_SSGP_LINEARIZED_ADAPTIVE, RECEDING, "$l$"),
    "ssgp-mpc-linearized-guarded": Style(_SSGP_LINEARIZED_GUARDED, RECEDING, "$g$"),
    "ssgp-mpc-linearized-saturated": Style(_SSGP_LINEARIZED_SATURATED, RECEDING, "$t$"),
    "ssgp-mpc-linearized-parametric": Style(_SSGP_LINEARIZED_PARAMETRIC, RECEDING, "$q$"),
    "ssgp-mpc-rti-parametric": Style(_SSGP_LINEARIZED_PARAMETRIC, RTI, "$k$"),
    "ssgp-mpc-rti-parametric-split": Style(_SSGP_LINEARIZED_PARAMETRIC, RTI, "$K$"),
    # the SSGP RTI plans with the system's registered learned term (a linearized residual)
    "ssgp-mpc-rti": Style(_SSGP_LINEARIZED, RTI, "8"),
    # the zero-order RTI plans with the residual's value only; "-split": preparation/feedback
    "ssgp-mpc-rti-zero-order": Style(_SSGP, RTI, "$z$"),
    "nominal-mpc-rti-split": Style(_NOMINAL, RTI, "$n$", linewidth=1.6),
    "ssgp-mpc-rti-split": Style(_SSGP_LINEARIZED, RTI, "$s$"),
    "ssgp-mpc-rti-zero-order-split": Style(_SSGP, RTI, "$Z$"),
    # the pattern RTI: the linearized residual on the nominal Jacobian pattern
    "ssgp-mpc-rti-pattern": Style(_SSGP_LINEARIZED, RTI, "$p$"),
    "ssgp-mpc-rti-pattern-split": Style(_SSGP_LINEARIZED, RTI, "$P$"),
    # the RTI linearized on every system (ssgp-mpc-rti: the system's registered term)
    "ssgp-mpc-rti-linearized": Style(_SSGP_LINEARIZED, RTI, "$r$"),
    "ssgp-mpc-rti-linearized-split": Style(_SSGP_LINEARIZED, RTI, "$R$"),
    "blackbox-mpc": Style(_BLACKBOX, RECEDING, "$b$"),
    "blackbox-mpc@rti": Style(_BLACKBOX, RTI, "$B$"),
    "blackbox-mpc@rti-split": Style(_BLACKBOX, RTI, "$S$"),
    # the SQP scheme: converged like the receding MPC, on the RTI's QP machinery
    "nominal-mpc@sqp": Style(_NOMINAL, SQP_SCHEME, "$N$", linewidth=1.6),
    "oracle-mpc@sqp": Style(_ORACLE, SQP_SCHEME, "$W$", linewidth=1.0, zorder=5.0),
    "paper-mpc@sqp": Style(_SSGP, SQP_SCHEME, "$Y$"),
    "robust-mpc@sqp": Style(_SSGP_LINEARIZED_PARAMETRIC, SQP_SCHEME, "$Q$"),
    # make_mpc(env): the robust recipe with its own scheme on each system (the SQP where it
    # matched IPOPT); robust-mpc@converged is the older ssgp-mpc-linearized-parametric
    "robust-mpc": Style(_SSGP_LINEARIZED_PARAMETRIC, RECEDING, "$m$"),
    "blackbox-mpc@sqp": Style(_BLACKBOX, SQP_SCHEME, "$C$"),
    # the grey-box baseline: recursive least squares on the parameter sensitivities, no GP
    "parametric-mpc": Style(_PARAMETRIC_RLS, RECEDING, "$j$"),
    "robust-mpc-guarded": Style(_GUARDED, RECEDING, "$u$"),
    "robust-mpc-exact": Style(_EXACT, RECEDING, "$e$"),
    "robust-mpc-linearized": Style(_LINEARIZED_EVERYWHERE, RECEDING, "$i$"),
    "parametric-mpc@rti": Style(_PARAMETRIC_RLS, RTI, "$G$"),
    "parametric-mpc@rti-split": Style(_PARAMETRIC_RLS, RTI, "$H$"),
    "parametric-mpc@sqp": Style(_PARAMETRIC_RLS, SQP_SCHEME, "$J$"),
    "sac": Style(_SAC, RECEDING, "*"),
    "ppo": Style(_PPO, RECEDING, "X"),
    "tqc": Style(_TQC, RECEDING, "$T$"),
}
"""The style of every controller recipe, by recipe name (see the module docstring)."""
STYLES = {ALIASES[name][0] if name in ALIASES else name: value for name, value in STYLES.items()}
# the older names (benchmarks.controllers.ALIASES) are drawn as the controller they stand for


_ORDER = {s.marker: i for i, s in enumerate(STYLES.values())}
"""Position of each recipe's (unique) marker in :data:`STYLES`, to stagger markers."""


def style(controller: str) -> Style:
    """The style of recipe ``controller``.

    Raises:
        KeyError: a recipe without a style in :data:`STYLES` (add one there).
    """
    try:
        return STYLES[ALIASES[controller][0] if controller in ALIASES else controller]
    except KeyError:
        raise KeyError(f"controller {controller!r} has no plot style: add it to "
                       "benchmarks.styles.STYLES") from None


def unit(system: str, name: str) -> str:
    """The unit of state or control ``name`` of the registered ``system``, from its physics
    module's ``STATE_UNITS`` / ``CONTROL_UNITS`` (:func:`gp_envs.register_system` checks
    they are there).

    Raises:
        KeyError: an unknown system, or a name that is none of its states and controls.
    """
    from gp_envs.systems import SYSTEMS

    if system not in SYSTEMS:
        raise KeyError(f"{system!r} has no unit table: it is not a registered system")
    physics = SYSTEMS[system].env_class().physics
    table = dict(zip(physics.STATE_NAMES, physics.STATE_UNITS, strict=True))
    table.update(zip(physics.CONTROL_NAMES, physics.CONTROL_UNITS, strict=True))
    try:
        return table[name]
    except KeyError:
        raise KeyError(f"{system} has no state or control {name!r} (so no unit)") from None


def axis_label(system: str | None, name: str) -> str:
    """``"name (unit)"`` for an axis showing state or control ``name`` of ``system`` (None: a
    model of unknown units, ``"name"``)."""
    return name if system is None else f"{name} ({unit(system, name)})"
