"""What does the GP add to re-identifying the nominal model's parameters online? The grey-box
baseline ``parametric-mpc`` on the robustness preset's trials of the robust recipe (issue:
every baseline at its best; record ``docs/studies/grey_box.md``).

``parametric-mpc`` is the robust recipe's data, term and scheme with its learner's parametric
part alone (:func:`gp_agents.parametric_rls`: recursive least squares on the parameter
sensitivities, no Fourier features, no change detector, nominal fallback or input saturation).
It runs on exactly the committed trials of the robust recipe at its 200 initial samples: the
``recommended`` preset's (randomized truth, seeds 400-419, the Dubins vehicle 400-449;
``benchmarks/results/recommended``: ``make_mpc(env)``, the SQP on the quadrotor and the Dubins
vehicle) and the robustness preset's
(``ssgp-mpc-linearized-parametric`` in ``benchmarks/results/robustness-parametric``: fixed,
randomized with the controlled system's data and with another draw's, perturbed, noisy and
changing systems, seeds 200-219, the Dubins vehicle 200-249). Nothing is tuned here. Paired
by trial: success with Wilson intervals, mean cost with BCa intervals, and where the two differ
beyond their intervals.

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.grey_box [--workers 2]`` (resumable:
finished trials are kept); writes ``benchmarks/results/grey-box/{metrics.csv,tables.md}``.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections import defaultdict
from pathlib import Path

import numpy as np

from benchmarks.presets import PRESETS
from benchmarks.report.stats import mean_ci, wilson_ci
from benchmarks.studies.study_runs import read_metrics, run_and_record, success_text, write_tables
from benchmarks.trial import N_INITIAL_POINTS, TrialSpec

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "results" / "grey-box"
REFERENCES = {"recommended": "robust-mpc",
              "robustness-parametric": "ssgp-mpc-linearized-parametric"}
"""Committed runs of the robust recipe (folders under ``benchmarks/results``) and its name in
each (the robustness run's is an alias of ``robust-mpc``)."""
GREY_BOX = "parametric-mpc"


def specs() -> list[tuple[str, TrialSpec, TrialSpec]]:
    """(reference folder, the committed robust-recipe trial, the same trial with the grey-box
    baseline)."""
    out = []
    for folder, preset in (("recommended", "recommended"),
                           ("robustness-parametric", "robustness")):
        out += [(folder, spec, dataclasses.replace(spec, controller=GREY_BOX))
                for spec in PRESETS[preset].experiments[0].specs
                if spec.controller == REFERENCES[folder] and spec.n_init == N_INITIAL_POINTS]
    return out


def _verdict(a: tuple[float, float], b: tuple[float, float], lower_better: bool) -> str:
    """Which side is ahead where the intervals do not overlap."""
    if a[1] < b[0]:
        return "robust" if lower_better else "grey box"
    if b[1] < a[0]:
        return "grey box" if lower_better else "robust"
    return "overlap"


def tables(pairs: list[tuple[str, TrialSpec, TrialSpec]], ours: dict[str, dict[str, str]]
           ) -> str:
    """One row per (run, env, scenario, cell), paired by trial."""
    refs = {folder: read_metrics(ROOT / "benchmarks" / "results" / folder / "metrics.csv")
            for folder in REFERENCES}
    groups: dict[tuple[str, str, str, str], list[tuple[dict, dict]]] = defaultdict(list)
    for folder, robust, grey in pairs:
        a, b = refs[folder].get(robust.key), ours.get(grey.key)
        if a is None or b is None or b.get("status") != "ok" or a.get("status") != "ok":
            continue
        groups[(folder, a["env"], a["scenario"], a["cell"])].append((a, b))
    lines = ["| run | env | scenario | cell | n | success robust | success grey box | "
             "success ahead | mean cost robust | mean cost grey box | cost ahead |",
             "|---|---|---|---|---:|---|---|---|---:|---:|---|"]
    for (folder, env, scenario, cell), items in sorted(groups.items()):
        n = len(items)
        k = [sum(r["success"] == "True" for r in side) for side in zip(*items, strict=True)]
        cost = [np.array([float(r["cost"]) for r in side]) for side in zip(*items, strict=True)]
        s_ci = [wilson_ci(x, n) for x in k]
        c_ci = [mean_ci(c) for c in cost]

        s = [success_text(k[i], n) for i in range(2)]
        c = [f"{cost[i].mean():.3f} [{c_ci[i][0]:.3f}, {c_ci[i][1]:.3f}]" for i in range(2)]
        lines.append(f"| {folder} | {env} | `{scenario}` | {cell} | {n} | {s[0]} | {s[1]} | "
                     f"{_verdict(s_ci[0], s_ci[1], lower_better=False)} | {c[0]} | {c[1]} | "
                     f"{_verdict(c_ci[0], c_ci[1], lower_better=True)} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    pairs = specs()
    ours = run_and_record([grey for _, _, grey in pairs], args.out, args.workers)
    text = write_tables(args.out, "The grey-box baseline against the robust recipe",
                        "OMP_NUM_THREADS=1 python -m benchmarks.studies.grey_box --workers 2",
                        tables(pairs, ours))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
