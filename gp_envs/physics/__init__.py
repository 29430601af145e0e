"""The physics of each system, written once in CasADi operations.

Each module defines ``PARAM_RANGES`` (every parameter's meaning, unit and valid range, the
table :func:`~gp_envs.physics.ranges.check_params` checks every parameter set against),
``PARAM_NAMES``, ``STATE_NAMES``, ``CONTROL_NAMES``, their ``STATE_UNITS`` and
``CONTROL_UNITS``, and ``ode(x, u, p)``.
The envs simulate the true plant with it (numeric, through compiled CasADi functions) and expose
the same function with nominal parameters to controllers (symbolic), see :mod:`gp_envs.model`.
"""

from gp_envs.physics import cartpole, dubins, pendulum, pilco_cartpole, quadrotor
from gp_envs.physics.ranges import ParamRange

__all__ = ["ParamRange", "cartpole", "dubins", "pendulum", "pilco_cartpole", "quadrotor"]
