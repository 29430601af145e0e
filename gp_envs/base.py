"""Machinery shared by the three envs: hidden truth, scenarios, stepping, reward and checks.

A concrete env (one file each: :mod:`gp_envs.cartpole_swingup`, :mod:`gp_envs.quadrotor`,
:mod:`gp_envs.dubins_obstacle`) declares its physics module, scenarios, bounds and task; this base
class turns that into a Gymnasium env whose controller API (observations, ``info``, rewards,
frames, the nominal model ``env.unwrapped.nominal_model``) never hands out the true parameters;
:class:`GPEnv` says precisely what is and is not hidden.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gp_envs.model import ControlModel, Task
from gp_envs.physics.ranges import ParamRange, check_value

RANDOMIZE_RANGE = ParamRange(0.0, 1.0, True, False, "relative spread of the true parameters")
"""Valid values of the ``randomize`` option (dimensionless)."""


def wrap_to_circle(angle: float) -> float:
    """``angle`` (rad) wrapped to ``[0, 2 pi)`` such that its float32 cast stays inside the
    observation space's ``[0, 2 pi]`` (an angle just below 2 pi rounds up: it becomes 0)."""
    wrapped = float(np.mod(angle, 2 * np.pi))
    return 0.0 if wrapped >= np.float32(2 * np.pi) else wrapped


NOISE_STREAM = 0x6F62736E6F697365
"""Second key of the observation-noise generator's seed, ``default_rng([seed, NOISE_STREAM])``:
the noise has its own stream, so the initial states and parameter draws of a seed are the same
with and without noise."""


def checked_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as a float array of exactly ``shape`` (an env step's check).

    Raises:
        ValueError: non-numeric, another shape (not reshaped), or not finite.
    """
    try:
        a = np.asarray(action, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"action must be an array of numbers of shape {shape}, "
                         f"got {action!r}") from None
    if a.shape != shape:
        raise ValueError(f"action must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"action must be finite, got {a}")
    return a


def task_info(task: Task, dt: float, steps: int, held: int, obs: np.ndarray, *,
              violation: str | None, reason: str | None, clipped: bool) -> dict[str, Any]:
    """The ``info`` keys of the task after ``steps`` periods of ``dt`` s, the last ``held`` of
    them ending at the goal: ``success`` once ``held`` covers the task's hold time (at least one
    period), and the observed state's ``at_goal`` and distance (every env of this package and
    :func:`gp_envs.wrap` report these)."""
    success = held >= max(round(task.hold_time / dt), 1)
    since = round((steps - held + 1) * dt, 9) if held else None
    return {
        "success": bool(success),
        "is_success": bool(success),  # the key stable-baselines3's callbacks read
        "at_goal": bool(task.at_goal(obs)),
        # time (s) of the first state of the current unbroken stretch at the goal (None: not
        # at the goal now); with "success" at an episode's end: when the held final stretch
        # began
        "at_goal_since": since,
        "distance_to_goal": task.goal_distance(obs),
        "constraint_violation": violation is not None,
        "violation": violation,
        "termination_reason": reason,
        "action_clipped": clipped,
        "time": steps * dt,
    }


class Plant(Protocol):
    """The truth that steps an env's state: the package's ODE with hidden parameter values (a
    :class:`~gp_envs.model.ControlModel`, the default), or an outside simulator
    (:meth:`GPEnv._make_plant`, e.g. MuJoCo in :class:`gp_envs.dmc.MuJoCoCartPoleEnv`)."""

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The state (n,) one control period after state ``x`` (n,) under control ``u`` (m,)
        held constant."""
        ...


@dataclass(frozen=True)
class ParamChange:
    """A step change of the true parameters during an episode (a time-varying scenario).

    Attributes:
        time: seconds after the reset; the control periods starting at or after it run on the
            changed plant (and :func:`gp_envs.oracle_model` returns it from then on).
        factors: multiplier per parameter name, relative to the episode's *initial* truth (its
            randomized draw included); parameters not named keep their current value.
    """

    time: float
    factors: Mapping[str, float]


@dataclass(frozen=True)
class Scenario:
    """A named pair of true and nominal parameter sets (the paper's tables).

    Attributes:
        description: one line, with the paper's table it comes from.
        true: true parameter values by name: public, as documentation of the experiment, but
            never handed out through the controller API (see :class:`GPEnv`).
        nominal: nominal parameter values by name (what a controller may know).
        u_lb, u_ub: (m,) control bounds for this scenario.
        nominal_spread: per-parameter standard deviation of a per-episode Gaussian draw of the
            nominal value around ``nominal`` (empty: nominal values are fixed).
        nominal_min, nominal_max: clip of drawn nominal values to the parameters' valid range
            (e.g. a loss factor ``b`` to ``[0, 0.9]`` so that ``1 - b`` stays positive).
        changes: step changes of the truth during the episode, in time order (empty: the
            truth is constant); hidden like the rest of the truth.
    """

    description: str
    true: Mapping[str, float]
    nominal: Mapping[str, float]
    u_lb: tuple[float, ...]
    u_ub: tuple[float, ...]
    nominal_spread: Mapping[str, float] = field(default_factory=dict)
    nominal_min: float = -np.inf
    nominal_max: float = np.inf
    changes: tuple[ParamChange, ...] = ()


class GPEnv(gym.Env[np.ndarray, np.ndarray]):
    """Base class of the ``gp_envs`` environments (see a concrete env for the system).

    Subclasses set the class attributes below and implement :meth:`_initial_state` and
    :meth:`_render_frame`; they may override :meth:`_observe` (e.g. to wrap angles) and
    :meth:`_violation` (e.g. obstacle contact).

    What is hidden, precisely. The controller API -- :attr:`nominal_model`, observations,
    ``info``, rewards and rendered frames -- never hands out a true parameter value, and it
    depends on the true values only through the state, whose evolution is the true dynamics
    (that is what a learner learns from): the nominal model is built from the scenario's
    nominal values (or their per-episode draw), rewards and ``info`` from the observed state,
    the nominal task and the action, frames from the state and the nominal model. The truth is
    not secret beyond that: ``SCENARIOS[scenario].true`` is a public class attribute, the
    documentation of the experiment like a paper's table; Gymnasium's ``env.spec.kwargs``
    echoes the caller's ``true_params``; with ``randomize`` an episode's truth can be rebuilt
    from its seed; private attributes hold it. The oracle is explicit:
    :func:`gp_envs.oracle_model`, for upper-bound baselines only.

    Envs pickle and deep-copy, RNG state included (a copy steps and resets like the
    original; see :meth:`__getstate__`).

    Args:
        scenario: name of a scenario in :attr:`SCENARIOS`.
        true_params: overrides of the scenario's true parameter values.
        randomize: relative spread of the true parameters per reset: each one is multiplied
            by ``1 + U(-randomize, randomize)`` (``g`` is never randomized). A real number in
            ``[0, 1)`` (:data:`RANDOMIZE_RANGE`).
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        observation_noise: standard deviation of zero-mean Gaussian noise added to each
            observed state component, in that component's unit (a number for all, or one per
            component; default 0: exact observations). Seeded by ``reset(seed=...)`` on its own
            stream (:data:`NOISE_STREAM`). Only the observation is noisy: the plant, the reward,
            ``info`` and the success criterion use the true state (the task is about the
            system, not the sensor).
        time_varying: False ignores the scenario's changes (its truth stays the episode's
            initial one), e.g. for data collected before a time-varying episode.

    Raises:
        ValueError: an unknown scenario, render mode or parameter name; ``randomize`` not a
            real number in ``[0, 1)`` (bools and strings included); a true parameter (after
            the overrides, and at either end of the ``randomize`` spread) outside its valid
            range in the physics module's ``PARAM_RANGES``, also after each of the scenario's
            changes; ``observation_noise`` negative, not finite or of the wrong length.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "human"], "render_fps": 20}

    physics: ClassVar[Any]
    """Physics module: ``PARAM_NAMES``, ``STATE_NAMES``, ``CONTROL_NAMES``, ``ode``."""
    NAME: ClassVar[str | None] = None
    """The name of the env's models (None: the physics module's short name)."""
    OUTSIDE_PLANT: ClassVar[bool] = False
    """True: the truth is an outside simulator (:meth:`_make_plant`), which has no parameter
    values to draw or override: ``randomize``, ``true_params`` and a scenario's changes raise,
    and :func:`gp_envs.oracle_model` has no true model to give."""
    SCENARIOS: ClassVar[dict[str, Scenario]]
    DEFAULT_SCENARIO: ClassVar[str]
    DT: ClassVar[float]
    """Control period, seconds."""
    SUBSTEPS: ClassVar[int]
    """RK4 substeps per control period."""
    X_LB: ClassVar[np.ndarray]
    X_UB: ClassVar[np.ndarray]
    """State box; leaving it terminates the episode (with the penalty of :meth:`_penalty`)."""
    PLAN_X_LB: ClassVar[np.ndarray | None] = None
    PLAN_X_UB: ClassVar[np.ndarray | None] = None
    """The models' planning box (``x_lb``/``x_ub`` of :attr:`nominal_model`), if it is not the
    termination box (None: :attr:`X_LB`/:attr:`X_UB`)."""
    ANGLE_INDICES: ClassVar[tuple[int, ...]] = ()
    DYNAMIC_INDICES: ClassVar[tuple[int, ...]]
    """State components driven by forces (see :class:`ControlModel`)."""

    def __init__(self, scenario: str | None = None, true_params: Mapping[str, float] | None = None,
                 randomize: float = 0.0, render_mode: str | None = None,
                 observation_noise: float | Sequence[float] = 0.0,
                 time_varying: bool = True) -> None:
        scenario = self.DEFAULT_SCENARIO if scenario is None else scenario
        if scenario not in self.SCENARIOS:
            raise ValueError(f"{type(self).__name__}: unknown scenario {scenario!r}; "
                             f"choose one of {sorted(self.SCENARIOS)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        self.randomize = check_value(type(self).__name__, "randomize", randomize,
                                     RANDOMIZE_RANGE)
        self.scenario = scenario
        self.render_mode = render_mode
        spec = self.SCENARIOS[scenario]
        truth = dict(spec.true)
        if true_params:
            unknown = set(true_params) - set(self.physics.PARAM_NAMES)
            if unknown:
                raise ValueError(f"{type(self).__name__}: unknown parameter(s) {sorted(unknown)}; "
                                 f"known: {list(self.physics.PARAM_NAMES)}")
            truth.update(true_params)
        if not time_varying:
            spec = dataclasses.replace(spec, changes=())
        self._spec = spec
        if self.OUTSIDE_PLANT:
            asked = [name for name, given in (("randomize", self.randomize > 0),
                                              ("true_params", bool(true_params)),
                                              ("the scenario's changes", bool(spec.changes)))
                     if given]
            if asked:
                raise ValueError(f"{type(self).__name__}: its truth is an outside simulator, "
                                 f"whose parameters are its own: {', '.join(asked)} cannot "
                                 f"apply to it")
            self._plant: Plant = self._make_plant({})
            self._base_truth: dict[str, float] = {}
        else:
            self._plant = self._make_plant(truth)  # checks the true parameters' ranges
            self._base_truth = dict(self._make_model(truth).params)
            self._check_changes()
            self._check_randomized_range()
        self.observation_noise = self._check_noise(observation_noise)
        self._noise_rng: np.random.Generator | None = None
        self._episode_truth = dict(self._base_truth)
        self._system_drawn = False  # whether a reset has drawn the episode's system
        self._next_change = 0
        self.nominal_model: ControlModel = self._make_model(dict(spec.nominal))
        """What a controller may know: nominal parameters, dynamics, bounds, task."""

        task = self.nominal_model.task
        self.action_space = spaces.Box(np.asarray(spec.u_lb, np.float32),
                                       np.asarray(spec.u_ub, np.float32), dtype=np.float32)
        self.observation_space = self._observation_space()
        self._max_steps = round(task.duration / self.DT)
        self._cost_bound = self._stage_cost_bound()
        self._state = np.zeros(len(self.physics.STATE_NAMES))
        self._steps = 0
        self._held = 0
        self._fig: Any = None

    # ----------------------------------------------------------------- to be provided
    def _task(self) -> Task:
        raise NotImplementedError

    def _initial_state(self) -> np.ndarray:
        raise NotImplementedError

    def _render_frame(self, ax: Any) -> None:
        raise NotImplementedError

    def _observe(self, state: np.ndarray) -> np.ndarray:
        """Observation (= full state, possibly with angles wrapped) of a true state."""
        return state.copy()

    def _violation(self, state: np.ndarray) -> str | None:
        """A constraint violated by ``state`` other than leaving the state box, or None."""
        return None

    def _observation_space(self) -> spaces.Box:
        n = len(self.physics.STATE_NAMES)
        return spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)

    # ----------------------------------------------------------------- models
    @classmethod
    def model_name(cls) -> str:
        """The name of this env's nominal and true models (:attr:`NAME`, or the physics
        module's short name): the system's name."""
        return cls.NAME or cls.physics.__name__.rsplit(".", 1)[-1]

    def _make_model(self, params: Mapping[str, float]) -> ControlModel:
        return ControlModel(
            name=self.model_name(), ode=self.physics.ode,
            param_names=tuple(self.physics.PARAM_NAMES), params=dict(params),
            state_names=tuple(self.physics.STATE_NAMES),
            control_names=tuple(self.physics.CONTROL_NAMES), dt=self.DT,
            x_lb=np.asarray(self.X_LB if self.PLAN_X_LB is None else self.PLAN_X_LB, float),
            x_ub=np.asarray(self.X_UB if self.PLAN_X_UB is None else self.PLAN_X_UB, float),
            u_lb=np.asarray(self._spec.u_lb, float), u_ub=np.asarray(self._spec.u_ub, float),
            task=self._task(), substeps=self.SUBSTEPS, angle_indices=self.ANGLE_INDICES,
            dynamic_indices=self.DYNAMIC_INDICES, param_ranges=self.physics.PARAM_RANGES,
        )

    def _make_plant(self, truth: Mapping[str, float]) -> Plant:
        """The truth that steps the state for parameter values ``truth``: the package's ODE
        (the true :class:`~gp_envs.model.ControlModel`). An env whose truth is an outside
        simulator sets :attr:`OUTSIDE_PLANT` and returns its simulator (``truth`` is then
        empty); it is made once, at construction."""
        return self._make_model(truth)

    def _oracle(self) -> ControlModel:
        """The true model of the current episode; only :func:`gp_envs.oracle_model` uses it.

        Raises:
            ValueError: the truth is an outside simulator (:attr:`OUTSIDE_PLANT`).
        """
        if self.OUTSIDE_PLANT or not isinstance(self._plant, ControlModel):
            raise ValueError(f"{type(self).__name__}: the truth is an outside simulator, not a "
                             f"model: there is no true model for an oracle")
        return self._plant

    def _check_noise(self, noise: float | Sequence[float]) -> np.ndarray:
        n = len(self.physics.STATE_NAMES)
        try:
            raw = np.asarray(noise)
            if raw.dtype.kind not in "iuf":  # no strings, bools or objects
                raise TypeError
            sd = np.broadcast_to(raw.astype(float), (n,)).copy()
        except (TypeError, ValueError):
            raise ValueError(f"{type(self).__name__}: observation_noise must be a number or "
                             f"{n} numbers (standard deviations per observed component), got "
                             f"{noise!r}") from None
        if not np.all(np.isfinite(sd)) or np.any(sd < 0):
            raise ValueError(f"{type(self).__name__}: observation_noise must be finite and "
                             f">= 0, got {noise!r}")
        return sd

    def _changed(self, truth: Mapping[str, float], upto: int) -> dict[str, float]:
        """``truth`` after the scenario's first ``upto`` changes."""
        out = dict(truth)
        for change in self._spec.changes[:upto]:
            out.update({k: truth[k] * f for k, f in change.factors.items()})
        return out

    def _check_changes(self) -> None:
        """The changes name known parameters, happen in order inside the episode, and every
        truth they produce (at both ends of a ``randomize`` spread too) is physical."""
        name = type(self).__name__
        duration = self._task().duration
        times = [c.time for c in self._spec.changes]
        if times != sorted(times) or any(not 0 < t < duration for t in times):
            raise ValueError(f"{name}: scenario changes must be in time order within "
                             f"(0, {duration}) s, got times {times}")
        for change in self._spec.changes:
            unknown = set(change.factors) - set(self.physics.PARAM_NAMES)
            if unknown:
                raise ValueError(f"{name}: a scenario change names unknown parameter(s) "
                                 f"{sorted(unknown)}")
        for k in range(1, len(self._spec.changes) + 1):
            try:
                self._make_model(self._changed(self._base_truth, k))
            except ValueError as err:
                raise ValueError(f"{name}: after the scenario's change at "
                                 f"{times[k - 1]} s, {err}") from None

    def _check_randomized_range(self) -> None:
        """Fail at construction, not at some later reset, if a randomized draw could leave a
        parameter's valid range: models at both ends of the spread go through the check."""
        if self.randomize == 0:
            return
        for sign in (-1.0, 1.0):
            end = {k: v if k == "g" else v * (1.0 + sign * self.randomize)
                   for k, v in self._base_truth.items()}
            try:
                for k in range(len(self._spec.changes) + 1):
                    self._make_model(self._changed(end, k))
            except ValueError as err:
                raise ValueError(f"{type(self).__name__}: randomize={self.randomize} draws each "
                                 f"true parameter v in [v (1 - randomize), v (1 + randomize)); "
                                 f"at an end of that spread, {err}") from None

    def _draw_episode_models(self) -> None:
        rng = self.np_random
        truth = dict(self._base_truth)
        if self.randomize > 0:
            for k in truth:
                if k != "g":
                    truth[k] *= 1.0 + rng.uniform(-self.randomize, self.randomize)
        if not self.OUTSIDE_PLANT:
            self._plant = self._make_plant(truth)
        self._episode_truth, self._next_change = truth, 0
        if self._spec.nominal_spread:
            nominal = dict(self._spec.nominal)
            for k, sd in self._spec.nominal_spread.items():
                nominal[k] = float(np.clip(rng.normal(nominal[k], sd), self._spec.nominal_min,
                                           self._spec.nominal_max))
            self.nominal_model = self._make_model(nominal)

    def _apply_changes(self, time: float) -> None:
        """Switch the plant to the truth after every change due by ``time`` (seconds)."""
        changes = self._spec.changes
        k = self._next_change
        while k < len(changes) and changes[k].time <= time + 1e-9:
            k += 1
        if k != self._next_change:
            self._next_change = k
            self._plant = self._make_plant(self._changed(self._episode_truth, k))

    def _observed(self, state: np.ndarray) -> np.ndarray:
        """The observation the agent gets of ``state``: :meth:`_observe` of the state plus the
        sensor noise (none by default)."""
        if self._noise_rng is None or not np.any(self.observation_noise):
            return self._observe(state)
        return self._observe(state + self.observation_noise * self._noise_rng.normal(
            size=state.shape))

    # ----------------------------------------------------------------- cost and penalty
    def _stage_cost_bound(self) -> float:
        """Upper bound of the stage cost over the state box and the action box (per second).

        Used for the termination penalty: leaving the box costs ``remaining_time * bound``, more
        than staying in it could ever cost, so ending an episode early never pays.
        """
        task = self.nominal_model.task
        lb = self._observation_bounds_for_cost()[0] - task.goal
        ub = self._observation_bounds_for_cost()[1] - task.goal
        emax = np.maximum(np.abs(lb), np.abs(ub))
        weighted = np.abs(task.Q) @ np.where(np.isfinite(emax), emax, 0.0)
        if np.any(~np.isfinite(emax) & (np.diag(task.Q) > 0)):
            raise ValueError("state cost weight on a component without a finite bound")
        du = np.maximum(np.abs(self.action_space.low - task.u_ref),
                        np.abs(self.action_space.high - task.u_ref))
        return float(np.where(np.isfinite(emax), emax, 0.0) @ weighted
                     + du @ np.abs(task.R) @ du)

    def _observation_bounds_for_cost(self) -> tuple[np.ndarray, np.ndarray]:
        lb = np.asarray(self.X_LB, float).copy()
        ub = np.asarray(self.X_UB, float).copy()
        low, high = self.observation_space.low, self.observation_space.high
        # angles wrapped in the observation have the observation space's bounds
        for i in range(len(lb)):
            if np.isfinite(low[i]):
                lb[i], ub[i] = max(lb[i], low[i]), min(ub[i], high[i])
        return lb, ub

    # ----------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode.

        Args:
            seed: seeds the env's RNG (initial-state noise, parameter draws).
            options: ``{"state": array (n,)}`` starts from that state (physical units);
                ``{"keep_system": True}`` keeps the previous episode's system (its randomized
                truth and nominal model, from before any of the scenario's changes) instead of
                drawing a new one: more episodes on the same system, e.g. to collect data on it.
        """
        options = options or {}
        unknown = set(options) - {"state", "keep_system"}
        if unknown:
            raise ValueError(f"unknown reset option(s) {sorted(unknown)}; known: "
                             f"['keep_system', 'state']")
        keep = bool(options.get("keep_system", False))
        if keep and not self._system_drawn:
            raise ValueError("reset(options={'keep_system': True}) needs an earlier reset that "
                             "drew the system")
        super().reset(seed=seed)
        if seed is not None:
            self._noise_rng = np.random.default_rng([seed, NOISE_STREAM])
        elif self._noise_rng is None:
            self._noise_rng = np.random.default_rng()
        if keep:
            if not self.OUTSIDE_PLANT:
                self._plant = self._make_plant(self._episode_truth)
            self._next_change = 0
        else:
            self._draw_episode_models()
        self._system_drawn = True
        if "state" in options:
            state = np.asarray(options["state"], dtype=float)
            if state.shape != (len(self.physics.STATE_NAMES),):
                raise ValueError(f"options['state'] must have shape "
                                 f"({len(self.physics.STATE_NAMES)},), got {state.shape}")
            if not np.all(np.isfinite(state)):
                raise ValueError(f"options['state'] must be finite, got {state}")
        else:
            state = self._initial_state()
        self._state = state
        self._steps = 0
        self._held = 0
        obs = self._observe(self._state)
        info = self._info(obs, violation=None, reason=None, clipped=False)
        if self.render_mode == "human":
            self.render()
        return self._observed(self._state).astype(np.float32), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Advance one control period with the action held constant (zero-order hold).

        Args:
            action: (m,) controls in the action space's units; exactly that shape (a scalar,
                an (m, 1) or a (1, m) array is an error, not reshaped).

        The action is clipped to the action space (``info["action_clipped"]`` says so); a NaN,
        infinite, non-numeric or wrong-shaped action raises ``ValueError``.
        """
        a = checked_action(action, self.action_space.shape)
        u = np.clip(a, self.action_space.low, self.action_space.high)
        clipped = bool(np.any(u != a))

        obs_before = self._observe(self._state)
        reward = -self.DT * float(self.nominal_model.task.stage_cost(obs_before, u))
        self._state = np.asarray(self._plant.step(self._state, u), dtype=float)
        self._steps += 1
        self._apply_changes(self._steps * self.DT)

        reason: str | None = None
        violation: str | None = None
        if not np.all(np.isfinite(self._state)):
            reason = "diverged: the simulated state is not finite"
            self._state = np.where(np.isfinite(self._state), self._state, 0.0)
        else:
            outside = np.flatnonzero((self._state < self.X_LB) | (self._state > self.X_UB))
            if outside.size:
                names = [self.physics.STATE_NAMES[i] for i in outside]
                reason = f"left the state box: {', '.join(names)}"
            violation = self._violation(self._state)
            if violation is not None:
                reason = violation
        terminated = reason is not None
        if terminated:
            remaining = max(self._max_steps - self._steps, 0) + 1
            reward -= remaining * self.DT * self._cost_bound
        obs = self._observe(self._state)
        if self.nominal_model.task.at_goal(obs) and not terminated:
            self._held += 1
        else:
            self._held = 0
        info = self._info(obs, violation=violation or (reason if terminated else None),
                          reason=reason, clipped=clipped)
        if self.render_mode == "human":
            self.render()
        return (self._observed(self._state).astype(np.float32), float(reward), bool(terminated),
                False, info)

    def _info(self, obs: np.ndarray, violation: str | None, reason: str | None, clipped: bool
              ) -> dict[str, Any]:
        return task_info(self.nominal_model.task, self.DT, self._steps, self._held, obs,
                         violation=violation, reason=reason, clipped=clipped)

    # ----------------------------------------------------------------- pickling
    def __getstate__(self) -> dict[str, Any]:
        """Pickled (and deep-copied) state: everything but the render figure.

        The copy has the same state, step counters, true and nominal models and RNG state
        (so its next ``reset()`` draws the same parameters); its figure is created anew by its
        first :meth:`render` (a matplotlib figure, or a window, is not part of the env).
        """
        state = self.__dict__.copy()
        state["_fig"] = None
        return state

    # ----------------------------------------------------------------- rendering
    def render(self) -> np.ndarray | None:
        """Draw the system; returns an (H, W, 3) uint8 frame for ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to make()")
            return None
        if self._fig is None:
            if self.render_mode == "human":
                import matplotlib.pyplot as plt

                self._fig = plt.figure(figsize=(5, 4), dpi=80)
            else:  # off-screen: a bare Agg canvas, no pyplot state, no display needed
                from matplotlib.backends.backend_agg import FigureCanvasAgg
                from matplotlib.figure import Figure

                self._fig = Figure(figsize=(5, 4), dpi=80)
                FigureCanvasAgg(self._fig)
        self._fig.clear()
        ax = self._fig.add_subplot(111)
        self._render_frame(ax)
        ax.set_title(f"{type(self).__name__}  t = {self._steps * self.DT:.2f} s", fontsize=9)
        if self.render_mode == "human":
            import matplotlib.pyplot as plt

            plt.pause(1.0 / self.metadata["render_fps"])
            return None
        canvas = self._fig.canvas
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        if self._fig is not None and self.render_mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
