"""Damped pendulum: a point mass on a rod, driven by a torque at a frictional pivot.

A point mass ``m`` at distance ``l`` from the pivot; ``theta = 0`` hangs down, ``theta = pi`` is
upright. The pivot applies the motor torque ``tau`` and viscous friction ``-b * thetadot``.
Newton's law for the rotation about the pivot (moment of inertia ``m l^2``):

    thetaddot = ( tau - b thetadot - m g l sin(theta) ) / (m l^2)

The mechanical energy ``E = m l^2 thetadot^2 / 2 - m g l cos(theta)`` changes at the rate
``dE/dt = thetadot (tau - b thetadot)``: friction only ever removes energy.
"""

from __future__ import annotations

import casadi as ca

from gp_envs.physics.ranges import ParamRange

PARAM_RANGES: dict[str, ParamRange] = {
    "m": ParamRange.positive("point mass, kg"),
    "l": ParamRange.positive("rod length (pivot to point mass), m"),
    "b": ParamRange.nonnegative("pivot friction, N m s/rad"),
    "g": ParamRange.positive("gravity, m/s^2"),
}
"""Meaning, unit and valid range of each parameter, in the order of ``p``: ``m l^2`` divides
the acceleration; negative friction would be an energy source; ``g > 0`` keeps ``theta = 0``
hanging down."""
PARAM_NAMES = tuple(PARAM_RANGES)
"""``("m", "l", "b", "g")``, see :data:`PARAM_RANGES`."""
STATE_NAMES = ("theta", "thetadot")
"""Angle (rad, 0 down) and angular rate (rad/s)."""
STATE_UNITS = ("rad", "rad/s")
"""Unit of each state component (axis labels, documentation)."""
CONTROL_NAMES = ("tau",)
"""Motor torque at the pivot (N m)."""
CONTROL_UNITS = ("N m",)
"""Unit of each control component."""


def ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Pendulum dynamics ``xdot = f(x, u, p)``.

    Args:
        x: (2,) state ``[theta, thetadot]``.
        u: (1,) control ``[tau]``.
        p: (4,) parameters in the order of :data:`PARAM_NAMES`.

    Returns:
        (2,) state derivative.
    """
    m, l, b, g = (p[i] for i in range(4))
    th, thd = x[0], x[1]
    thdd = (u[0] - b * thd - m * g * l * ca.sin(th)) / (m * l**2)
    return ca.vertcat(thd, thdd)


def mechanical_energy(x, p):
    """Kinetic plus potential energy (J) of state ``x`` (2,) with parameters ``p`` (4,);
    potential energy is zero at the pivot height. Used by the tests (dissipation)."""
    m, l, _, g = (p[i] for i in range(4))
    return 0.5 * m * l**2 * x[1] ** 2 - m * g * l * ca.cos(x[0])
