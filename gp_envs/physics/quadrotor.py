"""Quadrotor, small-attitude model (paper, Results, "Quadrotor", Eq. QEoM; errata note 3).

North-east-down frame: positive ``z`` is down and gravity is ``+g`` on ``zddot``. The four rotor
thrusts ``F1..F4`` (N, non-negative) are the controls; their sum acts along the body's thrust
axis. Euler-angle rates are used as body rates (the paper's simplification, valid for small
attitudes). Sign conventions of the translational terms are the paper's:

    xddot     =  (cos(phi) sin(theta) cos(psi) + sin(phi) sin(psi)) T / m
    yddot     =  (cos(phi) sin(theta) sin(psi) - sin(phi) cos(psi)) T / m
    zddot     =  g - cos(phi) cos(theta) T / m
    phiddot   = (thetad psid (Jy - Jz) + L (F4 - F2)) / Jx
    thetaddot = (phid psid (Jz - Jx) + L (F1 - F3)) / Jy
    psiddot   = (phid thetad (Jx - Jy) + 0.05 L (F2 + F4 - F1 - F3)) / Jz

with ``T = F1 + F2 + F3 + F4``. Hover needs ``T = m g``.
"""

from __future__ import annotations

import casadi as ca

from gp_envs.physics.ranges import ParamRange

PARAM_RANGES: dict[str, ParamRange] = {
    "m": ParamRange.positive("mass, kg"),
    "Jx": ParamRange.positive("roll inertia, kg m^2"),
    "Jy": ParamRange.positive("pitch inertia, kg m^2"),
    "Jz": ParamRange.positive("yaw inertia, kg m^2"),
    "L": ParamRange.positive("arm length (centre to rotor), m"),
    "g": ParamRange.positive("gravity, m/s^2"),
}
"""Meaning, unit and valid range of each parameter, in the order of ``p``: all positive (the
mass and the inertias divide the accelerations, a zero arm has no torque, ``g > 0`` is down
in NED). Each value is checked on its own: the inertias' triangle inequality is not."""
PARAM_NAMES = tuple(PARAM_RANGES)
"""``("m", "Jx", "Jy", "Jz", "L", "g")``, see :data:`PARAM_RANGES`."""
STATE_NAMES = ("x", "y", "z", "phi", "theta", "psi",
               "xdot", "ydot", "zdot", "phidot", "thetadot", "psidot")
"""Position (m, NED), roll/pitch/yaw (rad), their rates (m/s, rad/s)."""
STATE_UNITS = ("m", "m", "m", "rad", "rad", "rad",
               "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s")
"""Unit of each state component (axis labels, documentation)."""
CONTROL_NAMES = ("F1", "F2", "F3", "F4")
"""Rotor thrusts (N)."""
CONTROL_UNITS = ("N", "N", "N", "N")
"""Unit of each control component."""
YAW_DRAG_RATIO = 0.05
"""Rotor drag torque per unit thrust and arm length (the paper's 0.05 L)."""


def ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Quadrotor dynamics ``xdot = f(x, u, p)``.

    Args:
        x: (12,) state, see :data:`STATE_NAMES`.
        u: (4,) rotor thrusts ``[F1, F2, F3, F4]`` in newtons.
        p: (6,) parameters in the order of :data:`PARAM_NAMES`.

    Returns:
        (12,) state derivative.
    """
    m, jx, jy, jz, arm, g = (p[i] for i in range(6))
    phi, theta, psi = x[3], x[4], x[5]
    phid, thetad, psid = x[9], x[10], x[11]
    f1, f2, f3, f4 = u[0], u[1], u[2], u[3]
    thrust = f1 + f2 + f3 + f4
    cphi, sphi = ca.cos(phi), ca.sin(phi)
    cth, sth = ca.cos(theta), ca.sin(theta)
    cpsi, spsi = ca.cos(psi), ca.sin(psi)
    xdd = (cphi * sth * cpsi + sphi * spsi) * thrust / m
    ydd = (cphi * sth * spsi - sphi * cpsi) * thrust / m
    zdd = g - cphi * cth * thrust / m
    phidd = (thetad * psid * (jy - jz) + arm * (f4 - f2)) / jx
    thetadd = (phid * psid * (jz - jx) + arm * (f1 - f3)) / jy
    psidd = (phid * thetad * (jx - jy) + YAW_DRAG_RATIO * arm * (f2 + f4 - f1 - f3)) / jz
    return ca.vertcat(x[6], x[7], x[8], phid, thetad, psid, xdd, ydd, zdd, phidd, thetadd, psidd)
