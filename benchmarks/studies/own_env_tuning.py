"""The choices the own-env preset rests on, measured on tuning seeds (``docs/studies/own_env.md``).

1. Pendulum-v1 (seeds 1000-1009): the nominal MPC with the correct model at horizons 1.5,
   2.5 and 3.5 s (the default planning of a system without an entry gives 2.5 s), and at 2.5 s
   with nominal masses 0.4, 0.5, 1.6 and 2.0 kg (the env's is 1): which error makes the nominal
   MPC clearly worse, and whether the robust recipe (100 uniform random samples) recovers it.
2. DMC cart-pole swing-up at 0.05 s (seeds 0-9): the robust recipe with 200 initial samples
   from uniform random forces (the default for a model without a data controller) against the
   cart pole's tracking controller (``gp_agents.data_policies.cartpole_data_policy``).

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.own_env_tuning`` (about 10 minutes on
one core); writes ``benchmarks/results/own-env-tuning/{episodes.csv,tables.md}``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

import gp_envs
from benchmarks.outside_envs import OUTSIDE_ENVS, pendulum_v1_model, pendulum_v1_state
from gp_agents import collect_initial_data, make_mpc, rollout
from gp_agents.defaults import register_defaults, system_defaults

ROOT = Path(__file__).resolve().parents[2]
PENDULUM_SEEDS = tuple(range(1000, 1010))
DMC_SEEDS = tuple(range(10))


def _pendulum(mass: float) -> gp_envs.ModelWrapper:
    import gymnasium as gym

    return gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_v1_model(mass), state=pendulum_v1_state)


def _episode(make_env: Callable[[], object], recipe: str, seed: int, n_init: int,
             **settings: object) -> dict[str, object]:
    env = make_env()
    agent = make_mpc(env, recipe, **settings)
    if agent.learner is not None:
        agent.pretrain(collect_initial_data(env, n_init, seed=seed))
    episode = rollout(env, agent, seed=seed)
    env.close()
    return {"return": float(np.sum(episode.rewards)), "success": bool(episode.success)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/own-env-tuning")
    args = parser.parse_args()
    rows: list[dict[str, object]] = []
    for horizon in (1.5, 2.5, 3.5):
        rows += [{"study": "pendulum-horizon", "variant": f"correct mass, horizon {horizon} s",
                  "seed": s, **_episode(lambda: _pendulum(1.0), "nominal", s, 0,
                                        horizon=horizon)} for s in PENDULUM_SEEDS]
    for mass in (0.4, 0.5, 1.6, 2.0):
        rows += [{"study": "pendulum-mass", "variant": f"nominal MPC, mass {mass} kg",
                  "seed": s, **_episode(lambda m=mass: _pendulum(m), "nominal", s, 0)}
                 for s in PENDULUM_SEEDS]
    rows += [{"study": "pendulum-mass", "variant": "robust MPC, mass 0.4 kg, 100 uniform samples",
              "seed": s, **_episode(lambda: _pendulum(0.4), "robust", s, 100)}
             for s in PENDULUM_SEEDS]
    dmc = OUTSIDE_ENVS["dmc-cartpole"].scenarios["swingup"]
    tracker = system_defaults("dmc_cartpole")
    for name, defaults in (("tracking controller", tracker),
                           ("uniform random forces", dataclasses.replace(tracker,
                                                                         data_policy=None))):
        register_defaults("dmc_cartpole", defaults)
        try:
            rows += [{"study": "dmc-data", "variant": f"robust MPC, 200 samples, {name}",
                      "seed": s, **_episode(dmc, "robust", s, 200)} for s in DMC_SEEDS]
        finally:
            register_defaults("dmc_cartpole", tracker)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "episodes.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, ["study", "variant", "seed", "return", "success"])
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| study | variant | seeds | return mean [min, max] | successes |",
             "|---|---|---:|---:|---:|"]
    for key in dict.fromkeys((r["study"], r["variant"]) for r in rows):
        group = [r for r in rows if (r["study"], r["variant"]) == key]
        ret = np.array([r["return"] for r in group], float)
        lines.append(f"| {key[0]} | {key[1]} | {group[0]['seed']}-{group[-1]['seed']} | "
                     f"{ret.mean():.1f} [{ret.min():.1f}, {ret.max():.1f}] | "
                     f"{sum(bool(r['success']) for r in group)}/{len(group)} |")
    (args.out / "tables.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
