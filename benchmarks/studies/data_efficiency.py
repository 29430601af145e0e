"""Study for issue 44 (data efficiency): the choices behind the ``blackbox`` recipe, the
learning from a handful of samples (``Residual(refit_until=...)``) and the learning transient of
the cart-pole swing-up. Decision record: ``docs/studies/data_efficiency.md``.

Runs controller variants on *tuning* seeds (:data:`TUNING_SEEDS`; the ``data-efficiency``
preset's evaluation seeds are :data:`benchmarks.presets.DATA_EFFICIENCY_SEEDS`) and prints a
table per question. Not imported by the engine or the library::

    python -m benchmarks.studies.data_efficiency --question blackbox --seeds 0-3
    python -m benchmarks.studies.data_efficiency --question refit --seeds 0-9
    python -m benchmarks.studies.data_efficiency --question transient --seeds 0-9
    python -m benchmarks.studies.data_efficiency --question transient --evaluate \
        --seeds 500-519 --variants "oracle;robust;robust, lambda 0.98;paper"

Each episode is as the preset runs it (``--data own``): ``collect_initial_data(env, n,
seed=s)`` on the system ``env.reset(seed=s)`` gives, then ``make_mpc(env, recipe,
**overrides).pretrain(data)`` (``pretrain(None)`` for 0 samples) and one episode from
``env.reset(seed=s)``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

TUNING_SEEDS = tuple(range(20))
"""Seeds the choices here were made on (the evaluation seeds are 500-519)."""
EVALUATION_SEEDS = tuple(range(500, 520))
"""Seeds the chosen variants are reported on (``--evaluate``; never used to choose)."""


@dataclass(frozen=True)
class Variant:
    """A controller variant: a recipe of :func:`gp_agents.make_mpc` and constructor overrides
    (built lazily: ``overrides`` returns fresh objects per episode)."""

    name: str
    recipe: str
    overrides: Callable[[], dict[str, Any]] = field(default=lambda: {})
    note: str = ""
    data: str = "own"
    """``"own"``: ``collect_initial_data`` (the system's data policy); ``"own+swing"``: those
    and the oracle MPC's episode from another start (data where a swing-up goes: a diagnostic
    of data coverage); ``"random"``: uniform random forces (PILCO's first trial)."""


def _learner(**kw: Any) -> Callable[[], dict[str, Any]]:
    def make() -> dict[str, Any]:
        from gp_agents import online_ssgp

        return {"learner": online_ssgp(**kw)}
    return make


def _residual(**kw: Any) -> Callable[[], dict[str, Any]]:
    def make() -> dict[str, Any]:
        from gp_agents import Residual

        return {"residual": Residual(**kw)}
    return make


def _term(max_linearizations: int = 1, exact: bool = False) -> Callable[[], dict[str, Any]]:
    def make() -> dict[str, Any]:
        from gp_agents.mpc import LinearizedGP

        return {"term": "exact" if exact else LinearizedGP(max_linearizations)}
    return make


def _parametric(**kw: Any) -> Callable[[], dict[str, Any]]:
    """The robust recipe's learner with some of its parts changed (``fallback=False``: no
    NominalFallback; other keywords: :func:`gp_agents.online_ssgp`'s)."""
    def make() -> dict[str, Any]:
        from gp_agents import online_ssgp
        from gp_agents.learners import INPUT_SATURATION, ChangeDetector, NominalFallback

        fallback = kw.get("fallback", True)
        args = {"linear_features": "sensitivities", "change_detector": ChangeDetector(),
                "nominal_fallback": NominalFallback() if fallback else None,
                "input_saturation": INPUT_SATURATION, **{k: v for k, v in kw.items()
                                                         if k != "fallback"}}
        return {"learner": online_ssgp(**args)}
    return make


def _both(*parts: Callable[[], dict[str, Any]]) -> Callable[[], dict[str, Any]]:
    def make() -> dict[str, Any]:
        out: dict[str, Any] = {}
        for p in parts:
            out.update(p())
        return out
    return make


QUESTIONS: dict[str, tuple[str, str, tuple[int, ...], tuple[Variant, ...]]] = {
    # which learner the no-prior recipe uses (GP-MPC's protocol: one random trial first)
    "blackbox": ("pilco_cartpole", "pilco", (10, 40), (
        Variant("rbf", "blackbox", _both(_learner(linear_features=False),
                                         _residual(refit_until=100)),
                "Fourier features only"),
        Variant("rbf+linear", "blackbox", _both(_learner(linear_features=True),
                                                _residual(refit_until=100)),
                "Fourier + linear features on every input (the recipe)"),
        Variant("rbf+linear, no refit", "blackbox", _both(_learner(linear_features=True),
                                                          _residual()),
                "hyperparameters frozen at the first fit"),
    )),
    # whether refitting on the first samples helps the physics-prior recipes
    "refit": ("pilco_cartpole", "pilco", (0, 2, 5, 10), (
        Variant("robust", "robust", note="the recipe"),
        Variant("robust, refit<50", "robust",
                _residual(sensitivities=True, refit_until=50)),
    )),
    # the learning transient on the cart pole `online`: oracle against the learners
    "transient": ("cartpole", "online", (200,), (
        Variant("oracle", "oracle"),
        Variant("robust", "robust", note="the recipe"),
        # how sensitive the swing-up is to any model error: the true model's parameters (but
        # gravity) all 1% / 3% high, no learning
        Variant("oracle, parameters +1%", "oracle-off-1"),
        Variant("oracle, parameters +3%", "oracle-off-3"),
        # plans with a stale expansion? (one solve per replan about the shifted plan)
        Variant("robust, relinearize x3", "robust", _term(3),
                note="up to 3 solves per replan, re-linearized about each plan"),
        Variant("robust, exact term", "robust", _term(exact=True),
                note="the learner's mean inside the NLP"),
        # plans that distrust the model? (the residual switched off)
        Variant("robust, no fallback", "robust", _parametric(fallback=False),
                note="without the NominalFallback"),
        # how the first plans weigh new data
        Variant("robust, lambda 0.98", "robust", _parametric(forgetting_factor=0.98),
                note="forgetting factor 0.98 (halves a sample's weight in 34 steps)"),
        Variant("paper", "paper"),
        # the Fourier part's share: the parametric part (dp' S) with one frequency beside it
        Variant("robust, r=1", "robust", _parametric(n_frequencies=1),
                note="the parametric part with a single Fourier frequency"),
        # data where the swing-up goes (diagnostic) and data that excite more (exploration)
        Variant("robust + a swing-up's data", "robust", data="own+swing",
                note="initial data plus the oracle's swing-up from another start"),
        Variant("robust, random-force data", "robust", data="random",
                note="PILCO's first trial: uniform random forces instead of the tracker"),
    )),
}
"""question -> (env, scenario, initial samples, variants)."""


def episode(env_name: str, scenario: str, variant: Variant, seed: int, n_init: int
            ) -> dict[str, Any]:
    """One episode of ``variant`` (module docstring); its metrics."""
    from benchmarks.controllers import make_env
    from gp_agents import make_mpc, rollout

    env = make_env(env_name, scenario)
    learning = variant.recipe not in ("nominal", "oracle") and not variant.recipe.startswith(
        "oracle-off-")
    data = _data(env, variant.data, n_init, seed) if learning and n_init else None
    env.reset(seed=seed)
    if variant.recipe.startswith("oracle-off-"):  # the true model, its parameters off by e
        import gp_envs
        from gp_agents import PseudospectralMPC

        e = float(variant.recipe.rsplit("-", 1)[1]) / 100
        truth = gp_envs.oracle_model(env)
        wrong = truth.with_params(**{k: v * (1 + e) for k, v in truth.params.items()
                                     if k != "g"})
        agent = PseudospectralMPC.from_env(env, model_source=lambda: wrong)
    else:
        agent = make_mpc(env, variant.recipe, **variant.overrides())
    if learning:
        agent.pretrain(data)
    start = time.perf_counter()
    probe = _Probe(agent)
    run = rollout(env, probe, seed)
    dt = env.unwrapped.nominal_model.dt
    info = run.final_info
    since = info.get("at_goal_since")
    success = bool(info["success"])
    pumps = _pumps(run.observations)
    first = _first_at_goal(run.infos)
    k = round(first / dt) if np.isfinite(first) else len(run.rewards)
    return {"success": success, "cost": float(run.cost),
            "at_goal_since": float(since) if success and since is not None else float("nan"),
            "interaction_s": (n_init * dt + float(since)) if success else float("nan"),
            "first_at_goal_s": first,
            # the cost until the pole first reaches the goal, and after it
            "cost_swing": -float(np.sum(run.rewards[:k])),
            "cost_hold": -float(np.sum(run.rewards[k:])),
            "pumps": pumps, **probe.summary(k), "wall_s": time.perf_counter() - start}


class _Probe:
    """The agent, and what its learner did along the episode: at each transition the learned
    residual's error against the transition's own residual target (before learning it), the
    zero residual's (the nominal model's) error, and whether the residual was on."""

    def __init__(self, agent: Any) -> None:
        self.agent = agent
        self.rows: list[tuple[float, float, bool]] = []

    def reset(self) -> None:
        self.agent.reset()

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.agent.act(obs)

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        agent = self.agent
        learner = getattr(agent, "learner", None)
        fitted = learner is not None and hasattr(learner, "n_samples_seen_")
        if learner is None or not fitted:  # no learned residual: no error to compare
            self.rows.append((float("nan"), float("nan"), True))
        else:
            residual = agent.config.residual.model(agent.model)
            z, y = residual.targets(obs[None], np.asarray(action, float)[None], next_obs[None])
            pred = learner.predict(z)
            self.rows.append((float(np.linalg.norm(pred - y)), float(np.linalg.norm(y)),
                              bool(getattr(learner, "residual_on_", True))))
        agent.observe(obs, action, next_obs)

    def summary(self, k: int) -> dict[str, float]:
        """Mean errors of the learned and the zero residual (m/s^2, rad/s^2) before step k
        (the swing-up) and after it, and the steps with the residual off."""
        if not self.rows:
            return {}
        learned, zero, on = (np.array(c) for c in zip(*self.rows, strict=True))
        def m(a: np.ndarray) -> float:
            return float(np.nanmean(a)) if np.isfinite(a).any() else float("nan")
        return {"err_learned_swing": m(learned[:k]), "err_zero_swing": m(zero[:k]),
                "err_learned_hold": m(learned[k:]), "err_zero_hold": m(zero[k:]),
                "residual_off_steps": int(np.sum(~on.astype(bool)))}


def _data(env: Any, kind: str, n: int, seed: int) -> Any:
    """The initial data of :attr:`Variant.data`."""
    from gp_agents import Transitions, collect_initial_data, make_mpc, rollout

    if kind == "own":
        return collect_initial_data(env, n, seed=seed)
    if kind == "random":
        class Random:
            def __init__(self) -> None:
                self.rng = np.random.default_rng([seed, 7])

            def reset(self) -> None:
                pass

            def act(self, obs: np.ndarray) -> np.ndarray:
                space = env.action_space
                return self.rng.uniform(space.low, space.high).astype(np.float32)

            def observe(self, *args: Any) -> None:
                pass

        X, U, Xn = [], [], []
        k = 0
        while sum(len(x) for x in X) < n:
            run = rollout(env, Random(), seed * 1000 + k, max_steps=n - sum(len(x) for x in X))
            X.append(run.observations[:-1])
            U.append(run.actions)
            Xn.append(run.observations[1:])
            k += 1
        return Transitions(np.concatenate(X), np.concatenate(U), np.concatenate(Xn))
    if kind == "own+swing":
        base = collect_initial_data(env, n, seed=seed)
        oracle = make_mpc(env, "oracle")
        run = rollout(env, oracle, seed + 1000)
        return Transitions(np.concatenate([base.X, run.observations[:-1]]),
                           np.concatenate([base.U, run.actions]),
                           np.concatenate([base.X_next, run.observations[1:]]))
    raise ValueError(f"unknown data kind {kind!r}")


def _first_at_goal(infos: list[dict[str, Any]]) -> float:
    for i in infos:
        if i.get("at_goal"):
            return float(i["time"])
    return float("nan")


def _pumps(obs: np.ndarray) -> int:
    """Swings before the pole first passes 90 degrees from hanging: sign changes of the pole's
    angular rate while it is still below the horizontal (cart poles)."""
    theta = np.mod(obs[:, 1], 2 * np.pi)
    up = np.flatnonzero(np.abs(theta - np.pi) < np.pi / 2)
    end = up[0] if up.size else len(obs)
    rate = obs[:end, 3]
    signs = np.sign(rate[np.abs(rate) > 1e-3])
    return int(np.sum(signs[1:] != signs[:-1]))


def main(argv: list[str] | None = None) -> None:
    from benchmarks.cli import parse_seeds

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--question", choices=list(QUESTIONS), required=True)
    p.add_argument("--seeds", type=parse_seeds, default=list(TUNING_SEEDS[:10]))
    p.add_argument("--n-init", type=int, nargs="*", help="override the question's sample counts")
    p.add_argument("--variants", help="semicolon-separated subset of the variants")
    p.add_argument("--out", type=Path, default=Path("benchmarks/results/data-efficiency-study"))
    p.add_argument("--evaluate", action="store_true", help="report on the evaluation seeds "
                   f"{EVALUATION_SEEDS[0]}-{EVALUATION_SEEDS[-1]} (stored apart)")
    args = p.parse_args(argv)
    allowed = EVALUATION_SEEDS if args.evaluate else TUNING_SEEDS
    if set(args.seeds) - set(allowed):
        p.error(f"seeds must be within {allowed[0]}-{allowed[-1]}"
                + ("" if args.evaluate else " (tuning seeds; --evaluate for the others)"))
    env_name, scenario, n_inits, variants = QUESTIONS[args.question]
    if args.variants:
        keep = args.variants.split(";")
        variants = tuple(v for v in variants if v.name in keep)
    n_inits = tuple(args.n_init) if args.n_init else n_inits
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / f"{args.question}{'-evaluation' if args.evaluate else ''}.jsonl"
    done = {}
    if store.exists():
        for line in store.read_text().splitlines():
            r = json.loads(line)
            done[(r["variant"], r["n_init"], r["seed"])] = r
    for n in n_inits:
        for v in variants:
            for s in args.seeds:
                if (v.name, n, s) in done:
                    continue
                r = {"variant": v.name, "n_init": n, "seed": s,
                     **episode(env_name, scenario, v, s, n)}
                done[(v.name, n, s)] = r
                with store.open("a") as f:
                    f.write(json.dumps(r) + "\n")
                print(json.dumps(r), flush=True)
    print(f"\n{args.question}: {env_name} `{scenario}`, seeds {args.seeds[0]}-{args.seeds[-1]}")
    print("| variant | n_init | success | cost mean | interaction s (mean of successes) | "
          "first at goal s | pumps | cost swing / hold | residual error swing (zero's) | "
          "residual off steps |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n in n_inits:
        for v in variants:
            rows = [done[(v.name, n, s)] for s in args.seeds if (v.name, n, s) in done]
            succ = [r for r in rows if r["success"]]
            print(f"| {v.name} | {n} | {len(succ)}/{len(rows)} | "
                  f"{np.mean([r['cost'] for r in rows]):.2f} | "
                  f"{np.nanmean([r['interaction_s'] for r in succ]) if succ else float('nan'):.2f}"
                  f" | {np.nanmean([r['first_at_goal_s'] for r in rows]):.2f} | "
                  f"{np.mean([r['pumps'] for r in rows]):.1f} | "
                  f"{np.mean([r['cost_swing'] for r in rows]):.2f} / "
                  f"{np.mean([r['cost_hold'] for r in rows]):.2f} | "
                  f"{np.nanmean([r.get('err_learned_swing', np.nan) for r in rows]):.2f} "
                  f"({np.nanmean([r.get('err_zero_swing', np.nan) for r in rows]):.2f}) | "
                  f"{np.mean([r.get('residual_off_steps', 0) for r in rows]):.1f} |")


if __name__ == "__main__":
    main()
