"""Model-free RL baseline (stable-baselines3) behind the same ``act(obs)`` interface as the MPC.

An :class:`RLAgent` is a frozen SB3 policy (SAC, PPO, or sb3-contrib's TQC) plus the
preprocessing it was trained with, so it runs in the plain Gymnasium loop on the registered env
exactly as ``gym.make`` returns it::

    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    agent = RLAgent.load("benchmarks/models/cartpole/sac", env)  # a saved agent's directory
    obs, _ = env.reset(seed=0)
    while True:
        a = agent.act(obs)
        nobs, r, te, tr, info = env.step(a)
        agent.observe(obs, a, nobs)
        obs = nobs
        if te or tr:
            break

Preprocessing (part of the agent, never of the env; standard Gymnasium wrappers for training):

1. :class:`AngleFeatures` replaces every angle ``obs[i]``, ``i`` in
   ``gp_envs.nominal_model(env).angle_indices``, by ``(cos, sin)`` appended at the end: the
   network sees a continuous feature where the env wraps the angle.
2. SB3 ``VecNormalize`` running mean/std normalization of those features (statistics frozen
   after training, saved as a pickle).
3. :class:`NormalizedAction`: the policy acts in ``[-1, 1]^m``; the wrapper maps affinely onto the
   env's action box ``[low, high]``.
4. Optionally :class:`TimeFeature` (between 1 and 2): the fraction of the episode still to go,
   ``1 - t / T`` (``t`` steps since reset, ``T`` the time limit in steps), appended to the
   features. The agent counts its own ``act`` calls since :meth:`RLAgent.reset` for it, so it
   still acts on the plain env.

Training-only reward wrappers (recorded in the model's metadata under ``training_wrappers``; the
saved agent never sees a reward, and every evaluation runs on the plain registered env):

- :class:`BoundedShiftReward`: the task's reward without its time-dependent termination penalty,
  shifted by ``dt * bound`` on every step that does not terminate. Every trajectory's return
  changes by the same constant ``T * dt * bound``, so it ranks policies exactly as the task does
  (see the class docstring for the derivation from :mod:`gp_envs.base`).
- :class:`GoalBonusReward`: a declared shaping term, ``bonus * dt`` on every step that ends inside
  the goal tolerance (``info["at_goal"]``). This one does change the task.

A saved agent is a directory::

    model.zip          SB3 model (policy weights; no replay buffer)
    vecnormalize.pkl   VecNormalize statistics (only if observation normalization was used)
    metadata.json      algorithm, env id, scenario, spaces, preprocessing, training wrappers,
                       hyperparameters, seed, training steps, wall-clock training time,
                       library versions

A benchmark's outside env (a :func:`gp_envs.wrap`-ped simulator such as DeepMind Control's
cart-pole, which has no Gymnasium id) is recorded by its benchmark name and scenario (``env_id``
is the name) plus :func:`env_fingerprint` (simulator configuration, nominal model), which
:meth:`RLAgent.load` compares: the same benchmark env and scenario load, any other fails with
the differences listed. Its training reward is its own (no training reward wrappers).

An agent loads from its directory; a relative name is also looked up in the model directories
(``<env>/<algo>/`` folders) given as ``search``. This library knows no model directory of its
own (it never imports the benchmark): the policies shipped with the package are package data of
``benchmarks`` (``benchmarks/models/<env>/<algo>/``), so from any directory, also from a
non-editable install, ``RLAgent.load("cartpole/sac", env,
search=[benchmarks.controllers.MODELS_DIR])`` loads the installed copy, and
``saved_models(MODELS_DIR)`` lists them.

stable-baselines3 and torch are imported at the top of this module; the core package does not
import it eagerly, so ``gp_envs``/``gp_agents`` work without the RL extra.
"""

from __future__ import annotations

import copy
import json
import pickle
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import stable_baselines3
import torch
from gymnasium import spaces
from sb3_contrib import TQC
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

__all__ = ["ALGORITHMS", "AngleFeatures", "BoundedShiftReward", "GoalBonusReward",
           "NormalizedAction", "RLAgent", "TimeFeature", "env_fingerprint", "episode_limit",
           "get_env_state", "make_training_vec_env", "resolve_model_dir",
           "saved_models", "set_env_state", "termination_terms", "wrap_env"]

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"sac": SAC, "ppo": PPO, "tqc": TQC}
"""Supported algorithms by lower-case name (TQC from sb3-contrib)."""

MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
METADATA_FILE = "metadata.json"


# --------------------------------------------------------------------------- wrappers
def angle_features(obs: np.ndarray, angle_indices: Sequence[int]) -> np.ndarray:
    """Replace angles by their cosine and sine.

    Args:
        obs: (..., n) observations; ``obs[..., i]`` in radians for ``i`` in ``angle_indices``.
        angle_indices: indices of the angle components.

    Returns:
        (..., n + len(angle_indices)) float32: the non-angle components in their original order,
        then ``cos`` of each angle, then ``sin`` of each angle.
    """
    obs = np.asarray(obs, dtype=np.float64)
    idx = list(angle_indices)
    if not idx:
        return obs.astype(np.float32)
    keep = [i for i in range(obs.shape[-1]) if i not in set(idx)]
    ang = obs[..., idx]
    return np.concatenate([obs[..., keep], np.cos(ang), np.sin(ang)], axis=-1).astype(np.float32)


class AngleFeatures(gym.ObservationWrapper):
    """Observation wrapper: angles -> ``(cos, sin)`` features (see :func:`angle_features`).

    Args:
        env: an env with a ``Box(n,)`` observation space.
        angle_indices: indices of the angle components (e.g.
            ``env.unwrapped.nominal_model.angle_indices``).
    """

    def __init__(self, env: gym.Env, angle_indices: Sequence[int]) -> None:
        super().__init__(env)
        box = env.observation_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"AngleFeatures needs a 1-D Box observation space, got {box}")
        n = box.shape[0]
        self.angle_indices = tuple(int(i) for i in angle_indices)
        if any(not 0 <= i < n for i in self.angle_indices) or len(set(self.angle_indices)) != len(
                self.angle_indices):
            raise ValueError(f"angle indices {self.angle_indices} invalid for {n} observations")
        keep = [i for i in range(n) if i not in set(self.angle_indices)]
        k = len(self.angle_indices)
        low = np.concatenate([box.low[keep], -np.ones(2 * k)]).astype(np.float32)
        high = np.concatenate([box.high[keep], np.ones(2 * k)]).astype(np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        """(n,) raw observation -> (n + k,) features."""
        return angle_features(observation, self.angle_indices)


class NormalizedAction(gym.ActionWrapper):
    """Action wrapper: the agent acts in ``[-1, 1]^m``, the env receives ``[low, high]``.

    ``u = low + (a + 1) / 2 * (high - low)`` after clipping ``a`` to ``[-1, 1]``;
    :meth:`reverse_action` is the inverse map. Needs a bounded ``Box`` action space.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        box = env.action_space
        if not isinstance(box, spaces.Box) or not np.all(np.isfinite(box.low)) or not np.all(
                np.isfinite(box.high)):
            raise ValueError(f"NormalizedAction needs a bounded Box action space, got {box}")
        self.low = box.low.astype(np.float64)
        self.high = box.high.astype(np.float64)
        self.action_space = spaces.Box(-1.0, 1.0, shape=box.shape, dtype=np.float32)

    def action(self, action: np.ndarray) -> np.ndarray:
        """(m,) action in ``[-1, 1]`` -> (m,) float32 action in ``[low, high]`` (env units)."""
        return scale_action(action, self.low, self.high)

    def reverse_action(self, action: np.ndarray) -> np.ndarray:
        """(m,) action in env units -> (m,) float32 action in ``[-1, 1]``."""
        a = np.asarray(action, dtype=np.float64)
        return np.clip(2.0 * (a - self.low) / (self.high - self.low) - 1.0, -1.0, 1.0).astype(
            np.float32)


def scale_action(action: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Map ``[-1, 1]^m`` (clipped) affinely onto ``[low, high]``; float32, clipped to the box."""
    a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
    u = low + 0.5 * (a + 1.0) * (high - low)
    return np.clip(u.astype(np.float32), low.astype(np.float32), high.astype(np.float32))


def time_feature(steps: int, max_steps: int) -> float:
    """``1 - steps / max_steps``: the fraction of the episode still to go (1 at reset, 0 at the
    time limit); ``steps`` env steps since reset, ``max_steps`` the time limit in steps."""
    return 1.0 - float(steps) / float(max_steps)


class TimeFeature(gym.Wrapper):
    """Observation wrapper: append :func:`time_feature` of the steps since reset.

    The same feature as sb3-contrib's ``TimeFeatureWrapper`` (rl-baselines3-zoo's TQC entries for
    the Bullet swing-up and locomotion tasks), written here so the agent can rebuild it from its
    own step count at evaluation time without the wrapper.

    Args:
        env: an env with a 1-D ``Box`` observation space and a time limit.
        max_steps: the time limit in steps (default: ``env.spec.max_episode_steps``).
    """

    def __init__(self, env: gym.Env, max_steps: int | None = None) -> None:
        super().__init__(env)
        if max_steps is None:
            spec = env.spec
            max_steps = spec.max_episode_steps if spec is not None else None
        if not max_steps or max_steps <= 0:
            raise ValueError("TimeFeature needs a positive max_steps (or an env with a time limit)")
        self.max_steps = int(max_steps)
        box = env.observation_space
        if not isinstance(box, spaces.Box) or len(box.shape) != 1:
            raise ValueError(f"TimeFeature needs a 1-D Box observation space, got {box}")
        self.observation_space = spaces.Box(np.append(box.low, 0.0).astype(np.float32),
                                            np.append(box.high, 1.0).astype(np.float32),
                                            dtype=np.float32)
        self._t = 0

    def _with_time(self, obs: np.ndarray) -> np.ndarray:
        return np.append(np.asarray(obs, np.float32),
                         np.float32(time_feature(self._t, self.max_steps)))

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset the env and the step count."""
        obs, info = self.env.reset(**kwargs)
        self._t = 0
        return self._with_time(obs), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step the env; the returned observation carries the feature after this step."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._t += 1
        return self._with_time(obs), reward, terminated, truncated, info


def episode_limit(env: gym.Env) -> int:
    """The time limit of ``env`` in steps: its spec's ``max_episode_steps`` (a ``gym.make``-made
    env), else, for an env without one (e.g. a :func:`gp_envs.wrap`-ped DeepMind Control env,
    whose own time limit truncates it), the nominal model's task duration over its ``dt``.

    Raises:
        ValueError: neither is known.
    """
    spec = env.spec
    if spec is not None and spec.max_episode_steps:
        return int(spec.max_episode_steps)
    import gp_envs

    try:
        model = gp_envs.nominal_model(env)
    except TypeError:
        model = None
    if model is None or not np.isfinite(model.task.duration) or model.task.duration <= 0:
        raise ValueError(f"{type(env.unwrapped).__name__} has no known time limit (no spec "
                         f"max_episode_steps, no nominal model with a task duration)")
    return max(round(model.task.duration / model.dt), 1)


_SIMULATOR_ATTRS = ("domain", "task", "action_repeat", "dof_frictionloss")
"""Attributes of an outside simulator (:class:`gp_envs.dmc.DMCEnv`'s) recorded in
:func:`env_fingerprint` when present: they tell its configurations apart."""


def _jsonable(x: Any) -> Any:
    """``x`` as plain JSON data (slices as ``[start, stop]``, arrays as lists)."""
    if isinstance(x, slice):
        return [x.start, x.stop]
    if isinstance(x, Mapping):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    if x is None or isinstance(x, bool | int | float | str):
        return x
    return repr(x)


def env_fingerprint(env: gym.Env) -> dict[str, Any]:
    """What identifies an env that is not a registered ``gp_envs`` system (a benchmark's
    outside env, :func:`gp_envs.wrap`-ped): the simulator (class, Gymnasium id and kwargs if
    it has a spec, its configuration attributes :data:`_SIMULATOR_ATTRS`) and the nominal
    model (name, ``dt``, parameters, control bounds), as JSON data. Two envs made by the same
    benchmark env and scenario have equal fingerprints; scenarios that differ in the simulator
    (DMC's action repeat, friction) or in the model (a nominal parameter value) differ.

    Raises:
        TypeError: ``env`` has no nominal model.
    """
    import gp_envs

    model = gp_envs.nominal_model(env)
    base = env.unwrapped
    spec = base.spec
    simulator: dict[str, Any] = {"class": f"{type(base).__module__}.{type(base).__qualname__}",
                                 "id": spec.id if spec is not None else None,
                                 "kwargs": _jsonable(dict(spec.kwargs)) if spec else None}
    for attr in _SIMULATOR_ATTRS:
        if attr in vars(base):
            simulator[attr] = _jsonable(dict(vars(base)[attr]) if attr == "dof_frictionloss"
                                        else vars(base)[attr])
    return _jsonable({"simulator": simulator,
                      "model": {"name": model.name, "dt": float(model.dt),
                                "params": dict(model.params), "u_lb": model.u_lb,
                                "u_ub": model.u_ub}})


def termination_terms(env: gym.Env) -> tuple[float, int, float]:
    """``(dt, T, bound)`` of a ``gp_envs`` env's termination penalty.

    :meth:`gp_envs.base.GPEnv.step` gives reward ``-dt * l(x_k, u_k)`` per step and, on the
    step ``k`` (1-based) that terminates, subtracts ``(T - k + 1) * dt * bound`` (``T`` the
    episode's steps, ``bound`` the upper bound of the stage cost ``l`` per second over the state
    and action boxes). These are read from the env (``dt`` in s, ``bound`` per s).

    Raises:
        TypeError: not a ``gp_envs`` env.
    """
    base = env.unwrapped
    if not all(hasattr(base, a) for a in ("DT", "_max_steps", "_cost_bound", "_steps")):
        raise TypeError(f"{type(base).__name__} is not a gp_envs env (no termination penalty)")
    return float(base.DT), int(base._max_steps), float(base._cost_bound)


class BoundedShiftReward(gym.Wrapper):
    """Training reward: the task's reward with the termination penalty replaced by a bounded shift.

    Reward on a step that does not terminate: ``r + dt * bound``; on the step that terminates:
    ``r + (T - k + 1) * dt * bound``, i.e. the penalty of :meth:`gp_envs.base.GPEnv.step` is
    removed and the step gets no shift (``dt, T, bound`` from :func:`termination_terms`).

    Why this ranks policies exactly as the task does: for a trajectory that terminates at step
    ``k`` the task's return is ``C_k - (T - k + 1) dt bound`` (``C_k`` the summed ``-dt l``), the
    shifted one ``C_k + (k - 1) dt bound``; for one that runs to the time limit they are ``C_T``
    and ``C_T + T dt bound``. Both differ by the same constant ``T * dt * bound``
    (:attr:`return_offset`). Shifting every step including the terminating one (``r + dt
    bound`` everywhere, no penalty) would not be exact: terminated trajectories would gain one
    extra ``dt * bound`` (the ``+ 1`` in the env's remaining-step count). Per-step rewards lie in
    ``[0, dt * bound]`` (``l <= bound`` inside the boxes) and ``-dt * bound <= r <= 0`` on the
    terminating step, instead of a penalty of up to ``(T + 1) dt bound`` that depends on the time
    left, which the policy does not observe.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.dt, self.max_steps, self.bound = termination_terms(env)
        self.return_offset = self.max_steps * self.dt * self.bound
        """Shifted return minus the task's return, for every trajectory (reward units)."""

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step; the reward is the shifted one (see the class docstring)."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if terminated:
            k = self.env.unwrapped._steps
            reward = float(reward) + (max(self.max_steps - k, 0) + 1) * self.dt * self.bound
        else:
            reward = float(reward) + self.dt * self.bound
        return obs, reward, terminated, truncated, info


class GoalBonusReward(gym.Wrapper):
    """Declared shaping toward the success region: ``+ bonus * dt`` on every step whose resulting
    observation is inside the goal tolerance (``info["at_goal"]``).

    Args:
        env: a ``gp_envs`` env (its info carries ``at_goal``).
        bonus: reward per second spent inside the tolerance (reward units per s, > 0).
    """

    def __init__(self, env: gym.Env, bonus: float) -> None:
        super().__init__(env)
        if not (np.isfinite(bonus) and bonus > 0):
            raise ValueError(f"bonus must be positive and finite, got {bonus}")
        self.bonus = float(bonus)
        self.dt = float(env.unwrapped.DT)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Step; adds ``bonus * dt`` when ``info["at_goal"]``."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        if info.get("at_goal", False):
            reward = float(reward) + self.bonus * self.dt
        return obs, reward, terminated, truncated, info


def wrap_env(env: gym.Env, angle_indices: Sequence[int], time_limit: int | None = None
             ) -> gym.Env:
    """The agent's per-env preprocessing: :class:`AngleFeatures`, then :class:`TimeFeature` if
    ``time_limit`` (steps) is given, then :class:`NormalizedAction`."""
    env = AngleFeatures(env, angle_indices)
    if time_limit is not None:
        env = TimeFeature(env, time_limit)
    return NormalizedAction(env)


def training_wrappers_record(env: gym.Env, reward_shift: bool, goal_bonus: float,
                             time_feature_on: bool) -> list[dict[str, Any]]:
    """The metadata record of the training-only wrappers (and the time feature) on ``env``."""
    rec: list[dict[str, Any]] = []
    if reward_shift:
        dt, t_max, bound = termination_terms(env)
        rec.append({"name": "BoundedShiftReward", "dt_s": dt, "episode_steps": t_max,
                    "stage_cost_bound_per_s": bound, "shift_per_step": dt * bound,
                    "return_offset": t_max * dt * bound,
                    "what": "r + dt*bound on non-terminating steps, termination penalty removed "
                            "(terminating step unshifted); return = task return + offset for "
                            "every trajectory"})
    if goal_bonus:
        rec.append({"name": "GoalBonusReward", "bonus_per_s": float(goal_bonus),
                    "what": "+ bonus*dt on steps ending inside the goal tolerance "
                            "(info['at_goal']); changes the task"})
    if time_feature_on:
        rec.append({"name": "TimeFeature", "max_steps": episode_limit(env),
                    "what": "observation + [1 - t/T]; the agent rebuilds it from its act count"})
    return rec


def make_training_vec_env(env_id: str, scenario: str, seed: int, n_envs: int = 1,
                          norm_obs: bool = True, norm_reward: bool = False, gamma: float = 0.99,
                          reward_shift: bool = False, goal_bonus: float = 0.0,
                          time_feature_on: bool = False,
                          make_env: Callable[[], gym.Env] | None = None) -> VecNormalize:
    """Vectorized training env: ``gym.make`` (or ``make_env()``) -> training reward wrappers ->
    :func:`wrap_env` -> Monitor -> VecNormalize.

    Args:
        env_id: registered id, e.g. ``"gp_envs/CartPoleSwingUp-v0"`` (only a label when
            ``make_env`` is given).
        scenario: the env's scenario name (only a label when ``make_env`` is given).
        seed: seeds the sub-envs' first resets (``seed + i`` for sub-env ``i``).
        n_envs: number of sub-envs (``DummyVecEnv``, one process).
        norm_obs, norm_reward: VecNormalize options (reward normalization is training-only).
        gamma: discount used by VecNormalize's return estimate for reward normalization.
        reward_shift: apply :class:`BoundedShiftReward`.
        goal_bonus: if > 0, apply :class:`GoalBonusReward` with this bonus per second.
        time_feature_on: append :class:`TimeFeature` to the observation features.
        make_env: makes each sub-env instead of ``gym.make(env_id, scenario=scenario)``: an
            env that is not a registered ``gp_envs`` system but has a nominal model (a
            benchmark's outside env, :func:`gp_envs.wrap`-ped); its reward is its own, so
            ``reward_shift`` and ``goal_bonus`` are refused for it.

    Raises:
        ValueError: ``reward_shift`` or ``goal_bonus`` with ``make_env``.
    """
    import gp_envs  # registers the envs (and gives outside envs' nominal models)

    if make_env is not None:
        if reward_shift or goal_bonus:
            raise ValueError(f"{env_id} ({scenario}) is not a gp_envs system: its reward is "
                             f"the simulator's own, with no termination penalty to replace "
                             f"and no goal bonus; train it with the task reward")

        def outside_factory() -> gym.Env:
            env = make_env()
            angles = gp_envs.nominal_model(env).angle_indices
            limit = episode_limit(env) if time_feature_on else None
            return Monitor(wrap_env(env, angles, limit))

        venv = DummyVecEnv([outside_factory] * n_envs)
        venv.seed(seed)
        return VecNormalize(venv, norm_obs=norm_obs, norm_reward=norm_reward, gamma=gamma)

    def factory() -> gym.Env:
        env = gym.make(env_id, scenario=scenario)
        angles = env.unwrapped.nominal_model.angle_indices
        limit = env.spec.max_episode_steps if time_feature_on else None
        if reward_shift:
            env = BoundedShiftReward(env)
        if goal_bonus:
            env = GoalBonusReward(env, goal_bonus)
        return Monitor(wrap_env(env, angles, limit))

    venv = DummyVecEnv([factory] * n_envs)
    venv.seed(seed)
    return VecNormalize(venv, norm_obs=norm_obs, norm_reward=norm_reward, gamma=gamma)


# --------------------------------------------------------------------------- env state
_SKIP_LAYER_KEYS = frozenset({"env", "results_writer", "_saved_kwargs", "_metadata",
                              "_cached_spec"})
_BASE_KEYS = ("_state", "_steps", "_held", "_np_random", "_np_random_seed")


def get_env_state(env: gym.Env) -> dict[str, Any]:
    """Everything that evolves while a (wrapped) ``gp_envs`` env runs, as a picklable dict.

    The env itself does not pickle (its CasADi models hold mapping proxies), so a training
    checkpoint stores this instead: every wrapper layer's attributes except the wrapped env and
    spaces (step counters, Monitor accumulators, the checker's flags), and the base env's state,
    step and hold counters, RNG and this episode's true and nominal parameter values.
    """
    layers = []
    e = env
    while isinstance(e, gym.Wrapper):
        layers.append({k: copy.deepcopy(v) for k, v in vars(e).items()
                       if k not in _SKIP_LAYER_KEYS and not isinstance(v, spaces.Space)})
        e = e.env
    base = {k: copy.deepcopy(getattr(e, k)) for k in _BASE_KEYS if k in vars(e)}
    return {"layers": layers, "base": base, "base_type": type(e).__name__,
            "plant_params": dict(getattr(e._plant, "params", {})),
            "nominal_params": dict(e.nominal_model.params)}


def set_env_state(env: gym.Env, state: Mapping[str, Any]) -> None:
    """Put ``env`` (built like the one :func:`get_env_state` read) into that state.

    Raises:
        ValueError: the wrapper chain or the base env differ from the recorded ones.
    """
    layers = []
    e = env
    while isinstance(e, gym.Wrapper):
        layers.append(e)
        e = e.env
    if len(layers) != len(state["layers"]) or type(e).__name__ != state["base_type"]:
        raise ValueError("env state was recorded for a different wrapper chain or env")
    for layer, attrs in zip(layers, state["layers"], strict=True):
        for k, v in attrs.items():
            setattr(layer, k, copy.deepcopy(v))
    for k, v in state["base"].items():
        setattr(e, k, copy.deepcopy(v))
    if dict(getattr(e._plant, "params", {})) != dict(state["plant_params"]):
        e._plant = e._make_plant(dict(state["plant_params"]))
    if dict(e.nominal_model.params) != dict(state["nominal_params"]):
        e.nominal_model = e._make_model(dict(state["nominal_params"]))


# --------------------------------------------------------------------------- agent
def _shape(x: Sequence[int]) -> list[int]:
    return [int(v) for v in x]


class RLAgent:
    """A frozen SB3 policy with its preprocessing, acting on raw env observations.

    Args:
        model: trained SB3 model (acts on :func:`angle_features` -> normalized features, outputs
            actions in ``[-1, 1]^m``).
        metadata: the record saved next to the model; must contain ``algo``, ``env_id``,
            ``scenario``, ``obs_shape``, ``action_shape``, ``action_low``, ``action_high``,
            ``angle_indices``; may contain ``training_steps``, ``seed``, ``hyperparameters``,
            ``train_time_s``, ``time_feature_max_steps`` (the policy input ends with
            :func:`time_feature`; then :meth:`act` must be called once per env step after
            :meth:`reset`), ``training_wrappers``.
        obs_normalizer: frozen ``VecNormalize`` whose ``normalize_obs`` is applied to the
            features, or None.
        deterministic: act with the policy's mean action (default) instead of sampling.

    Attributes:
        algo, env_id, scenario, training_steps, seed, hyperparameters, train_time_s: from
            ``metadata``.
    """

    def __init__(self, model: BaseAlgorithm, metadata: Mapping[str, Any],
                 obs_normalizer: VecNormalize | None = None, deterministic: bool = True) -> None:
        required = ("algo", "env_id", "scenario", "obs_shape", "action_shape", "action_low",
                    "action_high", "angle_indices")
        missing = [k for k in required if k not in metadata]
        if missing:
            raise ValueError(f"RLAgent metadata lacks {missing}")
        self.model = model
        self.metadata: dict[str, Any] = dict(metadata)
        self.obs_normalizer = obs_normalizer  # only normalize_obs is used: never updates stats
        self.deterministic = bool(deterministic)
        self.algo: str = str(metadata["algo"])
        self.env_id: str = str(metadata["env_id"])
        self.scenario: str = str(metadata["scenario"])
        self.training_steps: int = int(metadata.get("training_steps", model.num_timesteps))
        self.seed: int | None = metadata.get("seed")
        self.hyperparameters: dict[str, Any] = dict(metadata.get("hyperparameters", {}))
        self.train_time_s: float | None = metadata.get("train_time_s")
        self.obs_shape = tuple(_shape(metadata["obs_shape"]))
        self.action_shape = tuple(_shape(metadata["action_shape"]))
        self.angle_indices = tuple(int(i) for i in metadata["angle_indices"])
        self._low = np.asarray(metadata["action_low"], dtype=np.float64)
        self._high = np.asarray(metadata["action_high"], dtype=np.float64)
        tf = metadata.get("time_feature_max_steps")
        self.time_feature_max_steps: int | None = int(tf) if tf else None
        self.steps_since_reset = 0
        """Number of :meth:`act` calls since :meth:`reset` (the time feature's step count)."""

    # ------------------------------------------------------------------ acting
    def preprocess(self, obs: np.ndarray, steps: int | None = None) -> np.ndarray:
        """(n,) raw observation -> (n + k [+ 1],) float32 policy input (features, normalized).

        Args:
            obs: (n,) observation in physical units.
            steps: env steps since reset for the time feature (default
                :attr:`steps_since_reset`); ignored without a time feature.

        Raises:
            ValueError: ``obs`` has the wrong shape or is not finite.
        """
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self.obs_shape:
            raise ValueError(f"obs must have shape {self.obs_shape}, got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"obs must be finite, got {x}")
        feats = angle_features(x, self.angle_indices)
        if self.time_feature_max_steps is not None:
            t = self.steps_since_reset if steps is None else int(steps)
            feats = np.append(feats, np.float32(time_feature(t, self.time_feature_max_steps)))
        if self.obs_normalizer is not None:
            feats = np.asarray(self.obs_normalizer.normalize_obs(feats[None]), np.float32)[0]
        return feats

    def act(self, obs: np.ndarray, deterministic: bool | None = None) -> np.ndarray:
        """Action for a raw observation.

        Args:
            obs: (n,) observation as returned by the env (physical units).
            deterministic: override :attr:`deterministic` for this call.

        Returns:
            (m,) float32 action inside the env's action box (physical units).

        Raises:
            ValueError: ``obs`` has the wrong shape or contains NaN/inf.
        """
        det = self.deterministic if deterministic is None else bool(deterministic)
        a, _ = self.model.predict(self.preprocess(obs)[None], deterministic=det)
        self.steps_since_reset += 1
        return scale_action(np.asarray(a).reshape(self.action_shape), self._low, self._high)

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """Receive a transition; a frozen policy does not learn, so this does nothing.

        Args:
            obs: (n,) observation before the step.
            action: (m,) action applied.
            next_obs: (n,) observation after the step.
        """
        del obs, action, next_obs

    def reset(self) -> None:
        """Start of an episode: the step count of the time feature restarts at 0 (the policies
        are otherwise memoryless)."""
        self.steps_since_reset = 0

    # ------------------------------------------------------------------ persistence
    @classmethod
    def metadata_for(cls, env: gym.Env, algo: str, *, outside_env: tuple[str, str] | None = None,
                     **extra: Any) -> dict[str, Any]:
        """The metadata record for a model trained on ``env`` (a ``gym.make``-made env).

        Args:
            env: the env (unwrapped by us; ``gym.make`` wrappers are fine).
            algo: a key of :data:`ALGORITHMS`.
            outside_env: ``(name, scenario)`` of the benchmark env ``env`` is, when it is not a
                registered ``gp_envs`` system (a :func:`gp_envs.wrap`-ped outside simulator,
                with no Gymnasium id of its own): then ``env_id`` is that name and the record
                gains ``outside_env`` (name, scenario, :func:`env_fingerprint`), which
                :meth:`load` checks.
            extra: further fields (``training_steps``, ``seed``, ``hyperparameters``, ...).
        """
        if outside_env is not None:
            import gp_envs

            name, scenario = outside_env
            identity: dict[str, Any] = {
                "env_id": str(name), "scenario": str(scenario),
                "outside_env": {"name": str(name), "scenario": str(scenario),
                                "fingerprint": env_fingerprint(env)}}
            angles = gp_envs.nominal_model(env).angle_indices
        else:
            if env.spec is None:
                raise ValueError("env has no spec; create it with gym.make")
            base = env.unwrapped
            identity = {"env_id": env.spec.id, "scenario": getattr(base, "scenario", None)}
            angles = base.nominal_model.angle_indices
        return {
            "algo": algo,
            **identity,
            "obs_shape": _shape(env.observation_space.shape),
            "action_shape": _shape(env.action_space.shape),
            "action_low": env.action_space.low.astype(float).tolist(),
            "action_high": env.action_space.high.astype(float).tolist(),
            "angle_indices": [int(i) for i in angles],
            "preprocessing": ["AngleFeatures (cos, sin of angle_indices)",
                              *(["TimeFeature (1 - t/T appended)"]
                                if extra.get("time_feature_max_steps") else []),
                              "VecNormalize observation statistics (frozen)",
                              "NormalizedAction ([-1, 1] -> action box)"],
            "versions": {"stable_baselines3": stable_baselines3.__version__,
                         "torch": torch.__version__, "gymnasium": gym.__version__},
            **extra,
        }

    def save(self, path: str | Path) -> Path:
        """Write the agent to directory ``path`` (created); returns the directory.

        Each file is written under a temporary name and renamed into place, ``metadata.json``
        last, so an interrupted save never leaves a metadata file next to a partial model.
        """
        out = Path(path)
        out.mkdir(parents=True, exist_ok=True)
        tmp = out / ".saving"
        tmp.mkdir(exist_ok=True)
        self.model.save(tmp / MODEL_FILE, exclude=["replay_buffer", "rollout_buffer"])
        vec = out / VECNORM_FILE
        if self.obs_normalizer is not None:
            self.obs_normalizer.save(str(tmp / VECNORM_FILE))
        meta = dict(self.metadata, training_steps=self.training_steps,
                    obs_normalization=self.obs_normalizer is not None)
        (tmp / METADATA_FILE).write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
        (out / METADATA_FILE).unlink(missing_ok=True)
        (tmp / MODEL_FILE).replace(out / MODEL_FILE)
        if self.obs_normalizer is not None:
            (tmp / VECNORM_FILE).replace(vec)
        else:
            vec.unlink(missing_ok=True)
        (tmp / METADATA_FILE).replace(out / METADATA_FILE)
        tmp.rmdir()
        return out

    @classmethod
    def load(cls, path: str | Path, env: gym.Env, deterministic: bool = True,
             search: Sequence[str | Path] = ()) -> RLAgent:
        """Load a saved agent and check that it was trained for ``env``.

        Args:
            path: directory written by :meth:`save` (or the ``model.zip`` inside it), or a
                name ``"<env>/<algo>"`` in a model directory of ``search`` (see
                :func:`resolve_model_dir`).
            env: the env the agent will act in (made with ``gym.make``).
            deterministic: see :class:`RLAgent`.
            search: model directories (``<env>/<algo>/`` folders) a relative ``path`` is
                looked up in when it holds no saved agent relative to the current directory.

        Raises:
            FileNotFoundError: no saved agent at ``path`` nor in ``search`` (the message lists
                the agents in ``search``).
            ValueError: the agent was trained for another env id, scenario or spaces (for
                an outside env: another simulator configuration or nominal model, see
                :func:`env_fingerprint`).
        """
        d = resolve_model_dir(path, search)
        meta_file = d / METADATA_FILE
        meta = json.loads(meta_file.read_text())
        cls._check_env(meta, env, d)
        algo = meta["algo"]
        if algo not in ALGORITHMS:
            raise ValueError(f"{d}: unknown algorithm {algo!r}; known: {sorted(ALGORITHMS)}")
        model = ALGORITHMS[algo].load(d / MODEL_FILE, device="cpu")
        normalizer = None
        if meta.get("obs_normalization", False):
            with open(d / VECNORM_FILE, "rb") as fh:
                normalizer = pickle.load(fh)  # frozen statistics; no venv needed to normalize
            normalizer.training = False
        return cls(model, meta, normalizer, deterministic=deterministic)

    @staticmethod
    def _check_env(meta: Mapping[str, Any], env: gym.Env, where: Path | str) -> None:
        problems = []
        outside = meta.get("outside_env")
        if outside is not None:  # a benchmark's outside env: no id; its fingerprint says
            try:
                fingerprint = env_fingerprint(env)
            except TypeError:
                fingerprint = None
            trained = outside["fingerprint"]
            if fingerprint != trained:
                if fingerprint is None:
                    differ = "this env has no nominal model"
                else:
                    keys = [f"{part}.{k}" for part in ("simulator", "model")
                            for k in sorted(set(trained.get(part, {}))
                                            | set(fingerprint.get(part, {})))
                            if trained.get(part, {}).get(k) != fingerprint.get(part, {}).get(k)]
                    # another simulator or model altogether: say that, not every field
                    keys = [k for k in keys if k in ("simulator.class", "model.name")] or keys
                    differ = ("this env differs in " + ", ".join(
                        f"{k} ({_fingerprint_value(fingerprint, k)!r} != trained "
                        f"{_fingerprint_value(trained, k)!r})" for k in keys))
                problems.append(f"trained on the benchmark env {outside['name']!r} scenario "
                                f"{outside['scenario']!r} (an outside simulator); {differ}")
        else:
            env_id = env.spec.id if env.spec is not None else None
            scenario = getattr(env.unwrapped, "scenario", None)
            if env_id != meta["env_id"]:
                problems.append(f"env id {env_id!r} != trained {meta['env_id']!r}")
            if scenario != meta["scenario"]:
                problems.append(f"scenario {scenario!r} != trained {meta['scenario']!r}")
        if _shape(env.observation_space.shape) != _shape(meta["obs_shape"]):
            problems.append(f"observation shape {env.observation_space.shape} != trained "
                            f"{tuple(meta['obs_shape'])}")
        if _shape(env.action_space.shape) != _shape(meta["action_shape"]):
            problems.append(f"action shape {env.action_space.shape} != trained "
                            f"{tuple(meta['action_shape'])}")
        elif not (np.allclose(env.action_space.low, meta["action_low"])
                  and np.allclose(env.action_space.high, meta["action_high"])):
            problems.append("action bounds differ from the trained ones")
        if problems:
            raise ValueError(f"RL agent in {where} does not fit this env: " + "; ".join(problems))

    def __repr__(self) -> str:
        return (f"RLAgent(algo={self.algo!r}, env_id={self.env_id!r}, scenario={self.scenario!r}, "
                f"training_steps={self.training_steps}, seed={self.seed})")


def _fingerprint_value(fingerprint: Mapping[str, Any], key: str) -> Any:
    part, _, name = key.partition(".")
    return fingerprint.get(part, {}).get(name)


def _is_saved_agent(d: Path) -> bool:
    return (d / METADATA_FILE).is_file() and (d / MODEL_FILE).is_file()


def saved_models(directory: str | Path) -> list[str]:
    """Names ``"<env>/<algo>"`` of the saved agents in a model directory laid out as
    ``<directory>/<env>/<algo>/`` (e.g. the benchmark's ``benchmarks/models``), sorted; empty if
    ``directory`` does not exist."""
    root = Path(directory)
    if not root.is_dir():
        return []
    return sorted(m.parent.relative_to(root).as_posix() for m in root.glob(f"*/*/{MODEL_FILE}")
                  if _is_saved_agent(m.parent))


def resolve_model_dir(path: str | Path, search: Sequence[str | Path] = ()) -> Path:
    """The directory of the saved agent ``path`` names.

    ``path`` is a directory written by :meth:`RLAgent.save` (or its ``model.zip``), absolute or
    relative to the current directory. A relative path that holds no saved agent there is looked
    up in each model directory of ``search`` in turn (``<env>/<algo>/`` folders, see
    :func:`saved_models`): as ``<dir>/<path>``, and with leading parts of ``path`` that repeat
    the end of ``<dir>`` dropped, so with ``search=[".../benchmarks/models"]`` the names
    ``"cartpole/sac"``, ``"models/cartpole/sac"`` and ``"benchmarks/models/cartpole/sac"`` all
    find ``.../benchmarks/models/cartpole/sac``. This module knows no model directory of its
    own: the benchmark passes its shipped one (``benchmarks.controllers.MODELS_DIR``).

    Args:
        path: a saved agent's directory or ``model.zip``, or a name relative to ``search``.
        search: model directories to look in, first match wins.

    Raises:
        FileNotFoundError: no saved agent at ``path`` nor in ``search``; the message lists the
            agents in ``search``.
    """
    d = Path(path)
    if d.is_file() or (d.name == MODEL_FILE and not d.is_dir()):
        d = d.parent
    if _is_saved_agent(d):
        return d
    roots = [Path(r) for r in search]
    if not d.is_absolute():
        for root in roots:
            parts = d.parts
            tail = root.resolve().parts
            for k in range(min(len(parts), len(tail)), 0, -1):
                if parts[:k] == tail[-k:]:
                    parts = parts[k:]
                    break
            if parts and _is_saved_agent(root.joinpath(*parts)):
                return root.joinpath(*parts)
    where = d if d.is_absolute() else f"{d} (relative to {Path.cwd()})"
    listed = [f"{root}: {', '.join(saved_models(root)) or 'none'}" for root in roots]
    found = ("; saved agents in " + "; in ".join(listed) if listed else
             "; pass the saved agent's directory, or the model directories to look in "
             "(search=[...], e.g. benchmarks.controllers.MODELS_DIR for the shipped policies)")
    raise FileNotFoundError(f"no saved RLAgent ({METADATA_FILE} + {MODEL_FILE}) in {where}"
                            f"{found}")
