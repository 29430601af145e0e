"""A user's own system end to end, as a user would do it (``docs/guide/own-system.md``).

A small system (a puck pushed along a line, with unmodeled friction and a mass error) lives in
a package installed into a temporary directory: its modules plus a ``*.dist-info`` folder whose
``entry_points.txt`` declares the system module in the group ``gp_envs.systems``. With that
directory on ``PYTHONPATH`` (and nothing else), subprocesses train an RL model with ``python -m
benchmarks.rl.train --env puck`` into ``<cwd>/benchmarks/models`` and run it and
``robust-mpc`` (the recommended recipe: initial data, learning) with ``python -m benchmarks``
in that directory (the trials in a spawned worker process), then with ``--models DIR`` from
another directory.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.runner import load_record

ROOT = Path(__file__).resolve().parent.parent

EXAMPLE = ROOT / "examples" / "own_system" / "gp_puck"
"""The user guide's example system (a puck on a line), installed here as a user would."""


def _install_plugin(site: Path) -> None:
    """Write package ``gp_puck`` and its distribution metadata into ``site``."""
    pkg = site / "gp_puck"
    pkg.mkdir(parents=True)
    for module in ("__init__.py", "puck.py", "env.py", "control.py"):
        shutil.copy(EXAMPLE / module, pkg / module)
    dist = site / "gp_puck-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: gp-puck\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[gp_envs.systems]\npuck = gp_puck.env\n\n"
                                           "[gp_agents.systems]\npuck = gp_puck.control\n")


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    res = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, f"{args}:\n{res.stdout}\n{res.stderr}"
    return res


def _records(out: Path) -> dict[str, dict]:
    records = [load_record(p) for p in sorted((out / "runs").glob("*.npz"))]
    return {r["spec"]["controller"]: r for r in records if r is not None}


def test_own_system_trains_and_runs_through_the_command_lines(tmp_path: Path) -> None:
    pytest.importorskip("gp_agents.rl")
    site = tmp_path / "site"
    _install_plugin(site)
    env = dict(os.environ, OMP_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    work = tmp_path / "work"
    work.mkdir()

    # train_rl knows the plugin's system (and lists it in --help)
    assert "puck" in _run(["-m", "benchmarks.rl.train", "--help"], work, env).stdout
    _run(["-m", "benchmarks.rl.train", "--env", "puck", "--algo", "sac", "--steps", "300",
          "--eval-freq", "0", "--eval-episodes", "1", "--checkpoint-freq", "0",
          "--no-progress"], work, env)
    model = work / "benchmarks" / "models" / "puck" / "sac"
    meta = json.loads((model / "metadata.json").read_text())
    assert (model / "model.zip").is_file()
    assert meta["env_id"] == "gp_puck/Puck-v0" and meta["training_steps"] == 300

    # gp-bench in that directory: the trials run in a spawned worker process, which knows the
    # system through the entry point and the model directory through the trial's spec
    _run(["-m", "benchmarks", "--envs", "puck", "--controllers", "robust-mpc,sac",
          "--seeds", "0", "--workers", "1", "--no-progress"], work, env)
    out = work / "benchmark-results" / "custom"
    records = _records(out)
    assert sorted(records) == ["robust-mpc", "sac"]
    for name, record in records.items():
        assert record["status"] == "ok", (name, record["message"])
        assert record["metrics"]["steps"] == 30 and np.isfinite(record["metrics"]["cost"])
    sac = records["sac"]["metrics"]
    assert sac["recipe_model_source"] == "user"
    assert sac["recipe_model_dir"] == str(model.resolve())
    assert sac["recipe_training_steps"] == 300
    assert "recipe_model_source" not in records["robust-mpc"]["metrics"]
    assert (out / "report.md").is_file()

    # from another directory, --models names the model directory (in this process: --workers 0)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _run(["-m", "benchmarks", "--envs", "puck", "--controllers", "sac", "--seeds", "1",
          "--max-steps", "3", "--workers", "0", "--no-progress",
          "--models", str(work / "benchmarks" / "models")], elsewhere, env)
    record = _records(elsewhere / "benchmark-results" / "custom")["sac"]
    assert record["status"] == "ok", record["message"]
    assert record["metrics"]["recipe_model_dir"] == str(model.resolve())
    assert record["spec"]["models"] == str((work / "benchmarks" / "models").resolve())

    # without either, the run says where it looked and how to train one (recorded, and the
    # command exits 3 with the reason: a requested controller could not run)
    bare = tmp_path / "bare"
    bare.mkdir()
    res = subprocess.run([sys.executable, "-m", "benchmarks", "--envs", "puck", "--controllers",
                          "sac", "--seeds", "0", "--max-steps", "3", "--workers", "0",
                          "--no-progress"], cwd=bare, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 3 and "not available: sac on puck" in res.stderr, res.stderr
    record = _records(bare / "benchmark-results" / "custom")["sac"]
    assert record["status"] == "unavailable"
    assert "python -m benchmarks.rl.train --env puck --algo sac" in record["message"]
