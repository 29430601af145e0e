"""Dubins vehicle with actuator losses (paper, "Obstacle Avoidance using SSGP"; errata note 2).

A planar vehicle commanded in speed ``u1`` (m/s) and turn rate ``u2`` (rad/s); the actuators
deliver only the fractions ``1 - b1`` and ``1 - b2`` of the command:

    xdot   = (1 - b1) u1 cos(psi)
    ydot   = (1 - b1) u1 sin(psi)
    psidot = (1 - b2) u2

(the paper's third equation repeats b1; the reading used here is b2).
"""

from __future__ import annotations

import casadi as ca

from gp_envs.physics.ranges import ParamRange

PARAM_RANGES: dict[str, ParamRange] = {
    "b1": ParamRange(-float("inf"), 1.0, False, False, "speed loss factor, dimensionless"),
    "b2": ParamRange(-float("inf"), 1.0, False, False, "turn-rate loss factor, dimensionless"),
}
"""Meaning, unit and valid range of each parameter, in the order of ``p``. A factor ``b < 1``
keeps the delivered fraction ``1 - b`` positive (errata note 2: the actuator moves the way it is
commanded); ``b < 0`` is an actuator stronger than its command, which the scenario's nominal
draws ``N(0.3, 0.3)`` believe in about 16% of the episodes, as the paper's experiment does."""
PARAM_NAMES = tuple(PARAM_RANGES)
"""``("b1", "b2")``, see :data:`PARAM_RANGES`."""
STATE_NAMES = ("x", "y", "psi")
"""Position (m) and heading (rad, from the x axis)."""
STATE_UNITS = ("m", "m", "rad")
"""Unit of each state component (axis labels, documentation)."""
CONTROL_NAMES = ("u1", "u2")
"""Commanded speed (m/s) and commanded turn rate (rad/s)."""
CONTROL_UNITS = ("m/s", "rad/s")
"""Unit of each control component."""


def ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Dubins dynamics ``xdot = f(x, u, p)``.

    Args:
        x: (3,) state ``[x, y, psi]``.
        u: (2,) control ``[u1, u2]``.
        p: (2,) parameters ``[b1, b2]``.

    Returns:
        (3,) state derivative.
    """
    b1, b2 = p[0], p[1]
    speed = (1 - b1) * u[0]
    return ca.vertcat(speed * ca.cos(x[2]), speed * ca.sin(x[2]), (1 - b2) * u[1])
