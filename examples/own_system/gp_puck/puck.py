"""Puck on a line: ``pdot = v``, ``vdot = (F - c v) / m`` (mass m, viscous friction c)."""

import casadi as ca

from gp_envs.physics.ranges import ParamRange

PARAM_RANGES = {"m": ParamRange.positive("mass, kg"),
                "c": ParamRange.nonnegative("viscous friction, N s/m")}
PARAM_NAMES = tuple(PARAM_RANGES)
STATE_NAMES = ("p", "v")
STATE_UNITS = ("m", "m/s")
CONTROL_NAMES = ("F",)
CONTROL_UNITS = ("N",)


def ode(x, u, p):
    """The state derivative (2,) of state ``x`` (2,), force ``u`` (1,) and parameters ``p``."""
    return ca.vertcat(x[1], (u[0] - p[1] * x[1]) / p[0])
