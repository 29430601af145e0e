"""PILCO's cart pole: a uniform rod on a cart with cart friction.

Source: the PILCO MATLAB code (``github:ICL-SML/pilco-matlab``, V0.9),
``scenarios/cartPole/dynamics_cp.m``, which cites M. P. Deisenroth, *Efficient Reinforcement
Learning Using Gaussian Processes*, KIT Scientific Publishing 2010, Appendix C. A cart of mass
``mc`` on a track, pushed by a horizontal force ``f``, with ground friction ``-b xdot``; on it,
hinged without friction, a pole that is a *uniform rod* of mass ``mp`` and length ``l`` (its
centre of mass at ``l / 2``, its inertia about the pivot ``mp l^2 / 3``). ``theta = 0`` hangs
down, ``theta = pi`` is upright, as in :mod:`gp_envs.physics.cartpole`.

Why no formula of its own: a rigid pole is dynamically the same as the point-mass pole of
:mod:`gp_envs.physics.cartpole` with equivalent parameters. The rod's Lagrangian,

    T = (mc + mp) xd^2 / 2 + mp (l/2) xd thd cos(th) + (mp l^2 / 3) thd^2 / 2,
    V = -mp g (l/2) cos(th),

equals the point-mass one (``T = (mc' + mp') xd^2 / 2 + mp' l' xd thd cos(th) + mp' l'^2 thd^2
/ 2``, ``V = -mp' g l' cos(th)``) term by term for

    mc' = mc + mp / 4,   mp' = 3 mp / 4,   l' = 2 l / 3   (b1 = b, b2 = 0),

(``mp' l' = mp l / 2``, ``mp' l'^2 = mp l^2 / 3``, ``mc' + mp' = mc + mp``: a quarter of the
rod's mass at the pivot, three quarters at its centre of percussion ``2 l / 3``). So
:func:`ode` and :func:`mechanical_energy` call the cart-pole module's with these parameters;
``tests/test_pilco.py`` checks :func:`ode` against ``dynamics_cp.m``'s printed equations.
"""

from __future__ import annotations

import casadi as ca

from gp_envs.physics import cartpole
from gp_envs.physics.ranges import ParamRange

PARAM_RANGES: dict[str, ParamRange] = {
    "mc": ParamRange.positive("cart mass, kg"),
    "mp": ParamRange.positive("pole (uniform rod) mass, kg"),
    "l": ParamRange.positive("pole (uniform rod) length, pivot to tip, m"),
    "b": ParamRange.nonnegative("cart-ground friction, N s/m"),
    "g": ParamRange.positive("gravity, m/s^2"),
}
"""Meaning, unit and valid range of each parameter, in the order of ``p`` (``dynamics_cp.m``'s
``M, m, l, b, g``). Masses and the length must be positive, the friction must dissipate."""
PARAM_NAMES = tuple(PARAM_RANGES)
"""``("mc", "mp", "l", "b", "g")``, see :data:`PARAM_RANGES`."""
STATE_NAMES = cartpole.STATE_NAMES
"""Cart position (m), pole angle (rad, 0 down), their rates (m/s, rad/s); PILCO orders them
``[x, xdot, thetadot, theta]``."""
STATE_UNITS = cartpole.STATE_UNITS
"""Unit of each state component."""
CONTROL_NAMES = cartpole.CONTROL_NAMES
"""Horizontal force on the cart (N)."""
CONTROL_UNITS = cartpole.CONTROL_UNITS
"""Unit of each control component."""


def point_mass_params(p: ca.SX) -> ca.SX:
    """The point-mass cart pole's parameters (6,) (:data:`gp_envs.physics.cartpole.PARAM_NAMES`)
    equivalent to the rod cart pole's ``p`` (5,) (:data:`PARAM_NAMES`); see the module doc."""
    mc, mp, l, b, g = (p[i] for i in range(5))
    return ca.vertcat(mc + mp / 4, 3 * mp / 4, 2 * l / 3, b, 0, g)


def ode(x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
    """Rod cart-pole dynamics ``xdot = f(x, u, p)``.

    Args:
        x: (4,) state ``[x, theta, xdot, thetadot]`` (m, rad, m/s, rad/s).
        u: (1,) control ``[f]`` (N).
        p: (5,) parameters in the order of :data:`PARAM_NAMES`.

    Returns:
        (4,) state derivative.
    """
    return cartpole.ode(x, u, point_mass_params(p))


def mechanical_energy(x, p):
    """Kinetic plus potential energy (J) of state ``x`` (4,) with parameters ``p`` (5,).

    Potential energy is zero at the pivot height (``dynamics_cp.m`` with two arguments returns
    the same energy); used by tests (conservation without friction).
    """
    return cartpole.mechanical_energy(x, point_mass_params(p))
