"""DeepMind Control Suite tasks as Gymnasium envs, and a nominal model of DMC's cart-pole.

:class:`DMCEnv` wraps any ``dm_control.suite`` task with its physics and reward untouched: the
observation is DMC's observation dict flattened in DMC's order, the action is DMC's action, the
reward is DMC's reward summed over the ``action_repeat`` physics control steps of one gym step
(returns stay on DMC's 0-1000 scale), and the episode ends by DMC's time limit (truncation).

dm_control is an optional dependency (the ``[mujoco]`` extra); it is imported when a
:class:`DMCEnv` is made, never when this module is imported.

For DMC's ``cartpole`` domain, :func:`cartpole_nominal_model` builds a
:class:`~gp_envs.model.ControlModel` in this package's cart-pole physics
(:mod:`gp_envs.physics.cartpole`) with the numbers of dm_control's ``cartpole.xml``
(:data:`CARTPOLE_XML_PARAMS`); :func:`cartpole_state` maps DMC's observation to that model's
state and :func:`cartpole_action` maps the model's control (a force in newtons) to DMC's action.
The nominal model is deliberately imperfect: it has a point-mass pole where MuJoCo has a capsule
(a rod). :data:`CARTPOLE_FRICTION` is a declared out-of-family variant of the plant (Coulomb
friction, which the model's viscous damping cannot represent), for
``DMCEnv("cartpole", "swingup", dof_frictionloss=CARTPOLE_FRICTION)``.

Conventions of DMC's cart-pole (checked against ``physics.named.data`` in ``tests/test_dmc.py``):
``qpos = [slider (cart x, m), hinge_1 (pole angle a, rad)]`` with ``a = 0`` upright and ``a > 0``
tilting the pole towards ``+x``; the observation is ``[x, cos a, sin a, xdot, adot]``
(``position`` = cart position and the pole's ``xmat`` entries ``zz``, ``xz``; ``velocity`` =
``qvel``). This package's angle is ``theta = pi - a`` (0 hanging down, pi upright, the tip at
``x + l sin(theta)``): the angle *and its sign* differ, ``thetadot = -adot``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gp_envs.base import Scenario
from gp_envs.cartpole_swingup import CartPoleSwingUpEnv
from gp_envs.model import ControlModel, ReadOnlyMapping, Task, diag
from gp_envs.physics import cartpole
from gp_envs.systems import System, register_system

_INSTALL_HINT = 'pip install "gp-pseudospectral-mpc[mujoco]"'
_DMC_SEED_LIMIT = 2**32  # numpy.random.RandomState (DMC's task RNG) takes seeds below 2**32
_JOINT_DOFS = {0: 6, 1: 3, 2: 1, 3: 1}  # mjtJoint free, ball, slide, hinge -> number of dofs


def _import_suite() -> Any:
    """``dm_control.suite``, imported on first use (dm_control is an optional extra).

    Without a display (no ``DISPLAY``) and no ``MUJOCO_GL`` chosen, MuJoCo's rendering backend
    is set to EGL, the headless one, before the import (else dm_control tries GLFW and warns)."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"
    try:
        from dm_control import suite
    except ImportError as exc:
        raise ImportError(f"DMCEnv needs dm_control and MuJoCo: {_INSTALL_HINT}") from exc
    return suite


def _check_action_repeat(action_repeat: Any) -> int:
    if isinstance(action_repeat, bool) or not isinstance(action_repeat, int | np.integer):
        raise ValueError(f"action_repeat must be an int >= 1, got {action_repeat!r}")
    if action_repeat < 1:
        raise ValueError(f"action_repeat must be an int >= 1, got {action_repeat!r}")
    return int(action_repeat)


class DMCEnv(gym.Env[np.ndarray, np.ndarray]):
    """A DeepMind Control Suite task as a Gymnasium env, physics and reward untouched.

    Observation: ``Box(float32)`` of DMC's observation dict, each entry flattened and
    concatenated in DMC's order (:attr:`observation_layout` gives each entry's slice), bounds
    from DMC's ``observation_spec``. Action: ``Box(float32)`` of DMC's ``action_spec``; actions
    are clipped to it. One gym step applies the action for ``action_repeat`` DMC steps (each the
    task's own control timestep), its reward is the sum of their DMC rewards (``info
    ["dmc_reward"]`` too), ``terminated`` is always False and ``truncated`` is True when DMC's
    episode ends (by its time limit; an episode ending inside a repeat stops there).

    Seeding uses dm_control's public API only: a seeded ``reset(seed=s)`` (re)loads the task
    with ``suite.load(domain, task, task_kwargs={"random": s})`` (a seed of ``2**32`` or more is
    replaced by one drawn from the seeded ``np_random``), so ``DMCEnv`` with seed ``s``
    reproduces ``suite.load`` with ``random=s``; an unseeded first reset loads with a seed drawn
    from ``np_random``; later unseeded resets continue the task's random stream.

    The env neither pickles nor deep-copies reliably (dm_control's physics holds MuJoCo
    pointers); make a new one instead.

    Args:
        domain: DMC domain name, e.g. ``"cartpole"``.
        task: task of that domain, e.g. ``"swingup"``.
        action_repeat: DMC control steps per gym step, an int >= 1.
        render_mode: None or ``"rgb_array"`` (MuJoCo's offscreen renderer; on a machine without
            a display set ``MUJOCO_GL=egl`` or ``osmesa`` before dm_control is imported).
        dof_frictionloss: optional Coulomb friction (MuJoCo's ``dof_frictionloss``: N for a
            slide joint, N m for a hinge) by joint name, set on every dof of the joint after
            every load and reset; the other joints keep the xml's values.

    Raises:
        ImportError: dm_control is not installed.
        ValueError: a bad ``action_repeat``, unknown domain or task, a bad ``render_mode``, or an
            unknown joint or a negative or non-finite friction in ``dof_frictionloss``.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 20}
    RENDER_HEIGHT = 240
    RENDER_WIDTH = 320

    def __init__(self, domain: str, task: str, *, action_repeat: int = 1,
                 render_mode: str | None = None,
                 dof_frictionloss: Mapping[str, float] | None = None) -> None:
        self.action_repeat = _check_action_repeat(action_repeat)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of "
                             f"{self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._suite = _import_suite()
        domains = sorted({d for d, _ in self._suite.ALL_TASKS})
        if domain not in domains:
            bench = ", ".join(f"{d}/{t}" for d, t in self._suite.BENCHMARKING)
            raise ValueError(f"unknown DMC domain {domain!r}; domains: {domains} "
                             f"(benchmarking tasks: {bench})")
        tasks = [t for d, t in self._suite.ALL_TASKS if d == domain]
        if task not in tasks:
            raise ValueError(f"unknown task {task!r} of DMC domain {domain!r}; tasks: {tasks}")
        self.domain, self.task = domain, task
        self._env = self._suite.load(domain, task)  # for the specs; reloaded on first reset
        self._friction = self._resolve_friction(dof_frictionloss)
        self.dof_frictionloss: Mapping[str, float] = ReadOnlyMapping(
            {k: float(v) for k, v in (dof_frictionloss or {}).items()})
        """The Coulomb friction set on top of the xml, by joint name (empty: the xml's)."""
        self._apply_friction()
        self._dmc_seed: int | None = None  # seed of the loaded task's RNG (None: spec-only env)
        self._timestep: Any = None
        self._closed = False

        obs_spec = self._env.observation_spec()
        lows, highs, layout, start = [], [], {}, 0
        for key, spec in obs_spec.items():
            size = int(np.prod(spec.shape, dtype=int))
            lo = np.broadcast_to(getattr(spec, "minimum", -np.inf), spec.shape)
            hi = np.broadcast_to(getattr(spec, "maximum", np.inf), spec.shape)
            lows.append(np.asarray(lo, dtype=np.float64).ravel())
            highs.append(np.asarray(hi, dtype=np.float64).ravel())
            layout[key] = slice(start, start + size)
            start += size
        self._obs_keys = tuple(obs_spec)
        self.observation_layout: Mapping[str, slice] = ReadOnlyMapping(layout)
        """Slice of the flattened observation that holds each entry of DMC's dict."""
        self.observation_space = spaces.Box(np.concatenate(lows).astype(np.float32),
                                            np.concatenate(highs).astype(np.float32),
                                            dtype=np.float32)
        act = self._env.action_spec()
        self._a_lo = np.broadcast_to(np.asarray(act.minimum, np.float64), act.shape).copy()
        self._a_hi = np.broadcast_to(np.asarray(act.maximum, np.float64), act.shape).copy()
        self.action_space = spaces.Box(self._a_lo.astype(np.float32),
                                       self._a_hi.astype(np.float32), dtype=np.float32)
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.dt))}

    # ----------------------------------------------------------------- properties
    @property
    def dt(self) -> float:
        """Seconds per gym step: ``action_repeat`` times DMC's control timestep."""
        return self.action_repeat * float(self._env.control_timestep())

    @property
    def physics(self) -> Any:
        """The dm_control ``Physics`` of the loaded task (for tests and oracles, not control).

        It is replaced on every seeded (and the first) reset; do not keep it across resets.
        """
        return self._env.physics

    def physics_state(self) -> np.ndarray:
        """The true physics state ``concatenate([qpos, qvel])``, shape (nq + nv,), float64.

        For tests and oracles only: the env's observation is DMC's observation, and a controller
        that claims to use only what the env shows must not call this.
        """
        data = self._env.physics.data
        return np.concatenate([data.qpos, data.qvel]).astype(np.float64)

    # ----------------------------------------------------------------- gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode (see the class docstring for seeding).

        Args:
            seed: optional seed (int >= 0).
            options: must be None or empty (no options are supported).

        Returns:
            (observation (n_obs,) float32, info ``{"time": s, "dmc_seed": int}``).

        Raises:
            ValueError: non-empty ``options``.
        """
        if options is not None and (not isinstance(options, Mapping) or len(options) > 0):
            raise ValueError(f"DMCEnv.reset takes no options, got {options!r}")
        super().reset(seed=seed)
        if seed is not None:
            dmc_seed = (int(seed) if int(seed) < _DMC_SEED_LIMIT
                        else int(self.np_random.integers(_DMC_SEED_LIMIT)))
            self._load(dmc_seed)
        elif self._dmc_seed is None or self._closed:
            self._load(int(self.np_random.integers(_DMC_SEED_LIMIT)))
        self._timestep = self._env.reset()
        self._apply_friction()
        assert self._dmc_seed is not None
        return self._flatten(self._timestep.observation), {
            "time": float(self._env.physics.data.time), "dmc_seed": self._dmc_seed}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Apply ``action`` (clipped to the bounds) for ``action_repeat`` DMC steps.

        Args:
            action: shape ``action_space.shape``, finite.

        Returns:
            (observation, reward = sum of the DMC rewards, terminated = False, truncated = DMC's
            episode ended, info ``{"dmc_reward": reward, "time": physics time in s}``).

        Raises:
            ValueError: wrong shape or a non-finite entry.
            RuntimeError: called before :meth:`reset` or after the episode ended.
        """
        if self._timestep is None:
            raise RuntimeError("call reset() before step()")
        if self._timestep.last():
            raise RuntimeError("the DMC episode has ended (truncated); call reset()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action must be finite, got {a}")
        a = np.clip(a, self._a_lo, self._a_hi)
        reward = 0.0
        for _ in range(self.action_repeat):
            self._timestep = self._env.step(a)
            reward += float(self._timestep.reward)
            if self._timestep.last():
                break
        obs = self._flatten(self._timestep.observation)
        info = {"dmc_reward": reward, "time": float(self._env.physics.data.time)}
        return obs, reward, False, bool(self._timestep.last()), info

    def render(self) -> np.ndarray | None:
        """An RGB frame (240, 320, 3) uint8 from camera 0 with ``render_mode="rgb_array"``.

        Returns:
            The frame, or None when ``render_mode`` is None.

        Raises:
            RuntimeError: MuJoCo cannot render here (no OpenGL context).
        """
        if self.render_mode is None:
            return None
        try:
            return self._env.physics.render(height=self.RENDER_HEIGHT, width=self.RENDER_WIDTH,
                                            camera_id=0)
        except Exception as exc:
            raise RuntimeError(
                "MuJoCo rendering is unavailable (no OpenGL context); on a machine without a "
                "display set MUJOCO_GL=egl (or osmesa) before dm_control is imported") from exc

    def close(self) -> None:
        """Release the DMC env (idempotent; a later :meth:`reset` loads the task anew)."""
        if not self._closed:
            self._env.close()
            self._closed = True

    # ----------------------------------------------------------------- internals
    def _load(self, dmc_seed: int) -> None:
        self._env.close()
        self._env = self._suite.load(self.domain, self.task, task_kwargs={"random": dmc_seed})
        self._dmc_seed = dmc_seed
        self._closed = False
        self._apply_friction()

    def _flatten(self, observation: Mapping[str, Any]) -> np.ndarray:
        return np.concatenate([np.asarray(observation[k], dtype=np.float64).ravel()
                               for k in self._obs_keys]).astype(np.float32)

    def _resolve_friction(self, friction: Mapping[str, float] | None
                          ) -> tuple[tuple[slice, float], ...]:
        """``dof_frictionloss`` as (dof slice, value) pairs, checked against the model."""
        if friction is None:
            return ()
        if not isinstance(friction, Mapping):
            raise ValueError(f"dof_frictionloss must be a mapping joint name -> value, "
                             f"got {friction!r}")
        model = self._env.physics.model
        joints = [model.id2name(j, "joint") for j in range(model.njnt)]
        out = []
        for name, value in friction.items():
            if name not in joints:
                raise ValueError(f"dof_frictionloss: unknown joint {name!r} of "
                                 f"{self.domain}/{self.task}; joints: {joints}")
            if isinstance(value, bool) or not isinstance(value, int | float | np.number):
                raise ValueError(f"dof_frictionloss[{name!r}] must be a real number, "
                                 f"got {value!r}")
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"dof_frictionloss[{name!r}] must be finite and >= 0, "
                                 f"got {value!r}")
            j = joints.index(name)
            start = int(model.jnt_dofadr[j])
            out.append((slice(start, start + _JOINT_DOFS[int(model.jnt_type[j])]),
                        float(value)))
        return tuple(out)

    def _apply_friction(self) -> None:
        model = self._env.physics.model
        for dofs, value in self._friction:
            model.dof_frictionloss[dofs] = value


# ===================================================================== DMC's cart-pole
CARTPOLE_XML_PARAMS: Mapping[str, float] = ReadOnlyMapping({
    "cart_mass": 1.0,          # kg, geom "cart" mass="1" (a 0.4 x 0.3 x 0.2 m box)
    "pole_mass": 0.1,          # kg, class "pole" geom mass=".1"
    "pole_length": 1.0,        # m, capsule fromto="0 0 0 0 0 1" (hinge at one end)
    "pole_radius": 0.045,      # m, capsule size
    "pole_com": 0.5,           # m, hinge to the pole's centre of mass (symmetric capsule)
    "slider_damping": 5e-4,    # N s/m, joint "slider" damping
    "hinge_damping": 2e-6,     # N m s/rad, class "pole" joint damping
    "gear": 10.0,              # N per unit action, motor "slide" gear
    "ctrl_min": -1.0,          # action, ctrlrange (ctrllimited="true")
    "ctrl_max": 1.0,
    "slider_min": -1.8,        # m, slider limited="true" range (a soft limit: solreflimit .08 1)
    "slider_max": 1.8,
    "timestep": 0.01,          # s, <option timestep>, integrator RK4
    "gravity": 9.81,           # m/s^2, MuJoCo's default (0 0 -9.81)
})
"""The numbers of dm_control's ``suite/cartpole.xml`` (and MuJoCo's defaults it relies on);
``tests/test_dmc.py`` checks them against the compiled ``physics.model``."""

CARTPOLE_CONTROL_TIMESTEP = 0.01
"""DMC cart-pole's control timestep, s (one physics step per control step)."""
CARTPOLE_TIME_LIMIT = 10.0
"""DMC cart-pole's episode length, s (1000 control steps)."""

CARTPOLE_FRICTION: Mapping[str, float] = ReadOnlyMapping({"slider": 1.0, "hinge_1": 0.05})
"""Declared out-of-family plant variant, fixed before any result was seen (not tuned): Coulomb
friction (``dof_frictionloss``) of 1.0 N on the slider (10% of the actuator's 10 N maximum
force) and 0.05 N m on the hinge (about 10% of the pole's maximum gravity torque,
``0.1 kg * 9.81 m/s^2 * 0.5 m = 0.49 N m``). The nominal model has viscous damping only."""

_LENGTHS = {
    # the pole's centre of mass: right static (gravity) torque and cart coupling, inertia about
    # the hinge mp * 0.5^2 = 0.025 kg m^2 where MuJoCo's capsule has 0.0344 kg m^2
    "com": CARTPOLE_XML_PARAMS["pole_com"],
    # the point mass with a thin uniform rod's small-oscillation frequency on a fixed pivot,
    # (mp L^2 / 3) / (mp L / 2) = 2 L / 3; right frequency, but coupling and torque too large
    "rod": 2.0 * CARTPOLE_XML_PARAMS["pole_length"] / 3.0,
}


def cartpole_task() -> Task:
    """The task of :func:`cartpole_nominal_model` (its docstring says where the weights come
    from): upright and centred, DMC's "swung up" bounds held for 1 s, DMC's 10 s."""
    Q = diag([2.3, 2.0, 0.05, 0.37])
    return Task(
        goal=np.array([0.0, np.pi, 0.0, 0.0]), Q=Q, R=diag([0.016]), Qf=10.0 * Q,
        u_ref=np.zeros(1),
        goal_tolerance=np.array([0.25, float(np.arccos(0.995)), np.inf, np.inf]),
        hold_time=1.0, duration=CARTPOLE_TIME_LIMIT, periodic_indices=(1,),
    )


def cartpole_params(length: str = "com") -> dict[str, float]:
    """:mod:`gp_envs.physics.cartpole`'s parameters with ``cartpole.xml``'s numbers (``l`` by
    ``length``, see :func:`cartpole_nominal_model`)."""
    if length not in _LENGTHS:
        raise ValueError(f"length must be one of {list(_LENGTHS)}, got {length!r}")
    xml = CARTPOLE_XML_PARAMS
    return {"mc": xml["cart_mass"], "mp": xml["pole_mass"], "l": _LENGTHS[length],
            "b1": xml["slider_damping"], "b2": xml["hinge_damping"], "g": xml["gravity"]}


def cartpole_nominal_model(action_repeat: int = 5, *, length: str = "com") -> ControlModel:
    """Nominal model of DMC's cart-pole in this package's cart-pole physics.

    :mod:`gp_envs.physics.cartpole` with ``cartpole.xml``'s numbers: ``mc = 1.0`` kg,
    ``mp = 0.1`` kg, ``b1 = 5e-4`` N s/m, ``b2 = 2e-6`` N m s/rad, ``g = 9.81`` m/s^2, and ``l``
    by ``length``. The physics has a point-mass pole; MuJoCo's is a capsule (about a uniform
    rod of length L = 1 m), whose inertia about the hinge is about ``mp L^2 / 3`` (0.0344 kg m^2
    for the capsule) rather than ``mp l^2`` (0.025 kg m^2 at ``l = 0.5``): no single ``l``
    matches both, so this nominal model is deliberately imperfect (a learned residual's job).

    State ``[x (m), theta (rad, 0 hanging down, pi upright), xdot (m/s), thetadot (rad/s)]``
    (:func:`cartpole_state` maps DMC's observation to it); control: the force on the cart in
    newtons, ``|f| <= gear = 10`` N (:func:`cartpole_action` maps it to DMC's action
    ``f / gear``).

    Task (the controller's cost; :class:`DMCEnv` keeps DMC's reward): goal ``[0, pi, 0, 0]``.
    The weights are the quadratic expansion about the goal of ``-log`` of DMC's smooth reward
    ``upright * centered * small_control * small_velocity`` (``(1 + cos a) / 2``,
    ``(1 + tol(x, margin 2)) / 2``, ``(4 + 1 - (f / 10)^2) / 5``,
    ``(1 + tol(adot, margin 5)) / 2``, gaussian tolerances with value 0.1 at the margin), i.e.
    ``e^2 / 4``, ``(ln 10 / 8) x^2``, ``(ln 10 / 50) adot^2``, ``f^2 / 500``, scaled by 8 so
    that the angle weight is 2 as in :mod:`gp_envs.cartpole_swingup`: ``Q = diag(2.3, 2, 0.05,
    0.37)`` (``xdot``, absent from DMC's reward, gets a small 0.05), ``R = 0.016`` per N^2,
    ``Qf = 10 Q``. Success (``goal_tolerance``, ``hold_time`` 1 s) uses DMC's own "swung up"
    bounds from its sparse reward: ``|x| <= 0.25`` m and ``cos a >= 0.995`` (``|theta - pi|
    <= 0.1`` rad). Duration: DMC's 10 s time limit.

    Bounds: ``|x| <= 1.8`` m (the slider's limited range in the xml), ``|xdot| <= 10`` m/s,
    ``|thetadot| <= 25`` rad/s (guards as in :mod:`gp_envs.cartpole_swingup`), theta free.

    Args:
        action_repeat: DMC control steps (0.01 s each) per model step: ``dt = 0.01 *
            action_repeat`` s, RK4 with ``5 * action_repeat`` substeps (2 ms).
        length: ``"com"`` (default): ``l = 0.5`` m, the pole's centre of mass; ``"rod"``:
            ``l = 2/3`` m, the point mass that swings like a thin rod of 1 m.

    Returns:
        The model, ``name="dmc_cartpole"``.

    Raises:
        ValueError: a bad ``action_repeat`` or an unknown ``length``.
    """
    action_repeat = _check_action_repeat(action_repeat)
    if length not in _LENGTHS:
        raise ValueError(f"length must be one of {list(_LENGTHS)}, got {length!r}")
    xml = CARTPOLE_XML_PARAMS
    f_max = xml["gear"] * xml["ctrl_max"]
    f_min = xml["gear"] * xml["ctrl_min"]
    task = cartpole_task()
    return ControlModel(
        name="dmc_cartpole", ode=cartpole.ode, param_names=cartpole.PARAM_NAMES,
        params=cartpole_params(length),
        state_names=cartpole.STATE_NAMES, control_names=cartpole.CONTROL_NAMES,
        dt=CARTPOLE_CONTROL_TIMESTEP * action_repeat,
        x_lb=np.array([xml["slider_min"], -np.inf, -10.0, -25.0]),
        x_ub=np.array([xml["slider_max"], np.inf, 10.0, 25.0]),
        u_lb=np.array([f_min]), u_ub=np.array([f_max]), task=task,
        substeps=5 * action_repeat, angle_indices=(1,), dynamic_indices=(2, 3),
        param_ranges=cartpole.PARAM_RANGES,
    )


def cartpole_action(u: np.ndarray) -> np.ndarray:
    """The model's control (force on the cart, N) as DMC's action ``f / gear``.

    Args:
        u: (..., 1) force(s) in newtons.

    Returns:
        (..., 1) DMC action(s), float64 (not clipped; :class:`DMCEnv` clips to [-1, 1]).
    """
    return np.asarray(u, dtype=np.float64) / CARTPOLE_XML_PARAMS["gear"]


def cartpole_state(obs: np.ndarray) -> np.ndarray:
    """DMC cart-pole's flattened observation as the nominal model's state.

    Args:
        obs: (..., 5) ``[x, cos a, sin a, xdot, adot]`` (DMC's ``position`` then ``velocity``;
            ``a`` the hinge angle, 0 upright, positive towards ``+x``).

    Returns:
        (..., 4) ``[x, theta, xdot, thetadot]`` float64 with ``theta = pi - a`` wrapped to
        ``[0, 2 pi)`` (0 hanging down) and ``thetadot = -adot``.
    """
    o = np.asarray(obs, dtype=np.float64)
    if o.shape[-1:] != (5,):
        raise ValueError(f"expected DMC cart-pole observations (..., 5), got {o.shape}")
    # theta = pi - a: cos(theta) = -cos(a), sin(theta) = sin(a)
    theta = np.mod(np.arctan2(o[..., 2], -o[..., 1]), 2 * np.pi)
    theta = np.where(theta >= np.float32(2 * np.pi), 0.0, theta)  # as gp_envs.base.wrap_to_circle
    return np.stack([o[..., 0], theta, o[..., 3], -o[..., 4]], axis=-1)


# ===================================================================== a gp_envs env in MuJoCo
class MuJoCoCartPole:
    """DMC's cart-pole physics (MuJoCo, ``cartpole.xml``) as a :class:`gp_envs.base.Plant`:
    it steps the package's state ``[x, theta, xdot, thetadot]`` (theta 0 hanging) under a force
    in newtons held for ``action_repeat`` of MuJoCo's 0.01 s steps.

    Each step starts from the given state (MuJoCo's solver warm start cleared), so a step
    depends on the state and the force only.

    Args:
        action_repeat: MuJoCo steps per control period.
        dof_frictionloss: Coulomb friction by joint name (:class:`DMCEnv`), or None.
    """

    def __init__(self, action_repeat: int = 5,
                 dof_frictionloss: Mapping[str, float] | None = None) -> None:
        self.action_repeat = _check_action_repeat(action_repeat)
        self._dmc = DMCEnv("cartpole", "swingup", dof_frictionloss=dof_frictionloss)

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The state one control period after ``x`` (4,) under the force ``u`` (1,), N."""
        physics = self._dmc.physics
        x = np.asarray(x, dtype=float)
        with physics.reset_context():
            physics.data.qpos[:] = [x[0], np.pi - x[1]]
            physics.data.qvel[:] = [x[2], -x[3]]
        physics.data.qacc_warmstart[:] = 0.0
        action = np.clip(cartpole_action(np.asarray(u, float)), CARTPOLE_XML_PARAMS["ctrl_min"],
                         CARTPOLE_XML_PARAMS["ctrl_max"])
        for _ in range(self.action_repeat):
            physics.set_control(action)
            physics.step()
        qpos, qvel = physics.data.qpos, physics.data.qvel
        return np.array([qpos[0], np.pi - qpos[1], qvel[0], -qvel[1]])


class MuJoCoCartPoleEnv(CartPoleSwingUpEnv):
    """DMC's cart-pole in MuJoCo as a ``gp_envs`` env (``gp_envs/MuJoCoCartPole-v0``): the
    package's observation (the state, the angle wrapped), reward (minus the task's cost),
    success and hidden-truth API around MuJoCo's physics (:class:`MuJoCoCartPole`, a
    :class:`~gp_envs.base.Plant` that is not the package's ODE). The nominal model has
    :func:`cartpole_nominal_model`'s numbers and task; the truth has no parameter values, so
    ``randomize`` and ``true_params`` raise and there is no oracle. For DMC's own reward and
    observation, wrap :class:`DMCEnv` with :func:`gp_envs.wrap` instead (the benchmark's
    ``dmc-cartpole``).

    Scenarios: ``"swingup"`` (``cartpole.xml`` as it is) and ``"friction"``
    (:data:`CARTPOLE_FRICTION`). Control period 0.05 s (5 MuJoCo steps), 10 s episodes from
    DMC's swing-up start (cart and pole at rest, hanging, 0.01 noise on every component).
    The episode ends if the cart leaves ``|x| <= 2.5`` m (MuJoCo's soft rails stop it near
    1.9 m); the models' planning box keeps it within the rails' 1.8 m.
    """

    NAME = "mujoco_cartpole"
    OUTSIDE_PLANT = True
    ACTION_REPEAT = 5
    SCENARIOS: ClassVar[dict[str, Scenario]] = {
        "swingup": Scenario(
            description="DMC's cartpole.xml in MuJoCo; nominal: the point-mass cart pole with "
                        "its numbers", true={}, nominal=cartpole_params(),
            u_lb=(-CARTPOLE_XML_PARAMS["gear"],), u_ub=(CARTPOLE_XML_PARAMS["gear"],)),
    }
    SCENARIOS["friction"] = Scenario(
        description="as swingup, with Coulomb friction on the slider and the hinge "
                    "(CARTPOLE_FRICTION), which the nominal model cannot represent",
        true={}, nominal=cartpole_params(), u_lb=SCENARIOS["swingup"].u_lb,
        u_ub=SCENARIOS["swingup"].u_ub)
    DEFAULT_SCENARIO = "swingup"
    DT = CARTPOLE_CONTROL_TIMESTEP * ACTION_REPEAT
    SUBSTEPS = 5 * ACTION_REPEAT
    X_LB = np.array([-2.5, -np.inf, -10.0, -25.0])
    X_UB = np.array([2.5, np.inf, 10.0, 25.0])
    PLAN_X_LB = np.array([CARTPOLE_XML_PARAMS["slider_min"], -np.inf, -10.0, -25.0])
    PLAN_X_UB = np.array([CARTPOLE_XML_PARAMS["slider_max"], np.inf, 10.0, 25.0])

    def _task(self) -> Task:
        return cartpole_task()

    def _initial_state(self) -> np.ndarray:
        return self.np_random.normal(0.0, 0.01, size=4)

    def _make_plant(self, truth: Mapping[str, float]) -> MuJoCoCartPole:
        friction = CARTPOLE_FRICTION if self.scenario == "friction" else None
        return MuJoCoCartPole(self.ACTION_REPEAT, dof_frictionloss=friction)


SYSTEM = register_system(System(
    name="mujoco_cartpole", env_id="gp_envs/MuJoCoCartPole-v0",
    entry_point="gp_envs.dmc:MuJoCoCartPoleEnv", max_episode_steps=200))
"""DMC's cart-pole in MuJoCo as a gp_envs system (:mod:`gp_envs.systems`; needs the
``[mujoco]`` extra to be made)."""
