"""PILCO's cart-pole swing-up: a uniform rod on a cart, 0.1 s control period, 4 s trials.

The cart-pole experiment of PILCO (Deisenroth & Rasmussen, ICML 2011) as its MATLAB code sets
it up (``github:ICL-SML/pilco-matlab`` V0.9, ``scenarios/cartPole/``: ``settings_cp.m``,
``dynamics_cp.m``, ``loss_cp.m``; ``base/rollout.m``), with the success criterion of GP-MPC
(Kamthe & Deisenroth, AISTATS 2018), which compares against PILCO on this system.
Physics: :mod:`gp_envs.physics.pilco_cartpole`.

Why a system of its own and not a scenario of ``gp_envs/CartPoleSwingUp-v0``: the control
period (0.1 s against that env's class-wide 0.05 s), the trial length (4 s against 6 s), the
start distribution, the parametrisation of the pole (a uniform rod of mass ``mp`` and length
``l``, which the point-mass pole's ``mp, l`` express only through a change of parameters that
would make the nominal model's declared errors meaningless) and the success criterion (the
pole *tip's* distance to its target, not a box on ``x`` and ``theta``) are all fixed per env
class there. The equations are the cart-pole module's (the physics module says why).

## Numbers and their sources
Files are those of ``scenarios/cartPole/`` of the MATLAB code unless a path is given; GP-MPC's
numbers (the 8 cm / 10-step success criterion, the anchors' interaction times) are as quoted by
this project's data-efficiency study, not checked against the paper's text.

- cart mass ``mc`` = 0.5 kg: ``dynamics_cp.m``, ``M = 0.5``.
- pole mass ``mp`` = 0.5 kg, a uniform rod (inertia ``m l^2 / 3`` about the pivot in the
  equations and the energy of ``dynamics_cp.m``): ``dynamics_cp.m``, ``m = 0.5``.
- pole length ``l`` = 0.5 m: ``dynamics_cp.m``, ``l = 0.5``; ``settings_cp.m``,
  ``cost.p = 0.5``; GP-MPC: 50 cm. (``draw_cp.m`` draws it 0.6 m long: a drawing only.)
- cart-ground friction ``b`` = 0.1 N s/m: ``dynamics_cp.m``, ``b = 0.1``; no pivot friction.
- gravity ``g`` = 9.82 m/s^2: ``dynamics_cp.m``, ``g = 9.82``.
- force bound 10 N: ``settings_cp.m``, ``policy.maxU = 10``; GP-MPC: 10 N.
- control period 0.1 s, zero-order hold: ``settings_cp.m``, ``dt = 0.10``,
  ``plant.ctrl = @zoh``.
- trial length 4 s = 40 steps: ``settings_cp.m``, ``T = 4.0``, ``H = ceil(T/dt)``.
- start ``N(0, 0.1^2)`` on each of ``x, xdot, thetadot, theta`` (hanging at rest):
  ``settings_cp.m``, ``mu0 = [0 0 0 0]'``, ``S0 = diag([0.1 0.1 0.1 0.1].^2)``;
  ``cartPole_learn.m`` and ``base/applyController.m`` start every trial from
  ``gaussian(mu0, S0)``.
- target ``x = 0``, ``theta = pi`` (tip at ``(0, l)``): ``settings_cp.m``,
  ``cost.target = [0 0 0 pi]'``.
- PILCO's cost ``1 - exp(-d^2 / (2 * 0.25^2))`` per step, ``d`` the tip's distance (m) to its
  target: ``loss_cp.m`` with ``settings_cp.m``'s ``cost.width = 0.25``.
- success: the tip within 8 cm of its target for 10 consecutive steps: GP-MPC.
- initial data: one trial (``cartPole_learn.m``, ``J = 1``) of forces drawn uniformly from
  ``[-10, 10]`` N at every step (``base/rollout.m`` without a policy function,
  ``policy.maxU.*(2*rand(1,nU)-1)``).
- measurement noise, standard deviation 0.01 on each component: ``settings_cp.m``,
  ``plant.noise = diag(ones(1,4)*0.01.^2)``.
- track ``|x| <= 3`` m: ``draw_cp.m``, ``xmin = -3; xmax = 3`` (drawn only: PILCO's simulation
  has no track limit). The nominal MPC's swing-ups stay within 0.82 m (seeds 0-9), but PILCO's
  random trial wanders: of 300 simulated 4 s trials of uniform random forces on the true
  model, 71 % left ``|x| <= 3`` m (median furthest excursion 4.9 m). Here such a trial ends
  there (terminated); :func:`gp_agents.collect_initial_data` starts another episode until it
  has its number of transitions, so the initial data's interaction time is still theirs.

Not from a source (chosen here): the velocity guards ``|xdot| <= 10`` m/s and ``|thetadot| <=
25`` rad/s (those of the other cart pole; divergence guards, never reached by a swing-up under
10 N); RK4 with 10 substeps (PILCO integrates with ``ode45``); the quadratic task cost below;
the nominal model's errors. The measurement noise is not on by default (as for the other envs):
``gym.make(..., observation_noise=0.01)`` reproduces it. GP-MPC's reported interaction times
(9 s over 3 trials counting the random one, PILCO's ~15 s over 5) imply 3 s trials there; the
MATLAB code's 4 s is used here (the paper's text was not at hand to check).

## Observation, action
As ``gp_envs/CartPoleSwingUp-v0`` (:mod:`gp_envs.cartpole_swingup`): observation ``[x, theta,
xdot, thetadot]`` with ``theta`` wrapped to ``[0, 2 pi)`` (0 hangs down, pi upright); action the
horizontal force on the cart in N, ``|f| <= 10``, clipped.

## Scenarios (true values are hidden, nominal ones are ``nominal_model``)
| name    | true mc, mp, l, b, g        | nominal mc, mp, l, b, g    | f_max |
|---------|-----------------------------|----------------------------|-------|
| "pilco" | 0.5, 0.5, 0.5, 0.1, 9.82    | 0.45, 0.45, 0.5, 0, 9.82   | 10 N  |

The nominal model's declared error (a choice, in the manner of the other cart pole's "online"
table): the cart-ground friction is unmodelled and both masses are 10 % low; the pole length
(measurable with a ruler) and gravity are right.

## Task, reward, success, episode
Success is GP-MPC's criterion: the pole tip, at ``(x + l sin(theta), -l cos(theta))`` with
PILCO's cost length ``l = 0.5`` m, within 8 cm of its target ``(0, l)`` for the last 10
consecutive control periods (1 s). ``info["at_goal"]`` is the tip criterion at the current step,
``info["distance_to_goal"]`` the tip distance (m), ``info["at_goal_since"]`` the time (s) at
which the current stretch at the goal began (so a benchmark can tell when the final, held
stretch began), ``info["pilco_loss"]`` PILCO's saturating cost of the current state.

The reward (and the controllers' cost) is this package's quadratic stage cost, not PILCO's
saturating one (whose gradient vanishes far from the target, which a receding-horizon planner
cannot use): ``l = e' Q e + R f^2`` per second, ``e = obs - [0, pi, 0, 0]`` with the angle
wrapped, ``Q = diag(2, 2, 0.05, 0.05)``, ``R = 1e-3`` (the other cart pole's weights); reward per
step ``-dt * l``. Leaving the track or the guards terminates with a penalty of the remaining
time times an upper bound of the stage cost. The episode lasts 4 s (40 steps, truncation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gp_envs.base import Scenario
from gp_envs.cartpole_swingup import CartPoleSwingUpEnv
from gp_envs.model import Task, diag
from gp_envs.physics import pilco_cartpole
from gp_envs.systems import System, register_system

G = 9.82
"""Gravity, m/s^2 (``dynamics_cp.m``)."""
POLE_LENGTH = 0.5
"""Pole length for the tip position, m (``settings_cp.m``: ``cost.p``)."""
TIP_TOLERANCE = 0.08
"""Success radius around the tip's target, m (GP-MPC: 8 cm)."""
COST_WIDTH = 0.25
"""Width of PILCO's saturating cost, m (``settings_cp.m``: ``cost.width``)."""


@dataclass(frozen=True)
class TipTask(Task):
    """A cart-pole task whose goal region is a disc around the pole tip's target.

    :meth:`at_goal` and :meth:`goal_distance` judge the pole tip's distance to where it is at
    the goal state, not a box on the state (``goal_tolerance`` is not used); the stage cost is
    the quadratic one of :class:`Task`.

    Attributes:
        pole_length: pivot-to-tip length, m.
        tip_tolerance: radius of the goal disc around the tip's target, m.
    """

    pole_length: float = POLE_LENGTH
    tip_tolerance: float = TIP_TOLERANCE

    def tip(self, x: np.ndarray) -> np.ndarray:
        """(..., 2) tip position (m; horizontal, vertical from the pivot height) of states
        ``x`` (..., 4) ``[x, theta, ...]``."""
        x = np.asarray(x, dtype=float)
        return np.stack([x[..., 0] + self.pole_length * np.sin(x[..., 1]),
                         -self.pole_length * np.cos(x[..., 1])], axis=-1)

    def tip_distance(self, x: np.ndarray) -> np.ndarray | float:
        """Distance (m) of the tip of state(s) ``x`` (..., 4) to the tip at the goal state."""
        d = np.linalg.norm(self.tip(x) - self.tip(self.goal), axis=-1)
        return float(d) if d.ndim == 0 else d

    def at_goal(self, x: np.ndarray) -> bool:
        """True when the tip is within :attr:`tip_tolerance` of its target."""
        return bool(self.tip_distance(x) <= self.tip_tolerance)

    def goal_distance(self, x: np.ndarray) -> float:
        """The tip's distance to its target, m."""
        return float(self.tip_distance(x))


def pilco_loss(task: TipTask, x: np.ndarray, width: float = COST_WIDTH) -> float:
    """PILCO's immediate cost ``1 - exp(-d^2 / (2 width^2))`` (dimensionless, in [0, 1)) of
    state ``x`` (4,), ``d`` the tip distance (m) to its target (``loss_cp.m``)."""
    return float(1.0 - np.exp(-0.5 * task.tip_distance(x) ** 2 / width**2))


class PilcoCartPoleEnv(CartPoleSwingUpEnv):
    """PILCO's cart-pole swing-up; see the module docstring for the numbers and their sources.

    Spaces, termination and rendering are those of :class:`CartPoleSwingUpEnv`.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"],
                                          "render_fps": 10}
    physics = pilco_cartpole
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "pilco": Scenario(
            description="PILCO's MATLAB cart pole; nominal: friction unmodelled, masses 10% low",
            true={"mc": 0.5, "mp": 0.5, "l": 0.5, "b": 0.1, "g": G},
            nominal={"mc": 0.45, "mp": 0.45, "l": 0.5, "b": 0.0, "g": G},
            u_lb=(-10.0,), u_ub=(10.0,)),
    }
    DEFAULT_SCENARIO = "pilco"
    DT = 0.1
    SUBSTEPS = 10
    TRACK = 3.0
    X_LB = np.array([-TRACK, -np.inf, -10.0, -25.0])
    X_UB = np.array([TRACK, np.inf, 10.0, 25.0])
    START_STD = 0.1
    """Standard deviation of each start component (m, rad, m/s, rad/s; ``settings_cp.m``)."""

    def _task(self) -> Task:
        return TipTask(
            goal=np.array([0.0, np.pi, 0.0, 0.0]),
            Q=diag([2.0, 2.0, 0.05, 0.05]), R=diag([1e-3]), Qf=diag([20.0, 20.0, 1.0, 1.0]),
            u_ref=np.zeros(1), goal_tolerance=np.full(4, np.inf),
            hold_time=10 * self.DT, duration=4.0, periodic_indices=(1,),
        )

    def _initial_state(self) -> np.ndarray:
        return self.np_random.normal(0.0, self.START_STD, size=4)

    def _info(self, obs: np.ndarray, violation: str | None, reason: str | None, clipped: bool
              ) -> dict[str, Any]:
        info = super()._info(obs, violation, reason, clipped)
        info["pilco_loss"] = pilco_loss(self.nominal_model.task, obs)
        return info


SYSTEM = register_system(System(
    name="pilco_cartpole", env_id="gp_envs/PilcoCartPole-v0",
    entry_point="gp_envs.pilco_cartpole:PilcoCartPoleEnv", max_episode_steps=40))
"""PILCO's cart pole's registration (:mod:`gp_envs.systems`)."""
