"""Every controller recipe and every env of the benchmark suite, in one place.

A controller is named by a short string (``"ssgp-mpc"``, ``"sac"``, ...) and built for one env
and seed by :func:`build_controller`. Change a recipe here and every preset follows.

MPC recipes (:class:`gp_agents.PseudospectralMPC`, built after ``env.reset`` so they plan with
the episode's nominal model; for the Dubins scenario that model is redrawn at every reset):

=================  ======================================================================
nominal-mpc        nominal physics only, receding horizon
oracle-mpc         the true model (``model_source=lambda: gp_envs.oracle_model(env)``): an
                   upper bound; the benchmark hands the truth in, the agent never looks
gp-mpc             nominal + :class:`ExactGP` fitted once on the initial data, no online learning
ssgp-mpc           nominal + :func:`gp_agents.online_ssgp` (``IncrementalSSGP(50,
                   forgetting_factor=0.995)``, own-likelihood hyperparameters with a
                   length-scale floor) pretrained on the initial data, learning online
<base>-episodic     the same model, planned once over the whole episode and run open loop
=================  ======================================================================

Speed variants of ``ssgp-mpc`` (:data:`SPEED_VARIANTS`, presets ``speed-options`` and
``linearized``): ``ssgp-mpc-nominal-hessian`` (``hessian="nominal"``), ``ssgp-mpc-model-inputs``
(``input_indices="model"``), ``ssgp-mpc-linearized`` (``learned_dynamics="linearized"``) and
``ssgp-mpc-linearized-model-inputs`` (both).

Variants with an explicit parametric part of the residual (:data:`SENSITIVITY_VARIANTS`, preset
``robustness``): ``ssgp-mpc-sensitivities`` (the learner also sees the nominal model's parameter
sensitivities, ``sensitivities=True``, and has linear features) and
``ssgp-mpc-linearized-sensitivities``; and ``ssgp-mpc-adaptive`` / ``ssgp-mpc-linearized-adaptive``,
whose learner also restarts when it detects that the system changed
(:class:`gp_agents.learners.ChangeDetector`); ``ssgp-mpc-linearized-guarded``, the latter with
the residual switched off while it predicts worse than the nominal model
(:class:`gp_agents.learners.NominalFallback`); ``ssgp-mpc-linearized-saturated``, the guarded
one whose learner saturates its standardized inputs (``input_saturation``,
:data:`gp_agents.learners.INPUT_SATURATION` standard deviations);
``ssgp-mpc-linearized-parametric``, the saturated one with linear features on the parameter
sensitivities only (the residual's parametric part alone).

Real-time-iteration variants (:data:`RTI_VARIANTS`, preset ``rti``): ``nominal-mpc-rti``,
``oracle-mpc-rti``, ``ssgp-mpc-rti`` (``scheme="rti"``; the SSGP one with the system's
registered learned term, ``PlanningDefaults.rti_learned_dynamics``),
``ssgp-mpc-rti-linearized`` (the GP linearized per node on every system),
``ssgp-mpc-rti-zero-order`` (the GP's value frozen per node, adjoint-corrected),
``ssgp-mpc-rti-pattern`` (the GP linearized on the nominal Jacobian pattern, the rest
adjoint-corrected), ``ssgp-mpc-rti-parametric`` (the learner of
``ssgp-mpc-linearized-parametric``), and each of the seven with ``-split`` (``scheme="rti-split"``:
preparation after the action, feedback on the measurement);
and their converged references warm-started with the previous multipliers
(:data:`WARM_DUAL_VARIANTS`): ``nominal-mpc-warm-duals``, ``oracle-mpc-warm-duals``.

RL recipes load a stable-baselines3 policy ``<env>/<algo>/`` (:class:`gp_agents.rl.RLAgent`)
from the first model directory of :func:`rl_model_dirs` that has one: the user's (``gp-bench
--models DIR``, else ``./benchmarks/models`` under the current directory, where
``python -m benchmarks.train_rl`` saves), then the shipped ones (:data:`MODELS_DIR`, package
data, so a non-editable install has them). A missing model (or one trained for another
scenario) makes the controller *unavailable* for that env, which the runner records instead
of crashing.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

import gp_envs
from benchmarks import USER_MODELS_DIR
from gp_agents.mpc import GPInNLP
from gp_agents.mpc.controller import default_learned_dynamics
from gp_envs.systems import SYSTEMS

MODELS_DIR = Path(__file__).resolve().parent / "models"
"""Where the shipped RL policies live: ``<env short name>/<algo>/`` inside the installed package
(``[tool.setuptools.package-data]`` in ``pyproject.toml`` ships them)."""


N_INITIAL_POINTS = 200
"""Initial transitions collected for the learning MPCs (paper: 200 points)."""


@dataclass(frozen=True)
class EnvInfo:
    """A benchmark env: registered id and the scenarios the suite runs."""

    env_id: str
    scenarios: tuple[str, ...]
    default_scenario: str


class _BenchmarkEnvs(Mapping[str, EnvInfo]):
    """The registered systems (:data:`gp_envs.SYSTEMS`) as benchmark envs, by short name (live:
    a system registered after import is a benchmark env too)."""

    def __getitem__(self, name: str) -> EnvInfo:
        system = SYSTEMS[name]
        return EnvInfo(system.env_id, system.scenarios, system.default_scenario)

    def __iter__(self) -> Iterator[str]:
        return iter(SYSTEMS)

    def __len__(self) -> int:
        return len(SYSTEMS)


ENVS: Mapping[str, EnvInfo] = _BenchmarkEnvs()
"""Benchmark envs by short name: every registered system (:func:`gp_envs.register_system`)."""


@dataclass(frozen=True)
class ControllerRecipe:
    """How to build one named controller.

    Attributes:
        name: registry key.
        label: display name in tables and plots.
        family: ``"mpc"`` or ``"rl"``.
        description: one line for ``--list-controllers`` and reports.
        learner: ``None``, ``"exact"`` (offline :class:`ExactGP`) or ``"ssgp"``
            (:class:`IncrementalSSGP`); MPC only.
        oracle: plan with the true model (upper bound); MPC only.
        mode: ``"receding"`` or ``"episodic"``; MPC only.
        learn_online: feed closed-loop transitions to the learner; MPC only.
        algo: ``"sac"``, ``"ppo"`` or ``"tqc"``; RL only.
        settings: extra keyword settings of :class:`gp_agents.PseudospectralMPC` as
            ``(name, value)`` pairs (the speed variants of the SSGP-MPC); MPC only.
    """

    name: str
    label: str
    family: str
    description: str
    learner: str | None = None
    oracle: bool = False
    mode: str = "receding"
    learn_online: bool = False
    algo: str | None = None
    settings: tuple[tuple[str, Any], ...] = ()

    @property
    def base(self) -> str:
        """Name of the model variant without the mode (``"ssgp"`` for ``"ssgp-episodic"``)."""
        if self.family != "mpc":
            return self.name
        return self.name.split("-mpc")[0] if "-mpc" in self.name else self.name.rsplit("-", 1)[0]

    @property
    def uses_initial_data(self) -> bool:
        """Whether the recipe collects initial data before the episode."""
        return self.learner is not None


def _mpc_recipes() -> dict[str, ControllerRecipe]:
    variants = {
        "nominal": ("nominal", "nominal physics", None, False, False),
        "oracle": ("oracle", "true model (upper bound)", None, True, False),
        "gp": ("offline GP", "nominal + exact GP fitted once on the initial data", "exact",
               False, False),
        "ssgp": ("SSGP", "nominal + incremental SSGP (r=50, lambda=0.995), learning online",
                 "ssgp", False, True),
    }
    out: dict[str, ControllerRecipe] = {}
    for key, (label, desc, learner, oracle, online) in variants.items():
        out[f"{key}-mpc"] = ControllerRecipe(
            f"{key}-mpc", f"{label} MPC", "mpc", f"{desc}; receding-horizon MPC",
            learner=learner, oracle=oracle, mode="receding", learn_online=online)
        out[f"{key}-episodic"] = ControllerRecipe(
            f"{key}-episodic", f"{label} episodic", "mpc",
            f"{desc.split(', learning')[0]}; planned once over the episode, open loop",
            learner=learner, oracle=oracle, mode="episodic", learn_online=False)
    return out


def _ssgp_variant(suffix: str, label: str, description: str, learner: str = "ssgp",
                  **settings: Any) -> tuple[str, ControllerRecipe]:
    """``ssgp-mpc-<suffix>``: the online SSGP-MPC with extra :class:`PseudospectralMPC`
    settings (and the learner kind of :func:`make_learner`)."""
    name = f"ssgp-mpc-{suffix}"
    return name, ControllerRecipe(name, f"SSGP MPC, {label}", "mpc", description,
                                  learner=learner, learn_online=True,
                                  settings=tuple(settings.items()))


SPEED_VARIANTS: dict[str, ControllerRecipe] = dict([
    _ssgp_variant("nominal-hessian", "nominal Hessian",
                  "ssgp-mpc with the GP's second derivatives dropped from the Lagrangian "
                  "Hessian (learned_dynamics=GPInNLP(hessian='nominal'))",
                  learned_dynamics=GPInNLP(hessian="nominal")),
    _ssgp_variant("model-inputs", "model inputs",
                  "ssgp-mpc whose learner sees only the states the nominal model's "
                  "accelerations depend on (input_indices='model')", input_indices="model"),
    _ssgp_variant("linearized", "linearized",
                  "ssgp-mpc planning with the GP residual linearized per node about the warm "
                  "start (learned_dynamics='linearized')", learned_dynamics="linearized"),
    _ssgp_variant("linearized-model-inputs", "linearized, model inputs",
                  "ssgp-mpc-linearized whose learner sees only the states the nominal model's "
                  "accelerations depend on (input_indices='model')",
                  learned_dynamics="linearized", input_indices="model"),
])
"""Variants of ``ssgp-mpc`` that trade exactness or generality for speed (issue: the SSGP-MPC's
step time), compared by the ``speed-options`` and ``linearized`` presets."""

SENSITIVITY_VARIANTS: dict[str, ControllerRecipe] = dict([
    _ssgp_variant("sensitivities", "sensitivities",
                  "ssgp-mpc whose learner also sees the nominal model's parameter sensitivities "
                  "d f_p/d p (sensitivities=True) and has linear features "
                  "(online_ssgp(linear_features=True)): an explicit parametric part of the "
                  "residual", learner="ssgp-linear", sensitivities=True),
    _ssgp_variant("linearized-sensitivities", "linearized, sensitivities",
                  "ssgp-mpc-sensitivities planning with the GP residual linearized per node "
                  "(learned_dynamics='linearized')", learner="ssgp-linear",
                  sensitivities=True, learned_dynamics="linearized"),
    _ssgp_variant("adaptive", "adaptive",
                  "ssgp-mpc-sensitivities whose learner also restarts from the new regime's "
                  "samples when its one-step prediction errors show that the system changed "
                  "(online_ssgp(linear_features=True, change_detector=ChangeDetector()))",
                  learner="ssgp-adaptive", sensitivities=True),
    _ssgp_variant("linearized-adaptive", "linearized, adaptive",
                  "ssgp-mpc-adaptive planning with the GP residual linearized per node "
                  "(learned_dynamics='linearized')", learner="ssgp-adaptive",
                  sensitivities=True, learned_dynamics="linearized"),
    _ssgp_variant("linearized-guarded", "linearized, guarded",
                  "ssgp-mpc-linearized-adaptive whose residual is switched off while it "
                  "predicts the newest samples worse than the nominal model "
                  "(online_ssgp(..., nominal_fallback=NominalFallback()))",
                  learner="ssgp-guarded", sensitivities=True, learned_dynamics="linearized"),
    _ssgp_variant("linearized-saturated", "linearized, saturated",
                  "ssgp-mpc-linearized-guarded whose learner saturates its standardized inputs "
                  "at INPUT_SATURATION standard deviations (online_ssgp(..., "
                  "input_saturation=INPUT_SATURATION)): plans far outside the initial data "
                  "meet a bounded residual, not an extrapolated slope",
                  learner="ssgp-saturated", sensitivities=True, learned_dynamics="linearized"),
    _ssgp_variant("linearized-parametric", "linearized, parametric",
                  "ssgp-mpc-linearized-saturated whose linear features are on the parameter "
                  "sensitivities only (online_ssgp(..., linear_features=<their columns>)): the "
                  "residual's parametric part dp' S(x, u) without linear terms in the raw "
                  "states and controls, which extrapolate as a drift the physics lacks",
                  learner="ssgp-parametric", sensitivities=True, learned_dynamics="linearized"),
])
"""Variants of ``ssgp-mpc`` whose residual has an explicit parametric part (issue: online
learning across the envelope), compared by the ``robustness`` preset."""


def _rti(base: str, label: str, description: str, learner: str | None = None,
         oracle: bool = False, **settings: Any) -> tuple[str, ControllerRecipe]:
    name = f"{base}-mpc-rti"
    return name, ControllerRecipe(
        name, f"{label} MPC, RTI", "mpc", description, learner=learner, oracle=oracle,
        learn_online=learner is not None, settings=(("scheme", "rti"), *settings.items()))


RTI_VARIANTS: dict[str, ControllerRecipe] = dict([
    _rti("nominal", "nominal", "nominal-mpc with a real-time iteration (scheme='rti': one "
         "Gauss-Newton SQP step per period after a converged cold start)"),
    _rti("oracle", "oracle", "oracle-mpc with a real-time iteration (scheme='rti')",
         oracle=True),
    _rti("ssgp", "SSGP", "ssgp-mpc with a real-time iteration (scheme='rti'), the GP entering "
         "the QP as the system's registered rti_learned_dynamics (PlanningDefaults: linearized "
         "per node at the shifted plan; the quadrotor: on the nominal Jacobian pattern)",
         learner="ssgp"),
])


def _ssgp_rti(suffix: str, label: str, description: str, learner: str = "ssgp",
              **settings: Any) -> tuple[str, ControllerRecipe]:
    """``ssgp-mpc-rti-<suffix>``: the one-call SSGP RTI with another learned term or learner."""
    name = f"ssgp-mpc-rti-{suffix}"
    return name, ControllerRecipe(name, f"SSGP MPC, RTI {label}", "mpc", description,
                                  learner=learner, learn_online=True,
                                  settings=(("scheme", "rti"), *settings.items()))


RTI_VARIANTS.update([
    _ssgp_rti("linearized", "linearized",
              "ssgp-mpc-rti with the GP linearized per node at the shifted plan on every system "
              "(learned_dynamics='linearized': its full Jacobian in the QP)",
              learned_dynamics="linearized"),
    _ssgp_rti("zero-order", "zero-order",
              "ssgp-mpc-rti with the GP's value frozen per node (learned_dynamics='zero-order': "
              "the nominal QP structure, the gradient corrected with the previous multipliers)",
              learned_dynamics="zero-order"),
    _ssgp_rti("pattern", "pattern",
              "ssgp-mpc-rti with the GP's Jacobian kept only on the nominal model's Jacobian "
              "pattern (learned_dynamics='linearized-pattern': the nominal QP structure with the "
              "learned control gains, the dropped derivatives corrected with the previous "
              "multipliers)", learned_dynamics="linearized-pattern"),
    _ssgp_rti("parametric", "parametric",
              "ssgp-mpc-rti whose learner is ssgp-mpc-linearized-parametric's (the parameter "
              "sensitivities as inputs, linear features on them only, gp_agents.parametric_ssgp)",
              learner="ssgp-parametric", sensitivities=True),
])
for _name in ("nominal-mpc-rti", "oracle-mpc-rti", "ssgp-mpc-rti", "ssgp-mpc-rti-linearized",
              "ssgp-mpc-rti-zero-order", "ssgp-mpc-rti-pattern", "ssgp-mpc-rti-parametric"):
    _base = RTI_VARIANTS[_name]
    RTI_VARIANTS[f"{_name}-split"] = dataclasses.replace(
        _base, name=f"{_name}-split", label=f"{_base.label}, split",
        description=f"{_name} split into a preparation (after the action: learner update, "
                    "shift with the predicted initial state, expansion, QP data) and a "
                    "feedback phase (the QP with the measured state; scheme='rti-split')",
        settings=tuple((k, "rti-split" if k == "scheme" else v) for k, v in _base.settings))
"""Real-time-iteration variants (issue: RTI), compared by the ``rti`` preset."""


def learned_term(recipe: ControllerRecipe, system: str) -> str | None:
    """The ``learned_dynamics`` name ``recipe``'s MPC uses on ``system`` (its own setting, else
    :func:`gp_agents.mpc.controller.default_learned_dynamics` of its scheme and the system's
    registration), or None for a recipe with no learner."""
    if recipe.learner is None:
        return None
    settings = dict(recipe.settings)
    if "learned_dynamics" in settings:
        term = settings["learned_dynamics"]
        return term if isinstance(term, str) else type(term).__name__
    return default_learned_dynamics(settings.get("scheme", "converged"),
                                    gp_envs.SYSTEMS[system].planning)

WARM_DUAL_VARIANTS: dict[str, ControllerRecipe] = {
    f"{base}-mpc-warm-duals": ControllerRecipe(
        f"{base}-mpc-warm-duals", f"{label} MPC, warm duals", "mpc",
        f"{base}-mpc whose converged IPOPT solves also start from the previous solve's "
        "multipliers with IPOPT's warm-start options (warm_start_duals=True): the fastest "
        "converged reference for the RTI's step-time ratios", oracle=base == "oracle",
        settings=(("warm_start_duals", True),))
    for base, label in (("nominal", "nominal"), ("oracle", "oracle"))}
"""Converged recipes warm-started with the previous multipliers (the ``rti`` preset's second,
faster converged reference)."""


CONTROLLERS: dict[str, ControllerRecipe] = {
    **_mpc_recipes(),
    **SPEED_VARIANTS,
    **SENSITIVITY_VARIANTS,
    **RTI_VARIANTS,
    **WARM_DUAL_VARIANTS,
    "sac": ControllerRecipe("sac", "SAC", "rl", "shipped stable-baselines3 SAC policy",
                            algo="sac"),
    "ppo": ControllerRecipe("ppo", "PPO", "rl", "shipped stable-baselines3 PPO policy",
                            algo="ppo"),
    "tqc": ControllerRecipe("tqc", "TQC", "rl", "shipped sb3-contrib TQC policy", algo="tqc"),
}
"""The controller registry: every recipe by name."""
RL_ALGORITHMS = tuple(name for name, r in CONTROLLERS.items() if r.family == "rl")
"""The RL recipes (``"sac"``, ``"ppo"``, ``"tqc"``): each loads its shipped policy where one
exists for the env."""


class UnknownNameError(ValueError):
    """An unknown controller, env, scenario or preset name (the message lists valid names)."""


class ControllerUnavailableError(RuntimeError):
    """The controller cannot run on this env/scenario (e.g. no shipped RL model)."""


def check_name(kind: str, name: str, valid: Any) -> None:
    """Raise :class:`UnknownNameError` listing ``valid`` when ``name`` is not among them."""
    if name not in valid:
        raise UnknownNameError(f"unknown {kind} {name!r}; valid {kind}s: {', '.join(valid)}")


def check_env_scenario(env: str, scenario: str) -> None:
    """Raise :class:`UnknownNameError` for an unknown env or a scenario it does not have."""
    check_name("env", env, list(ENVS))
    if scenario not in ENVS[env].scenarios:
        raise UnknownNameError(f"unknown scenario {scenario!r} of env {env}; valid scenarios of "
                               f"{env}: {', '.join(ENVS[env].scenarios)}")


@dataclass
class BuiltController:
    """A controller ready for an episode.

    Attributes:
        agent: object with ``reset()``, ``act(obs)``, ``observe(obs, a, next_obs)``.
        obs: the observation after ``env.reset(seed=seed)`` (the episode's first).
        prior_data_steps: env steps of data used before the episode (initial data, or RL
            training steps).
        info: recipe details for the record (e.g. the RL model's path and training steps).
    """

    agent: Any
    obs: Any
    prior_data_steps: int
    info: dict[str, Any]


def user_models_dir(models: str | Path | None = None) -> Path | None:
    """The user's model directory, absolute: ``models`` (``gp-bench --models``) if given, else
    :data:`benchmarks.USER_MODELS_DIR` under the current directory if it exists; None when
    there is none or it is the shipped :data:`MODELS_DIR`.

    Raises:
        FileNotFoundError: ``models`` is given but is not a directory.
    """
    if models is not None:
        path = Path(models).resolve()
        if not path.is_dir():
            raise FileNotFoundError(f"--models {models}: no such directory; give the directory "
                                    "that holds <env>/<algo>/ model folders (python -m "
                                    "benchmarks.train_rl writes ./benchmarks/models/<env>/<algo>)")
    else:
        path = USER_MODELS_DIR.resolve()
        if not path.is_dir():
            return None
    return None if path == MODELS_DIR.resolve() else path


def rl_model_dirs(models: str | Path | None = None) -> list[Path]:
    """The model directories the RL recipes look in, first match wins: the user's
    (:func:`user_models_dir` of ``models``), then the shipped :data:`MODELS_DIR`."""
    user = user_models_dir(models)
    return [MODELS_DIR] if user is None else [user, MODELS_DIR]


def rl_model_dir(env: str, algo: str, models: str | Path | None = None) -> Path:
    """Directory of the RL model of ``algo`` for benchmark env ``env``: ``<dir>/<env>/<algo>``
    of the first of :func:`rl_model_dirs` that holds a saved agent there (the shipped path if
    none does)."""
    for root in rl_model_dirs(models):
        path = root / env / algo
        if (path / "metadata.json").is_file() and (path / "model.zip").is_file():
            return path
    return MODELS_DIR / env / algo


def make_env(env: str, scenario: str, **options: Any) -> gym.Env:
    """``gym.make`` of a benchmark env (short name) in ``scenario``; ``options`` are the env's
    other keyword arguments (``randomize``, ``observation_noise``, ``true_params``, ...)."""
    check_env_scenario(env, scenario)
    return gym.make(ENVS[env].env_id, scenario=scenario, **options)


class OracleModel:
    """The oracle recipes' model source: the env's true model (``gp_envs.oracle_model``), the
    benchmark's to hand in (a class, so that the agent pickles)."""

    def __init__(self, env: gym.Env) -> None:
        self.env = env

    def __call__(self) -> Any:
        return gp_envs.oracle_model(self.env)


def make_learner(kind: str, parametric_columns: tuple[int, ...] = ()) -> Any:
    """A fresh residual learner of the recipe kind ``"exact"``, ``"ssgp"``, ``"ssgp-linear"``
    (:func:`gp_agents.online_ssgp` with linear features), ``"ssgp-adaptive"`` (linear
    features and a :class:`~gp_agents.learners.ChangeDetector`), ``"ssgp-guarded"`` (those
    and a :class:`~gp_agents.learners.NominalFallback`), ``"ssgp-saturated"`` (those and
    the input saturation :data:`~gp_agents.learners.INPUT_SATURATION`) or
    ``"ssgp-parametric"`` (:func:`gp_agents.parametric_ssgp` of ``parametric_columns``, the
    input's parameter sensitivities: the saturated one with linear features on those only)."""
    from gp_agents import online_ssgp, parametric_ssgp
    from gp_agents.learners import INPUT_SATURATION, ChangeDetector, ExactGP, NominalFallback

    if kind == "exact":
        return ExactGP()
    if kind == "ssgp":
        return online_ssgp()
    if kind == "ssgp-linear":
        return online_ssgp(linear_features=True)
    if kind == "ssgp-adaptive":
        return online_ssgp(linear_features=True, change_detector=ChangeDetector())
    if kind == "ssgp-guarded":
        return online_ssgp(linear_features=True, change_detector=ChangeDetector(),
                           nominal_fallback=NominalFallback())
    if kind == "ssgp-saturated":
        return online_ssgp(linear_features=True, change_detector=ChangeDetector(),
                           nominal_fallback=NominalFallback(), input_saturation=INPUT_SATURATION)
    if kind == "ssgp-parametric":
        return parametric_ssgp(parametric_columns)
    raise ValueError(f"unknown learner kind {kind!r}")


def build_controller(name: str, env: gym.Env, env_name: str, seed: int,
                     n_init: int = N_INITIAL_POINTS, *, data_env: gym.Env | None = None,
                     settings: dict[str, Any] | None = None,
                     options: dict[str, Any] | None = None,
                     learner: Any | None = None,
                     models: str | Path | None = None) -> BuiltController:
    """Build controller ``name`` for ``env`` and reset ``env`` with ``seed``.

    Learning recipes first collect ``n_init`` transitions with
    :func:`gp_agents.collect_initial_data` (seeded with ``seed``; it resets the env itself),
    then reset the env with ``seed``, build the agent on the episode's model and pretrain it.

    Args:
        name: controller name (:data:`CONTROLLERS`).
        env: a ``gym.make``-made benchmark env.
        env_name: its short name (key of :data:`ENVS`), for the RL model path.
        seed: the trial's seed.
        n_init: initial transitions for the learning recipes.
        data_env: the env the initial data are collected on (default ``env``).
        settings: extra :class:`gp_agents.PseudospectralMPC` settings (MPC recipes only).
        options: ``env.reset`` options of the episode (e.g. a start state).
        learner: an unfitted learner used instead of the recipe's (learning recipes only; e.g.
            ``online_ssgp(r)`` for another rank).
        models: the user's RL model directory (RL recipes; see :func:`rl_model_dirs`).

    Raises:
        UnknownNameError: unknown controller name.
        ControllerUnavailableError: e.g. no shipped RL model for this env and scenario.
    """
    check_name("controller", name, list(CONTROLLERS))
    recipe = CONTROLLERS[name]
    if recipe.family == "rl":
        return _build_rl(recipe, env, env_name, seed, options, models)
    from gp_agents import PseudospectralMPC, collect_initial_data

    if learner is not None and recipe.learner is None:
        raise ValueError(f"controller {name!r} learns nothing: it takes no learner")
    data = None
    if recipe.learner is not None:
        data = collect_initial_data(data_env or env, n_init, seed=seed)
    obs, _ = env.reset(seed=seed, options=options)
    if learner is None and recipe.learner is not None:
        learner = make_learner(recipe.learner, _parametric_columns(recipe, env, settings))
    source = OracleModel(env) if recipe.oracle else None
    agent = PseudospectralMPC.from_env(env, learner, model_source=source, mode=recipe.mode,
                                       learn_online=recipe.learn_online,
                                       **{**dict(recipe.settings), **(settings or {})})
    if data is not None:
        agent.pretrain(data)
    agent.reset()
    return BuiltController(agent, obs, len(data) if data is not None else 0,
                           {"horizon_s": agent.horizon, "mesh": agent.mesh.describe()})


def _parametric_columns(recipe: ControllerRecipe, env: gym.Env,
                        settings: dict[str, Any] | None) -> tuple[int, ...]:
    """The learner-input columns of the parameter sensitivities of ``recipe``'s MPC on
    ``env`` (empty if it has none): the residual its agent will build."""
    from gp_agents.residual import ResidualModel

    s = {**dict(recipe.settings), **(settings or {})}
    if not s.get("sensitivities", False):
        return ()
    return ResidualModel(env.unwrapped.nominal_model, s.get("uncertain_indices"),
                         s.get("input_indices"), sensitivities=True).sensitivity_columns


def _build_rl(recipe: ControllerRecipe, env: gym.Env, env_name: str, seed: int,
              options: dict[str, Any] | None = None,
              models: str | Path | None = None) -> BuiltController:
    """The RL recipe's agent: the policy of :func:`rl_model_dir` (the user's before the
    shipped one); its record names the model directory, plus ``model_source="user"`` for a
    user's model (a shipped one's record is as it always was)."""
    algo = str(recipe.algo)
    path = rl_model_dir(env_name, algo, models)
    if not (path / "metadata.json").is_file() or not (path / "model.zip").is_file():
        where = " or ".join(str(d / env_name / algo) for d in rl_model_dirs(models))
        raise ControllerUnavailableError(
            f"no {recipe.label} model for env {env_name} (looked in {where}); train one: "
            f"python -m benchmarks.train_rl --env {env_name} --algo {algo} (saves to "
            f"./{USER_MODELS_DIR}/{env_name}/{algo}; gp-bench --models DIR looks elsewhere)")
    try:
        import torch

        from gp_agents.rl import RLAgent
    except ImportError as err:  # the rl extra is not installed
        raise ControllerUnavailableError(f"RL extra not installed: {err}") from err
    torch.set_num_threads(1)
    try:
        agent = RLAgent.load(path, env)
    except ValueError as err:  # trained for another scenario / spaces
        raise ControllerUnavailableError(str(err)) from err
    obs, _ = env.reset(seed=seed, options=options)
    agent.reset()
    if path.is_relative_to(MODELS_DIR):
        source = {"model_dir": str(path.relative_to(MODELS_DIR.parent.parent))}
    else:
        source = {"model_dir": str(path), "model_source": "user"}
    return BuiltController(agent, obs, int(agent.training_steps),
                           {**source, "training_steps": int(agent.training_steps)})
