"""Cart pole with ground and pivot damping (paper, Results, "Cart Pole"; errata note 1).

A cart of mass ``mc`` on a track, pushed by a horizontal force ``f``; a pole modelled as a point
mass ``mp`` at distance ``l`` from a frictional pivot on the cart. ``theta = 0`` hangs down,
``theta = pi`` is upright. Ground friction is ``-b1 * xdot`` on the cart, pivot friction a torque
``-b2 * thetadot`` on the pole. Lagrange's equations, with ``d = mc + mp sin(theta)^2``, give

    xddot     = ( f - b1 xd + b2 thd cos(th) / l + mp sin(th) (l thd^2 + g cos(th)) ) / d
    thetaddot = -( b2 thd (mc + mp) / (mp l) + (f - b1 xd) cos(th)
                   + sin(th) ((mc + mp) g + mp l thd^2 cos(th)) ) / (l d)

The paper prints b2 with the opposite sign (an energy source); this is the dissipative form.
"""

from __future__ import annotations

import casadi as ca

from gp_envs.physics.ranges import ParamRange

PARAM_RANGES: dict[str, ParamRange] = {
    "mc": ParamRange.positive("cart mass, kg"),
    "mp": ParamRange.positive("pole mass, kg"),
    "l": ParamRange.positive("pole length (pivot to point mass), m"),
    "b1": ParamRange.nonnegative("ground damping, N s/m"),
    "b2": ParamRange.nonnegative("pivot damping, N m s/rad"),
    "g": ParamRange.positive("gravity, m/s^2"),
}
"""Meaning, unit and valid range of each parameter, in the order of ``p``. Masses and the length
must be positive (``mp l`` and ``l d`` divide the accelerations); negative damping would be an
energy source (errata note 1); ``g > 0`` keeps ``theta = 0`` hanging down."""
PARAM_NAMES = tuple(PARAM_RANGES)
"""``("mc", "mp", "l", "b1", "b2", "g")``, see :data:`PARAM_RANGES`."""
STATE_NAMES = ("x", "theta", "xdot", "thetadot")
"""Cart position (m), pole angle (rad, 0 down), their rates (m/s, rad/s)."""
STATE_UNITS = ("m", "rad", "m/s", "rad/s")
"""Unit of each state component (axis labels, documentation)."""
CONTROL_NAMES = ("f",)
"""Horizontal force on the cart (N)."""
CONTROL_UNITS = ("N",)
"""Unit of each control component."""


def ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Cart-pole dynamics ``xdot = f(x, u, p)``.

    Args:
        x: (4,) state ``[x, theta, xdot, thetadot]``.
        u: (1,) control ``[f]``.
        p: (6,) parameters in the order of :data:`PARAM_NAMES`.

    Returns:
        (4,) state derivative.
    """
    mc, mp, l, b1, b2, g = (p[i] for i in range(6))
    th, xd, thd = x[1], x[2], x[3]
    s, c = ca.sin(th), ca.cos(th)
    f = u[0] - b1 * xd
    d = mc + mp * s**2
    xdd = (f + b2 * thd * c / l + mp * s * (l * thd**2 + g * c)) / d
    thdd = -(b2 * thd * (mc + mp) / (mp * l) + f * c
             + s * ((mc + mp) * g + mp * l * thd**2 * c)) / (l * d)
    return ca.vertcat(xd, thd, xdd, thdd)


def mechanical_energy(x, p):
    """Kinetic plus potential energy (J) of state ``x`` (4,) with parameters ``p`` (6,).

    Potential energy is zero at the pivot height; used by tests (conservation/dissipation).
    """
    mc, mp, l, _, _, g = (p[i] for i in range(6))
    th, xd, thd = x[1], x[2], x[3]
    kinetic = 0.5 * (mc + mp) * xd**2 + mp * l * xd * thd * ca.cos(th) + 0.5 * mp * l**2 * thd**2
    return kinetic - mp * g * l * ca.cos(th)
