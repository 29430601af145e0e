"""A sweep on a Dask cluster: the benchmark engine submits one trial per task. With
``--scheduler local`` it starts a LocalCluster on this machine; give a scheduler address
(``tcp://host:8786``) to use an existing cluster (workers need this package installed).

The report (``report.md``, ``summary.csv``, ``metrics.csv``, figures) stays in
``./benchmark-results/dask-sweep/`` under the current directory (``dask-sweep-smoke/`` for the
smoke run; git-ignored in a checkout); rerunning skips the trials already there.

Run: ``python examples/dask_sweep.py`` (``GP_EXAMPLES_SMOKE=1``: one seed, 5 steps per episode)
"""

import csv
import os
from pathlib import Path

from benchmarks.cli import main


def sweep(smoke: bool) -> int:
    """Robust vs nominal MPC on the randomized cart pole, on a local Dask cluster."""
    out = Path("benchmark-results") / ("dask-sweep-smoke" if smoke else "dask-sweep")
    argv = ["--controllers", "robust-mpc,nominal-mpc", "--envs", "cartpole",
            "--randomize", "0.1", "--data", "own", "--seeds", "0" if smoke else "0-9",
            "--scheduler", "local", "--workers", "2", "--no-progress", "--out", str(out)]
    if smoke:
        argv += ["--max-steps", "5"]
    status = main(argv)
    with open(out / "summary.csv", newline="") as f:
        for row in csv.DictReader(f):
            print(f"{row['controller']:12s} episodes {row['episodes']}, success "
                  f"{float(row['success_rate']):.2f}, cost {float(row['cost_mean']):.2f}")
    print(f"the report is kept in {out.resolve()}")
    return status


if __name__ == "__main__":  # the cluster's worker processes import this module too
    raise SystemExit(sweep(os.environ.get("GP_EXAMPLES_SMOKE") == "1"))
