"""How fast is ``make_mpc(env)`` against the package's own real-time iteration, measured in one
interleaved run? (issue: converged quality at real-time speed, acceptance; decision record
``docs/studies/sqp_scheme.md``).

Per system (cart pole ``online``, quadrotor ``online``, Dubins ``paper``) and block (seeds
``--seeds``, randomize 0.1, as the recommended preset's cells), four controllers run one episode
each in lockstep (:func:`gp_agents.agent.rollout_lockstep`: one ``act`` of each in turn, so a change
of the machine's load hits all alike), each learner pretrained on the block's
``collect_initial_data(env, 200, seed)`` (untimed):

- ``default``: ``make_mpc(env)``, the robust recipe with its own scheme on the system
  (:data:`gp_agents.mpc.recipes.RECIPE_SCHEMES`);
- ``ipopt``: the robust recipe's converged IPOPT solve (``scheme="converged"``);
- ``robust rti``: the robust recipe's real-time iteration (``scheme="rti"``);
- ``oracle rti``: the oracle recipe's real-time iteration, the package's RTI step without a
  learned term (the issue's reference).

Per episode the median ``act`` time after the cold start; per block the ratios against the
oracle RTI; the table gives each ratio's median and min-max over blocks, and the outcomes.
Timing only: the outcomes are deterministic, the times are not (``OMP_NUM_THREADS=1``, a quiet
machine).

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.default_speed [--seeds 7100-7104]``;
writes ``benchmarks/results/default-speed/report.md``.
"""

from __future__ import annotations

import argparse
import os
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "results" / "default-speed"
SYSTEMS = {"cartpole": "online", "quadrotor": "online", "dubins": "paper"}
VARIANTS = {"default": ("robust", None), "ipopt": ("robust", "converged"),
            "robust rti": ("robust", "rti"), "oracle rti": ("oracle", "rti")}
"""Column -> (recipe, scheme; None: the recipe's own)."""
REFERENCE = "oracle rti"


def _seeds(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def measure(system: str, seed: int) -> dict[str, tuple[float, float, bool]]:
    """One block: column -> (act median after the cold start in ms, cost, success)."""
    import gymnasium as gym

    import gp_envs
    from gp_agents import collect_initial_data, make_mpc
    from gp_agents.agent import rollout_lockstep

    env_id = gp_envs.SYSTEMS[system].env_id
    pairs, names = [], []
    for name, (recipe, scheme) in VARIANTS.items():
        env = gym.make(env_id, scenario=SYSTEMS[system], randomize=0.1)
        env.reset(seed=seed)  # the block's truth draw, before the data are collected
        agent = make_mpc(env, recipe, scheme=scheme)
        if recipe != "oracle":
            agent.pretrain(collect_initial_data(env, 200, seed=seed))
        pairs.append((env, agent))
        names.append(name)
    episodes = rollout_lockstep(pairs, seed)
    return {name: (float(np.median(ep.act_times[1:]) * 1e3), float(ep.cost), bool(ep.success))
            for name, ep in zip(names, episodes, strict=True)}


def report(results: dict[str, list[dict[str, tuple[float, float, bool]]]], seeds: list[int]
           ) -> str:
    """The table: per system and column, act median (median over blocks), ratio to the
    oracle RTI (median, min-max over blocks), successes and mean cost."""
    lines = ["| system | controller | act median (ms) | / oracle RTI, median (min-max) | "
             "/ IPOPT, median (min-max) | success | mean cost |",
             "|---|---|---:|---:|---:|---|---:|"]
    for system, blocks in results.items():
        for name in VARIANTS:
            act = np.array([b[name][0] for b in blocks])
            ref = act / np.array([b[REFERENCE][0] for b in blocks])
            ipopt = act / np.array([b["ipopt"][0] for b in blocks])
            wins = sum(b[name][2] for b in blocks)
            cost = np.mean([b[name][1] for b in blocks])
            lines.append(f"| {system} | {name} | {np.median(act):.2f} | {np.median(ref):.2f} "
                         f"({ref.min():.2f}-{ref.max():.2f}) | {np.median(ipopt):.2f} "
                         f"({ipopt.min():.2f}-{ipopt.max():.2f}) | {wins}/{len(blocks)} | "
                         f"{cost:.3f} |")
    return ("# make_mpc(env) against the package's own RTI, one interleaved run\n\n"
            "`OMP_NUM_THREADS=1 python -m benchmarks.studies.default_speed --seeds "
            f"{seeds[0]}-{seeds[-1]}`\n\n" + "\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="7100-7104", help="block seeds, e.g. 7100-7104")
    parser.add_argument("--systems", default=",".join(SYSTEMS))
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    seeds = _seeds(args.seeds)
    systems = args.systems.split(",")
    unknown = sorted(set(systems) - set(SYSTEMS))
    if unknown:
        parser.error(f"unknown systems {unknown}; systems: {', '.join(SYSTEMS)}")
    from tqdm import tqdm

    results: dict[str, list[dict[str, tuple[float, float, bool]]]] = {s: [] for s in systems}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # degraded-controller warnings: counted in the outcomes
        for system, seed in tqdm([(s, k) for s in systems for k in seeds], desc="blocks"):
            results[system].append(measure(system, seed))
    text = report(results, seeds)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "report.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
