"""Every controller and every env of the benchmark suite, in one place.

A controller is named by a short string and built for one env and seed by
:func:`build_controller`. The names compose (:func:`controller_name`):

- ``<recipe>-mpc[@<scheme>]``: the MPC recipe of :data:`gp_agents.RECIPES` (``robust``,
  ``paper``, ``nominal``, ``oracle``, ``blackbox``, ``parametric``) built by
  :func:`gp_agents.make_mpc`, with the recipe's own scheme on the env (no suffix: what
  ``make_mpc(env, recipe)`` gives, :data:`gp_agents.mpc.recipes.RECIPE_SCHEMES`) or the
  scheme ``converged`` (IPOPT), ``sqp``, ``rti`` or ``rti-split``: ``robust-mpc``,
  ``robust-mpc@converged``, ``paper-mpc@rti-split``;
- the RL algorithms ``sac``, ``ppo``, ``tqc`` (the shipped stable-baselines3 policies,
  :class:`gp_agents.rl.RLAgent`; a missing model, or one trained for another scenario, makes the
  controller *unavailable* for that env, which the runner records instead of crashing);
- study variants under their own names (:mod:`benchmarks.studies.variants`: the offline GP,
  the episodic plans, the speed and residual variants of the paper's recipe, the RTI's other
  learned terms, the warm-dual converged references), which earlier studies decided on; that
  module registers them (:func:`register_controller`) when the registry first needs them
  (:func:`load_study_variants`), so importing the engine imports no study.

Every name the suite used before the recipes had names (``ssgp-mpc``,
``ssgp-mpc-linearized-parametric``, ``nominal-mpc-rti``, ...) stays a working alias
(:data:`ALIASES`), with its label, so that committed results load and reproduce.

MPCs are built after ``env.reset``, so they plan with the episode's nominal model (for the
Dubins scenario that model is redrawn at every reset).

RL recipes load a stable-baselines3 policy ``<env>/<algo>/`` (:class:`gp_agents.rl.RLAgent`)
from the first model directory of :func:`rl_model_dirs` that has one: the user's (``gp-bench
--models DIR``, else ``./benchmarks/models`` under the current directory, where
``python -m benchmarks.rl.train`` saves), then the shipped ones (:data:`MODELS_DIR`, package
data, so a non-editable install has them).
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

import gp_envs
from benchmarks import USER_MODELS_DIR
from benchmarks.outside_envs import OUTSIDE_ENVS, OutsideEnv
from benchmarks.systems import benchmark_system
from gp_agents.mpc import RECIPES, make_mpc
from gp_agents.mpc.config import default_term
from gp_agents.mpc.recipes import RECIPE_SCHEMES, OracleModel, recipe_settings
from gp_agents.mpc.settings import SCHEME_NAMES
from gp_envs.systems import SYSTEMS

MODELS_DIR = Path(__file__).resolve().parent / "models"
"""Where the shipped RL policies live: ``<env short name>/<algo>/`` inside the installed package
(``[tool.setuptools.package-data]`` in ``pyproject.toml`` ships them)."""


N_INITIAL_POINTS = 200
"""Initial transitions collected for the learning MPCs (paper: 200 points)."""


@dataclass(frozen=True)
class EnvInfo:
    """A benchmark env: registered id (None for an outside env) and the scenarios the suite
    runs; ``outside``: the outside simulator's entry (:mod:`benchmarks.outside_envs`), or None
    for a ``gp_envs`` system."""

    env_id: str | None
    scenarios: tuple[str, ...]
    default_scenario: str
    outside: OutsideEnv | None = None


class _BenchmarkEnvs(Mapping[str, EnvInfo]):
    """The registered systems (:data:`gp_envs.SYSTEMS`) and the outside envs
    (:data:`benchmarks.outside_envs.OUTSIDE_ENVS`) as benchmark envs, by short name (live: a
    system registered after import is a benchmark env too)."""

    def __getitem__(self, name: str) -> EnvInfo:
        if name in OUTSIDE_ENVS:
            outside = OUTSIDE_ENVS[name]
            return EnvInfo(None, tuple(outside.scenarios), outside.default_scenario, outside)
        system = SYSTEMS[name]
        scenarios = benchmark_system(name).scenarios or system.scenarios
        return EnvInfo(system.env_id, scenarios, system.default_scenario)

    def __iter__(self) -> Iterator[str]:
        return iter([*SYSTEMS, *OUTSIDE_ENVS])

    def __len__(self) -> int:
        return len(SYSTEMS) + len(OUTSIDE_ENVS)


ENVS: Mapping[str, EnvInfo] = _BenchmarkEnvs()
"""Benchmark envs by short name: every registered system (:func:`gp_envs.register_system`) and
every outside env (:mod:`benchmarks.outside_envs`)."""


@dataclass(frozen=True)
class ControllerRecipe:
    """How to build one named controller.

    Attributes:
        name: registry key.
        label: display name in tables and plots.
        family: ``"mpc"`` or ``"rl"``.
        description: one line for ``--list-controllers`` and reports.
        learner: ``None``, ``"exact"`` (offline :class:`ExactGP`) or an SSGP kind of
            :func:`make_learner`; MPC only.
        oracle: plan with the true model (upper bound); MPC only.
        mode: ``"receding"`` or ``"episodic"``; MPC only.
        learn_online: feed closed-loop transitions to the learner; MPC only.
        algo: ``"sac"``, ``"ppo"`` or ``"tqc"``; RL only.
        settings: constructor settings of :class:`gp_agents.PseudospectralMPC` as
            ``(name, value)`` pairs (the study variants); MPC only.
        recipe: the :data:`gp_agents.RECIPES` name it is built from (:func:`gp_agents.make_mpc`;
            None: the study variants, built from their own settings).
        scheme: the scheme of a recipe-built controller (``"converged"``, ``"sqp"``,
            ``"rti"``, ``"rti-split"``; None: the recipe's own on the env, as
            ``make_mpc(env, recipe)`` without ``scheme``); a study variant's is
            ``"converged"`` unless its settings say otherwise.
        alias_of: the composed name this older name stands for (None: a main or study name).
        main: listed first by ``--list-controllers`` (the recipes and RL algorithms).
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
    recipe: str | None = None
    scheme: str | None = "converged"
    alias_of: str | None = None
    main: bool = False

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


def controller_name(recipe: str, scheme: str | None = None) -> str:
    """The composed controller name of an MPC recipe and scheme (None: the recipe's own on
    the env): ``robust-mpc``, ``robust-mpc@converged``, ``paper-mpc@rti-split``."""
    return f"{recipe}-mpc" + ("" if scheme is None else f"@{scheme}")


_RECIPE_LEARNERS = {"robust": "ssgp-parametric", "paper": "ssgp", "nominal": None,
                    "oracle": None, "blackbox": "ssgp-blackbox", "parametric": "rls-parametric"}
_RECIPE_LABELS = {"robust": "robust", "paper": "paper", "nominal": "nominal", "oracle": "oracle",
                  "blackbox": "black-box", "parametric": "parametric"}
_SCHEME_LABELS = {None: "", "converged": ", IPOPT", "sqp": ", SQP", "rti": ", RTI",
                  "rti-split": ", RTI split"}


def _recipe_controllers() -> dict[str, ControllerRecipe]:
    """``<recipe>-mpc[@<scheme>]`` for every library recipe and scheme (and none: the
    recipe's own)."""
    out = {}
    for recipe, description in RECIPES.items():
        learner = _RECIPE_LEARNERS[recipe]
        for scheme in (None, *SCHEME_NAMES):
            if scheme == "converged" and recipe not in RECIPE_SCHEMES:
                continue  # its own scheme is the converged one everywhere: no second name
            name = controller_name(recipe, scheme)
            tail = ("" if scheme is None else " (converged: IPOPT)" if scheme == "converged"
                    else f" ({scheme})")
            out[name] = ControllerRecipe(
                name, f"{_RECIPE_LABELS[recipe]} MPC{_SCHEME_LABELS[scheme]}", "mpc",
                description + tail, learner=learner, oracle=recipe == "oracle",
                learn_online=learner is not None, recipe=recipe, scheme=scheme,
                main=scheme is None)
    return out


ALIASES: dict[str, tuple[str, str]] = {
    "ssgp-mpc": ("paper-mpc", "SSGP MPC"),
    "ssgp-mpc-linearized-parametric": ("robust-mpc@converged",
                                       "SSGP MPC, linearized, parametric"),
    "nominal-mpc-rti": ("nominal-mpc@rti", "nominal MPC, RTI"),
    "oracle-mpc-rti": ("oracle-mpc@rti", "oracle MPC, RTI"),
    "ssgp-mpc-rti": ("paper-mpc@rti", "SSGP MPC, RTI"),
    "ssgp-mpc-rti-parametric": ("robust-mpc@rti", "SSGP MPC, RTI parametric"),
    "nominal-mpc-rti-split": ("nominal-mpc@rti-split", "nominal MPC, RTI, split"),
    "oracle-mpc-rti-split": ("oracle-mpc@rti-split", "oracle MPC, RTI, split"),
    "ssgp-mpc-rti-split": ("paper-mpc@rti-split", "SSGP MPC, RTI, split"),
    "ssgp-mpc-rti-parametric-split": ("robust-mpc@rti-split", "SSGP MPC, RTI parametric, split"),
}
"""Every older name of a recipe-built controller: ``old -> (composed name, old label)``. Frozen:
committed results and presets use these names, and build exactly the composed controller."""


def learned_term(recipe: ControllerRecipe, system: str) -> str | None:
    """The ``term`` name ``recipe``'s MPC uses on the benchmark env ``system`` (its own
    setting, else its recipe's on that env, an outside env's truth being outside its model's
    family, else :func:`gp_agents.mpc.config.default_term` of its scheme and the system's
    tuning), or None for a recipe with no learner."""
    if recipe.learner is None:
        return None
    settings = dict(recipe.settings)
    if recipe.recipe is not None:
        settings.update(recipe_settings(recipe.recipe, recipe.scheme, system,
                                        outside=system in OUTSIDE_ENVS))
    term = settings.get("term")
    if term is not None:
        return term if isinstance(term, str) else type(term).__name__
    scheme = settings.get("scheme", recipe.scheme)
    name = scheme if isinstance(scheme, str) else scheme.name
    return default_term(name, system)


def _main_and_aliases() -> dict[str, ControllerRecipe]:
    main = _recipe_controllers()
    aliases = {old: dataclasses.replace(main[new], name=old, label=label, alias_of=new,
                                        main=False, description=f"= {new}")
               for old, (new, label) in ALIASES.items()}
    return {**main, **aliases}


_BUILT_IN: dict[str, ControllerRecipe] = {
    **_main_and_aliases(),
    "sac": ControllerRecipe("sac", "SAC", "rl", "shipped stable-baselines3 SAC policy",
                            algo="sac", main=True),
    "ppo": ControllerRecipe("ppo", "PPO", "rl", "shipped stable-baselines3 PPO policy",
                            algo="ppo", main=True),
    "tqc": ControllerRecipe("tqc", "TQC", "rl", "shipped sb3-contrib TQC policy", algo="tqc",
                            main=True),
}

STUDY_VARIANTS_MODULE = "benchmarks.studies.variants"
"""The module that registers the study variants (:func:`load_study_variants`)."""
_study_variants = {"loaded": False}


def load_study_variants() -> bool:
    """Register the study variants (import :data:`STUDY_VARIANTS_MODULE` once, which calls
    :func:`register_controller` for each); True if this call registered them. The registry
    calls it itself the first time it is asked for a name it does not hold or for its whole
    list, so that importing the engine imports no study. An installed package has no studies
    (they run from a checkout): there the registry holds the main, older and RL names only."""
    if _study_variants["loaded"]:
        return False
    _study_variants["loaded"] = True
    try:
        importlib.import_module(STUDY_VARIANTS_MODULE)
    except ModuleNotFoundError as error:
        if error.name is None or not STUDY_VARIANTS_MODULE.startswith(error.name):
            _study_variants["loaded"] = False
            raise
        return False  # not installed: no study variants
    except BaseException:
        _study_variants["loaded"] = False
        raise
    return True


class _Registry(Mapping[str, ControllerRecipe]):
    """The controller registry: the built-in controllers, then whatever
    :func:`register_controller` adds; the study variants are loaded on first need
    (:func:`load_study_variants`): a name it does not hold, or its whole list."""

    def __init__(self, controllers: Mapping[str, ControllerRecipe]) -> None:
        self._controllers = dict(controllers)

    def __getitem__(self, name: str) -> ControllerRecipe:
        if name not in self._controllers:
            load_study_variants()
        return self._controllers[name]

    def __iter__(self) -> Iterator[str]:
        load_study_variants()
        return iter(self._controllers)

    def __len__(self) -> int:
        load_study_variants()
        return len(self._controllers)

    def add(self, name: str, recipe: ControllerRecipe) -> None:
        self._controllers[name] = recipe


CONTROLLERS: Mapping[str, ControllerRecipe] = _Registry(_BUILT_IN)
"""The controller registry: every name (main, aliases, RL, and the study variants, which
:mod:`benchmarks.studies.variants` registers when first needed)."""
RL_ALGORITHMS = tuple(name for name, r in _BUILT_IN.items() if r.family == "rl")
"""The RL recipes (``"sac"``, ``"ppo"``, ``"tqc"``): each loads its shipped policy where one
exists for the env."""


def register_controller(name: str, recipe: ControllerRecipe) -> None:
    """Add controller ``name``, built by ``recipe``, to :data:`CONTROLLERS` (how the study
    variants are registered; ``gp-bench --controllers NAME`` and the presets can then name it).

    Raises:
        ValueError: ``recipe.name`` is not ``name``, or ``name`` is taken by another recipe.
    """
    if recipe.name != name:
        raise ValueError(f"register_controller({name!r}): the recipe is named {recipe.name!r}")
    registry = CONTROLLERS._controllers  # type: ignore[attr-defined]
    if registry.get(name, recipe) != recipe:
        raise ValueError(f"controller {name!r} is already registered with another recipe")
    CONTROLLERS.add(name, recipe)  # type: ignore[attr-defined]


class UnknownNameError(ValueError):
    """An unknown controller, env, scenario or preset name (the message lists valid names)."""


class ControllerUnavailableError(RuntimeError):
    """The controller cannot run on this env/scenario (e.g. no shipped RL model)."""


def check_name(kind: str, name: str, valid: Any) -> None:
    """Raise :class:`UnknownNameError` listing ``valid`` when ``name`` is not among them (for a
    controller ``<known MPC>@<scheme>`` with a scheme that is not one, the schemes instead)."""
    if name in valid:
        return
    if kind == "controller":
        _check_scheme_suffix(name)
    raise UnknownNameError(f"unknown {kind} {name!r}; valid {kind}s: {', '.join(valid)}")


def _check_scheme_suffix(name: str) -> None:
    """Raise :class:`UnknownNameError` naming the schemes when ``name`` is a known MPC's name
    with an ``@<scheme>`` suffix that composes no controller (``robust-mpc@fast``)."""
    base, at, scheme = name.partition("@")
    recipe = CONTROLLERS.get(base)
    if not at or recipe is None or recipe.recipe is None:
        return
    suffixes = list(SCHEME_NAMES)
    composed = controller_name(recipe.recipe, scheme) if scheme in SCHEME_NAMES else None
    if recipe.alias_of is not None and composed is not None:
        raise UnknownNameError(f"unknown controller {name!r}: {base!r} is an older name of "
                               f"{recipe.alias_of!r}; use {composed!r}")
    if scheme == "converged":
        raise UnknownNameError(f"unknown controller {name!r}: the {recipe.recipe} recipe's own "
                               f"scheme is the converged one; use {base!r}")
    raise UnknownNameError(f"unknown scheme {scheme!r} of controller {base!r} (schemes: "
                           f"{', '.join(suffixes)}, as {base}@{suffixes[1]}; the recipe's "
                           "own: no suffix)")


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
        data: the initial transitions the learner was pretrained on (None: none).
    """

    agent: Any
    obs: Any
    prior_data_steps: int
    info: dict[str, Any]
    data: Any = None


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
                                    "benchmarks.rl.train writes ./benchmarks/models/<env>/<algo>)")
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


def rl_models(models: str | Path | None = None) -> dict[str, dict[str, Path]]:
    """The saved RL policies the RL recipes find, ``{algo: {env: model directory}}`` for each of
    :data:`RL_ALGORITHMS` (the first of :func:`rl_model_dirs` that has one wins, as in
    :func:`rl_model_dir`): on which envs each RL controller can run."""
    found: dict[str, dict[str, Path]] = {algo: {} for algo in RL_ALGORITHMS}
    for root in reversed(rl_model_dirs(models)):  # the user's replace the shipped ones
        for path in root.glob("*/*/model.zip"):
            env, algo = path.parent.parent.name, path.parent.name
            if algo in found and (path.parent / "metadata.json").is_file():
                found[algo][env] = path.parent
    return {algo: dict(sorted(envs.items())) for algo, envs in found.items()}


def make_env(env: str, scenario: str, **options: Any) -> gym.Env:
    """``gym.make`` of a benchmark env (short name) in ``scenario``; ``options`` are the env's
    other keyword arguments (``randomize``, ``observation_noise``, ``true_params``, ...).

    Raises:
        ValueError: for an outside env (:mod:`benchmarks.outside_envs`), any option that would
            change its truth or its observations (its simulator's truth is its own: none
            applies; zeros and the defaults are fine).
    """
    check_env_scenario(env, scenario)
    info = ENVS[env]
    if info.outside is not None:
        # zeros, None and time_varying (an outside env has no scenario changes) change nothing
        given = {k: v for k, v in options.items() if k != "time_varying" and v is not None
                 and not (isinstance(v, (int, float)) and not isinstance(v, bool) and v == 0)}
        if given:
            raise ValueError(f"env {env} is an outside simulator ({info.outside.description}): "
                             f"{', '.join(sorted(given))} cannot apply to it (its truth is "
                             f"its own; use a gp_envs env to randomize, change or hide one)")
        return info.outside.make(scenario)
    return gym.make(info.env_id, scenario=scenario, **options)


def scenario_changes(env: str, scenario: str) -> tuple[Any, ...]:
    """The step changes of the truth in ``scenario`` of benchmark env ``env``
    (:class:`gp_envs.base.ParamChange`; none for an outside env, whose truth is its own)."""
    check_env_scenario(env, scenario)
    if ENVS[env].outside is not None:
        return ()
    return tuple(SYSTEMS[env].env_class().SCENARIOS[scenario].changes)


def make_learner(kind: str, parametric_columns: tuple[int, ...] = ()) -> Any:
    """A fresh residual learner of the recipe kind ``"exact"``, ``"ssgp"``, ``"ssgp-linear"``
    (:func:`gp_agents.online_ssgp` with linear features), ``"ssgp-adaptive"`` (linear
    features and a :class:`~gp_agents.learners.ChangeDetector`), ``"ssgp-guarded"`` (those
    and a :class:`~gp_agents.learners.NominalFallback`), ``"ssgp-saturated"`` (those and
    the input saturation :data:`~gp_agents.learners.INPUT_SATURATION`) or
    ``"ssgp-parametric"`` (:func:`gp_agents.parametric_ssgp`: the saturated one with linear
    features on the parameter sensitivities only, ``parametric_columns`` or, if empty, those
    of the MPC it is given to), ``"ssgp-blackbox"`` (the black-box recipe's) or
    ``"rls-parametric"`` (:func:`gp_agents.learners.parametric_rls`, the parametric recipe's:
    recursive least squares on the parameter sensitivities alone, no GP)."""
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
        return parametric_ssgp(parametric_columns or None)
    if kind == "rls-parametric":
        from gp_agents.learners import parametric_rls

        return parametric_rls(parametric_columns or None)
    if kind == "ssgp-blackbox":
        from gp_agents.mpc.recipes import BLACKBOX_LINEAR_FEATURES

        return online_ssgp(linear_features=BLACKBOX_LINEAR_FEATURES)
    raise ValueError(f"unknown learner kind {kind!r}")


def build_controller(name: str, env: gym.Env, env_name: str, seed: int,
                     n_init: int = N_INITIAL_POINTS, *, data_env: gym.Env | None = None,
                     settings: dict[str, Any] | None = None,
                     options: dict[str, Any] | None = None,
                     learner: Any | None = None, same_system: bool = False,
                     models: str | Path | None = None) -> BuiltController:
    """Build controller ``name`` for ``env`` and reset ``env`` with ``seed``.

    Learning recipes first collect ``n_init`` transitions with
    :func:`gp_agents.collect_initial_data` on ``data_env`` (seeded with ``seed``), then reset
    the env with ``seed``, build the agent on the episode's model and pretrain it.

    Args:
        name: controller name (:data:`CONTROLLERS`).
        env: a ``gym.make``-made benchmark env.
        env_name: its short name (key of :data:`ENVS`), for the RL model path.
        seed: the trial's seed.
        n_init: initial transitions for the learning recipes; 0: none, the learner is fitted
            on the episode's first transitions (``agent.pretrain(None)``).
        data_env: the env the initial data are collected on (default ``env``).
        settings: constructor settings of :class:`gp_agents.PseudospectralMPC` that replace
            the recipe's (MPC recipes only).
        options: ``env.reset`` options of the episode (e.g. a start state).
        learner: an unfitted learner used instead of the recipe's (learning recipes only; e.g.
            ``online_ssgp(r)`` for another rank).
        same_system: collect the data as a user does, on the system ``env.reset(seed=seed)``
            gives (``collect_initial_data``'s default); False (the presets): each data episode
            a reset of its own with seed ``seed * 1000 + k``, the data env already being the
            system the trial's cell asks for.
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
    if recipe.learner is not None and n_init > 0:
        data = collect_initial_data(data_env or env, n_init, seed=seed, same_system=same_system)
    obs, _ = env.reset(seed=seed, options=options)
    if recipe.oracle or recipe.recipe == "oracle":
        try:
            gp_envs.oracle_model(env)
        except ValueError as err:  # an outside simulator's truth is not a model
            raise ControllerUnavailableError(str(err)) from None
    overrides = dict(settings or {})
    if learner is not None:
        overrides["learner"] = learner
    if recipe.recipe is not None:
        agent = make_mpc(env, recipe.recipe, scheme=recipe.scheme, **overrides)
    else:
        own = {**dict(recipe.settings), **overrides}
        if "learner" not in own and recipe.learner is not None:
            own["learner"] = make_learner(recipe.learner)
        agent = PseudospectralMPC.from_env(
            env, own.pop("learner", None),
            model_source=OracleModel(env) if recipe.oracle else None, **own)
    if recipe.learner is not None:
        agent.pretrain(data)  # None (n_init 0): learned from the episode's first step
    agent.reset()
    return BuiltController(agent, obs, len(data) if data is not None else 0,
                           {"horizon_s": agent.config.schedule.horizon,
                            "mesh": agent.config.schedule.mesh(agent.model.dt).describe()},
                           data)


def _build_rl(recipe: ControllerRecipe, env: gym.Env, env_name: str, seed: int,
              options: dict[str, Any] | None = None,
              models: str | Path | None = None) -> BuiltController:
    """The RL recipe's agent: the policy of :func:`rl_model_dir` (the user's before the
    shipped one); its record names the model directory, plus ``model_source="user"`` for a
    user's model (a shipped one's record is as it always was)."""
    algo = str(recipe.algo)
    path = rl_model_dir(env_name, algo, models)  # an outside env's too: trained the same way
    if not (path / "metadata.json").is_file() or not (path / "model.zip").is_file():
        where = " or ".join(str(d / env_name / algo) for d in rl_model_dirs(models))
        raise ControllerUnavailableError(
            f"no {recipe.label} model for env {env_name} (looked in {where}); train one: "
            f"python -m benchmarks.rl.train --env {env_name} --algo {algo} (saves to "
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
