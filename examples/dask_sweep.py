"""A sweep on a Dask cluster: the benchmark engine submits one trial per task. With
``--scheduler local`` it starts a LocalCluster on this machine; give a scheduler address
(``tcp://host:8786``) to use an existing cluster (workers need this package installed).

Run: ``python examples/dask_sweep.py`` (``GP_EXAMPLES_SMOKE=1``: one seed, 5 steps per episode)
"""

import csv
import os
import tempfile

from benchmarks.cli import main


def sweep(smoke: bool) -> int:
    """Robust vs nominal MPC on the randomized cart pole, on a local Dask cluster."""
    with tempfile.TemporaryDirectory() as out:
        argv = ["--controllers", "robust-mpc,nominal-mpc", "--envs", "cartpole",
                "--randomize", "0.1", "--data", "own", "--seeds", "0" if smoke else "0-9",
                "--scheduler", "local", "--workers", "2", "--no-progress", "--out", out]
        if smoke:
            argv += ["--max-steps", "5"]
        status = main(argv)
        with open(os.path.join(out, "summary.csv"), newline="") as f:
            for row in csv.DictReader(f):
                print(f"{row['controller']:12s} episodes {row['episodes']}, success "
                      f"{float(row['success_rate']):.2f}, cost {float(row['cost_mean']):.2f}")
    return status


if __name__ == "__main__":  # the cluster's worker processes import this module too
    raise SystemExit(sweep(os.environ.get("GP_EXAMPLES_SMOKE") == "1"))
