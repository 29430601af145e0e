"""Study for issue 44 (data efficiency): the choices behind the ``blackbox`` recipe, the
learning from a handful of samples (``Residual(refit_until=...)``) and the learning transient of
the cart-pole swing-up. Decision record: ``docs/studies/data_efficiency.md``.

Runs controller variants on *tuning* seeds (:data:`TUNING_SEEDS`; the ``data-efficiency``
preset's evaluation seeds are :data:`benchmarks.presets.DATA_EFFICIENCY_SEEDS`) and prints a
table per question. Not imported by the engine or the library::

    python -m benchmarks.studies.data_efficiency --question blackbox --seeds 0-3
    python -m benchmarks.studies.data_efficiency --question refit --seeds 0-9
    python -m benchmarks.studies.data_efficiency --question transient --seeds 0-9

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


@dataclass(frozen=True)
class Variant:
    """A controller variant: a recipe of :func:`gp_agents.make_mpc` and constructor overrides
    (built lazily: ``overrides`` returns fresh objects per episode)."""

    name: str
    recipe: str
    overrides: Callable[[], dict[str, Any]] = field(default=lambda: {})
    note: str = ""


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
        Variant("nominal", "nominal"),
        Variant("robust", "robust", note="the recipe"),
        Variant("paper", "paper"),
    )),
}
"""question -> (env, scenario, initial samples, variants)."""


def episode(env_name: str, scenario: str, variant: Variant, seed: int, n_init: int
            ) -> dict[str, Any]:
    """One episode of ``variant`` (module docstring); its metrics."""
    from benchmarks.controllers import make_env
    from gp_agents import collect_initial_data, make_mpc, rollout

    env = make_env(env_name, scenario)
    learning = variant.recipe not in ("nominal", "oracle")
    data = collect_initial_data(env, n_init, seed=seed) if learning and n_init else None
    env.reset(seed=seed)
    agent = make_mpc(env, variant.recipe, **variant.overrides())
    if learning:
        agent.pretrain(data)
    start = time.perf_counter()
    run = rollout(env, agent, seed)
    dt = env.unwrapped.nominal_model.dt
    info = run.final_info
    since = info.get("at_goal_since")
    success = bool(info["success"])
    pumps = _pumps(run.observations)
    return {"success": success, "cost": float(run.cost),
            "at_goal_since": float(since) if success and since is not None else float("nan"),
            "interaction_s": (n_init * dt + float(since)) if success else float("nan"),
            "first_at_goal_s": _first_at_goal(run.infos),
            "pumps": pumps, "wall_s": time.perf_counter() - start}


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
    p.add_argument("--variants", help="comma-separated subset of the variants")
    p.add_argument("--out", type=Path, default=Path("benchmarks/results/data-efficiency-study"))
    args = p.parse_args(argv)
    if set(args.seeds) - set(TUNING_SEEDS):
        p.error(f"tune on the tuning seeds {TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]} only")
    env_name, scenario, n_inits, variants = QUESTIONS[args.question]
    if args.variants:
        keep = args.variants.split(",")
        variants = tuple(v for v in variants if v.name in keep)
    n_inits = tuple(args.n_init) if args.n_init else n_inits
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / f"{args.question}.jsonl"
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
          "first at goal s | pumps |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for n in n_inits:
        for v in variants:
            rows = [done[(v.name, n, s)] for s in args.seeds if (v.name, n, s) in done]
            succ = [r for r in rows if r["success"]]
            print(f"| {v.name} | {n} | {len(succ)}/{len(rows)} | "
                  f"{np.mean([r['cost'] for r in rows]):.2f} | "
                  f"{np.nanmean([r['interaction_s'] for r in succ]) if succ else float('nan'):.2f}"
                  f" | {np.nanmean([r['first_at_goal_s'] for r in rows]):.2f} | "
                  f"{np.mean([r['pumps'] for r in rows]):.1f} |")


if __name__ == "__main__":
    main()
