"""The evaluation of the trusted RTI on the robustness preset (issue 43, acceptance): per cell,
the split RTI of the robust recipe against the converged robust recipe, generated from the
engine's own ``summary.csv`` of one run of the preset with both controllers.

Run the preset's cells for the two controllers (one worker; resumable: a rerun skips finished
trials), then this to write ``rti_trust.md`` next to the run's own report::

    python -m benchmarks --preset robustness \\
        --controllers ssgp-mpc-rti-parametric-split,ssgp-mpc-linearized-parametric \\
        --workers 1 --out benchmarks/results/robustness-rti-trust
    python -m benchmarks.studies.rti_trust_evaluation

(The preset names the robust recipe's split RTI ``ssgp-mpc-rti-parametric-split`` and its
converged MPC ``ssgp-mpc-linearized-parametric``, the frozen aliases of ``robust-mpc@rti-split``
and ``robust-mpc@converged``.)

The acceptance, per cell: the RTI succeeds on as many seeds as the converged MPC, every
quadrotor seed ends within 1 cm, and at most :data:`MAX_REJECTED` of its RTI steps are
rejected (replaced by a converged solve). From the run's ``metrics.csv`` (one row per episode)
the table also pairs the two controllers seed by seed: the seeds only the RTI lost, both lost,
only the converged MPC lost, and the RTI's rejected fraction on the seeds both won (where a
rejection is no longer the safety net catching a model the converged MPC fails with too).
"""

from __future__ import annotations

import argparse
import csv
import math
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_DIR = ROOT / "benchmarks" / "results" / "robustness-rti-trust"
RTI, CONVERGED = "ssgp-mpc-rti-parametric-split", "ssgp-mpc-linearized-parametric"
MAX_REJECTED = 0.10
"""The largest fraction of rejected RTI steps a cell may have."""
MAX_QUADROTOR_ERROR = 0.01
"""The largest final position error (m) of a quadrotor seed."""


def _f(value: float, digits: int = 3) -> str:
    return "-" if not math.isfinite(value) else f"{value:.{digits}g}"


def _num(row: dict[str, str], key: str) -> float:
    try:
        return float(row.get(key, "nan"))
    except ValueError:
        return math.nan


def cells(summary: Path) -> list[dict[str, object]]:
    """One record per (env, scenario, cell) that has both controllers (the default initial
    data; the preset's other sample counts are the converged recipe's alone)."""
    rows = [r for r in csv.DictReader(summary.open())
            if r["controller"] in (RTI, CONVERGED) and r["status"] == "ok"]
    groups: dict[tuple[str, str, str, str], dict[str, dict[str, str]]] = {}
    for r in rows:
        groups.setdefault((r["env"], r["scenario"], r["cell"], r["n_init"]), {})[
            r["controller"]] = r
    out = []
    for (env, scenario, cell, n_init), pair in groups.items():
        if set(pair) != {RTI, CONVERGED}:
            continue
        rti, conv = pair[RTI], pair[CONVERGED]
        n_rti, n_conv = int(rti["episodes"]), int(conv["episodes"])
        s_rti = round(_num(rti, "success_rate") * n_rti)
        s_conv = round(_num(conv, "success_rate") * n_conv)
        rejected = _num(rti, "rti_rejected_fraction")
        err = _num(rti, "final_position_error_max")
        same = s_rti >= s_conv and n_rti == n_conv
        within = env != "quadrotor" or (math.isfinite(err) and err <= MAX_QUADROTOR_ERROR)
        out.append(dict(
            env=env, scenario=scenario, cell=cell, n_init=n_init, episodes=n_rti,
            success_rti=s_rti, success_converged=s_conv, rejected=rejected,
            rti_steps=int(_num(rti, "rti_steps")), recovered=int(_num(rti, "rti_recovered")),
            n_rejected=int(_num(rti, "rti_rejected")), error_rti=err,
            error_converged=_num(conv, "final_position_error_max"),
            cost_rti=_num(rti, "cost_mean"), cost_converged=_num(conv, "cost_mean"),
            failures=int(_num(rti, "solver_failures")),
            met=same and within and rejected <= MAX_REJECTED))
    return out


def paired(metrics: Path) -> dict[tuple[str, str, str, str], dict[str, float]]:
    """Per (env, scenario, cell, n_init), the two controllers' episodes paired by seed:
    ``rti_only``, ``both`` and ``converged_only`` (seeds lost) and ``rejected_both_won`` (the
    RTI's rejected fraction on the seeds both won; NaN without such seeds)."""
    episodes: dict[tuple[str, str, str, str], dict[str, dict[str, dict[str, str]]]] = {}
    for r in csv.DictReader(metrics.open()):
        if r["controller"] in (RTI, CONVERGED) and r["status"] == "ok":
            key = (r["env"], r["scenario"], r["cell"], r["n_init"])
            episodes.setdefault(key, {}).setdefault(r["seed"], {})[r["controller"]] = r
    out = {}
    for key, seeds in episodes.items():
        won = {"rti_only": 0, "both": 0, "converged_only": 0}
        steps = rejected = 0.0
        for pair in seeds.values():
            if set(pair) != {RTI, CONVERGED}:
                continue
            ok_rti = pair[RTI]["success"] == "True"
            ok_conv = pair[CONVERGED]["success"] == "True"
            if ok_rti and ok_conv:
                steps += _num(pair[RTI], "rti_steps")
                rejected += _num(pair[RTI], "rti_rejected")
            elif ok_conv:
                won["rti_only"] += 1
            elif ok_rti:
                won["converged_only"] += 1
            else:
                won["both"] += 1
        out[key] = {**won, "rejected_both_won": rejected / steps if steps else math.nan}
    return out


def write(directory: Path) -> Path:
    """Write ``rti_trust.md`` in ``directory`` from its ``summary.csv`` (and, when present,
    its ``metrics.csv``); returns its path."""
    table = cells(directory / "summary.csv")
    seeds = paired(directory / "metrics.csv") if (directory / "metrics.csv").is_file() else {}
    lines = [
        "# Trusted RTI on the robustness preset (issue 43)", "",
        "Generated by `benchmarks/studies/rti_trust_evaluation.py` from this run's "
        "`summary.csv` and `metrics.csv` (the benchmark engine's). Controllers: the robust "
        "recipe's split RTI "
        f"(`{RTI}` = `robust-mpc@rti-split`) and the converged robust recipe (`{CONVERGED}` = "
        "`robust-mpc@converged`); the preset's evaluation seeds (200-219, Dubins 200-249; "
        "never used for tuning). *Met*: the RTI succeeds on as many seeds as the converged "
        f"MPC, every quadrotor seed ends within {MAX_QUADROTOR_ERROR * 100:g} cm, and at most "
        f"{MAX_REJECTED:.0%} of its RTI steps were rejected (replaced by a converged solve); "
        "*recovered*: steps whose violation the recovery brought within tolerance; *seeds lost*: "
        "by the RTI only / by both / by the converged MPC only; *rejected % where both won*: "
        "the RTI's rejected fraction on the seeds both controllers won.", "",
        "| env | scenario | cell | success RTI / converged | RTI steps | recovered | rejected "
        "| rejected % | seeds lost | rejected % where both won "
        "| max final pos. err. RTI / converged (m) | cost mean RTI / converged "
        "| solver failures (RTI) | met |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for c in table:
        pair = seeds.get((str(c["env"]), str(c["scenario"]), str(c["cell"]), str(c["n_init"])))
        lost = ("-" if pair is None else
                f"{pair['rti_only']:g} / {pair['both']:g} / {pair['converged_only']:g}")
        both = "-" if pair is None else _f(100 * pair["rejected_both_won"], 2)
        lines.append(
            f"| {c['env']} | {c['scenario']} | {c['cell']} "
            f"| {c['success_rti']}/{c['episodes']} / {c['success_converged']}/{c['episodes']} "
            f"| {c['rti_steps']} | {c['recovered']} | {c['n_rejected']} "
            f"| {_f(100 * float(c['rejected']), 2)} | {lost} | {both} "
            f"| {_f(float(c['error_rti']))} / {_f(float(c['error_converged']))} "
            f"| {_f(float(c['cost_rti']), 4)} / {_f(float(c['cost_converged']), 4)} "
            f"| {c['failures']} | {'yes' if c['met'] else '**no**'} |")
    met = sum(bool(c["met"]) for c in table)
    worst = max((float(c["rejected"]) for c in table), default=math.nan)
    lines += ["", f"Cells meeting the acceptance: {met} of {len(table)}; the largest rejected "
              f"fraction of a cell: {_f(100 * worst, 2)}%."]
    out = directory / "rti_trust.md"
    out.write_text("\n".join(lines) + "\n")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dir", type=Path, default=DEFAULT_DIR,
                        help="the preset run's directory (its summary.csv)")
    args = parser.parse_args(argv)
    print(f"report: {write(args.dir)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
