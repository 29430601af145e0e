"""The no-prior model of the ``"blackbox"`` recipe: kinematics only, every force learned.

GP-MPC (Kamthe & Deisenroth, AISTATS 2018) and PILCO (Deisenroth & Rasmussen, ICML 2011) learn
the dynamics from data with no physics prior. The ``"blackbox"`` recipe
(:func:`gp_agents.make_mpc`) is that baseline inside this package's MPC: the same planner,
learner and online learning as the other recipes, on a model that knows only the kinematic
identities (position rates are the velocities) and nothing about forces.

:func:`blackbox_model` keeps the nominal model's *kinematic* rows (the components outside its
``dynamic_indices``: ``d(x)/dt = xdot``, ``d(theta)/dt = thetadot``, which no parameter value
can make wrong; it checks that they depend on no parameter) and sets every *dynamic* row
(accelerations; the Dubins vehicle's actuated rates) to zero. The learned residual then sits on
exactly those rows (:class:`~gp_agents.residual.ResidualModel`'s default), so its targets are
the whole accelerations the data show. Bounds, task, control period and the parameter vector
(which the kinematic rows ignore) are the nominal model's, so an MPC can plan with it exactly
as with the nominal one; it lives here, on the controller side: no env knows it.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import gymnasium as gym

from gp_envs.model import ControlModel, OdeFn
from gp_envs.wrapper import nominal_model

__all__ = ["BlackBoxModel", "KinematicOde", "blackbox_model"]


@dataclass(frozen=True)
class KinematicOde:
    """``ode(x, u, p)`` whose rows in ``kinematic`` are ``nominal``'s and whose other rows are
    zero (a value object: equal for equal fields, so CasADi functions compiled for it are shared).

    Attributes:
        nominal: the nominal model's ``ode``.
        kinematic: the rows kept (the kinematic identities).
    """

    nominal: OdeFn
    kinematic: tuple[int, ...]

    def __call__(self, x: ca.SX, u: ca.SX, p: ca.SX) -> ca.SX:
        f = self.nominal(x, u, p)
        return ca.vertcat(*[f[i] if i in self.kinematic else ca.SX(0)
                            for i in range(x.shape[0])])


def blackbox_model(nominal: ControlModel) -> ControlModel:
    """``nominal`` without its physics: the kinematic rows kept, every dynamic row zero.

    Raises:
        ValueError: a kinematic row (outside ``dynamic_indices``) that depends on a parameter,
            i.e. is not a kinematic identity this construction may keep.
    """
    kinematic = tuple(i for i in range(nominal.n_states) if i not in nominal.dynamic_indices)
    x = ca.SX.sym("x", nominal.n_states)
    u = ca.SX.sym("u", nominal.n_controls)
    p = ca.SX.sym("p", len(nominal.param_names))
    f = nominal.casadi_parametric_function()(x, u, p)
    for i in kinematic:
        if ca.depends_on(f[i], p):
            raise ValueError(f"{nominal.name}: the rate of {nominal.state_names[i]!r} (not in "
                             f"dynamic_indices) depends on the model's parameters; a black-box "
                             f"model keeps only parameter-free kinematic rows")
    return ControlModel(
        name=nominal.name, ode=KinematicOde(nominal.ode, kinematic),
        param_names=nominal.param_names, params=dict(nominal.params),
        state_names=nominal.state_names, control_names=nominal.control_names, dt=nominal.dt,
        x_lb=nominal.x_lb, x_ub=nominal.x_ub, u_lb=nominal.u_lb, u_ub=nominal.u_ub,
        task=nominal.task, substeps=nominal.substeps, angle_indices=nominal.angle_indices,
        dynamic_indices=nominal.dynamic_indices, param_ranges=nominal.param_ranges)


class BlackBoxModel:
    """The ``"blackbox"`` recipe's model source: :func:`blackbox_model` of the env's current
    nominal model (the same object until the nominal model changes; a class, not a closure, so
    that the agent pickles)."""

    def __init__(self, env: gym.Env) -> None:
        self.env = env
        self._nominal: ControlModel | None = None
        self._model: ControlModel | None = None

    def __call__(self) -> ControlModel:
        nominal = nominal_model(self.env)
        if nominal is not self._nominal or self._model is None:
            self._nominal, self._model = nominal, blackbox_model(nominal)
        return self._model
