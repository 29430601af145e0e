"""Does the SQP scheme give the converged IPOPT solve's outcomes? (issue: converged quality at
real-time speed; decision record ``docs/studies/sqp_scheme.md``).

The robust recipe with ``scheme="sqp"`` (``robust-mpc@sqp``) against its converged IPOPT solve
(``robust-mpc@converged``) on the ``recommended`` preset's trials (randomized truth, 200
initial samples; seeds 400-419, the Dubins vehicle 400-449; the IPOPT trials run here too,
since that preset's ``robust-mpc`` is ``make_mpc(env)``, the SQP on the quadrotor and the
Dubins vehicle since this study) and on the robustness preset's robust-recipe cells on every
system, against their committed IPOPT runs (``ssgp-mpc-linearized-parametric`` in
``benchmarks/results/robustness-parametric``: fixed, randomized, noisy, perturbed and changed
systems, seeds 200-249). Nothing is tuned here: the SQP's budget and
tolerance are its defaults. Paired by trial: success, cost (mean and largest paired relative
difference), act median (the committed IPOPT runs' times come from other runs on this
machine: a rough ratio, not an interleaved timing).

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.sqp_scheme [--workers 2]`` (resumable:
finished trials are kept); writes ``benchmarks/results/sqp-scheme/{metrics.csv,tables.md}``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from benchmarks.presets import PRESETS
from benchmarks.studies.study_runs import read_metrics, run_and_record, success_text, write_tables
from benchmarks.trial import TrialSpec

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "results" / "sqp-scheme"
SQP = "robust-mpc@sqp"
IPOPT = "robust-mpc@converged"
REFERENCES = ("robustness-parametric",)
"""Committed runs of the robust recipe's converged IPOPT solve the study pairs with (the
others' IPOPT trials it runs itself)."""


def specs() -> list[tuple[str, TrialSpec, TrialSpec]]:
    """(preset, its IPOPT trial, the same trial with the SQP scheme)."""
    out = []
    for spec in PRESETS["recommended"].experiments[0].specs:
        if spec.controller == "robust-mpc":
            out.append(("recommended", dataclasses.replace(spec, controller=IPOPT),
                        dataclasses.replace(spec, controller=SQP)))
    for spec in PRESETS["robustness"].experiments[0].specs:
        if spec.controller == "ssgp-mpc-linearized-parametric":
            out.append(("robustness-parametric", spec, dataclasses.replace(spec, controller=SQP)))
    return out


def tables(pairs: list[tuple[str, TrialSpec, TrialSpec]], ours: dict[str, dict[str, str]]
           ) -> str:
    """The paired comparison, one row per (preset, env, scenario, cell)."""
    refs = {folder: read_metrics(ROOT / "benchmarks" / "results" / folder / "metrics.csv")
            for folder in REFERENCES}
    groups: dict[tuple[str, str, str, str], list[tuple[dict, dict]]] = defaultdict(list)
    for folder, ipopt, sqp in pairs:
        a, b = refs.get(folder, ours).get(ipopt.key), ours.get(sqp.key)
        if a is None or b is None or b.get("status") != "ok":
            continue
        groups[(folder, a["env"], a["scenario"], a["cell"])].append((a, b))
    lines = ["| run | env | scenario | cell | n | success IPOPT | success SQP | mean cost "
             "IPOPT | mean cost SQP | difference | largest paired difference | act median "
             "IPOPT (ms) | act median SQP (ms) | SQP plans that fell back to IPOPT |",
             "|---|---|---|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for (folder, env, scenario, cell), items in sorted(groups.items()):
        n = len(items)
        succ = [sum(r["success"] == "True" for r in side) for side in zip(*items, strict=True)]
        cost = [np.array([float(r["cost"]) for r in side]) for side in zip(*items, strict=True)]
        act = [np.median([float(r["act_median_ms"]) for r in side])
               for side in zip(*items, strict=True)]
        ratio = cost[1] / cost[0] - 1.0
        fell = sum(int(float(b["solves"])) - 1 for _, b in items)  # the cold starts aside
        plans = sum(int(b["steps"]) for _, b in items)

        lines.append(
            f"| {folder} | {env} | `{scenario}` | {cell} | {n} | {success_text(succ[0], n)} | "
            f"{success_text(succ[1], n)} | "
            f"{cost[0].mean():.3f} | {cost[1].mean():.3f} | "
            f"{100 * (cost[1].mean() / cost[0].mean() - 1):+.2f}% | "
            f"{100 * float(np.max(np.abs(ratio))) if n else math.nan:.2f}% | {act[0]:.2f} | "
            f"{act[1]:.2f} | {fell} of {plans} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    pairs = specs()
    own = [ipopt for folder, ipopt, _ in pairs if folder not in REFERENCES]
    ours = run_and_record([*own, *(sqp for _, _, sqp in pairs)], args.out, args.workers)
    text = write_tables(args.out,
                        "The SQP scheme against the converged IPOPT solve (robust recipe)",
                        "OMP_NUM_THREADS=1 python -m benchmarks.studies.sqp_scheme",
                        tables(pairs, ours))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
