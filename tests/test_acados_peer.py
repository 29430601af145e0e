"""The acados peer study (:mod:`benchmarks.studies.acados_peer`) without acados.

The worker's numpy dynamics must be the project's physics, the exported OCP must carry the env's
numbers through a JSON round trip, and a failed acados setup must end in a skip report with a
one-line reason (exit 0). No wall-clock assertions.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest
from agent_parts import mesh_of

import gp_envs
from benchmarks.studies import acados_peer, acados_peer_worker
from gp_agents import PseudospectralMPC
from gp_envs.physics import quadrotor


@pytest.fixture(scope="module")
def env_agent() -> tuple[gym.Env, PseudospectralMPC]:
    env = gym.make("gp_envs/Quadrotor-v0")
    agent = PseudospectralMPC.from_env(env, scheme="rti")
    env.reset(seed=100)
    return env, agent


def test_worker_imports_nothing_from_the_project() -> None:
    source = Path(acados_peer_worker.__file__).read_text()
    for name in ("gp_agents", "gp_envs", "benchmarks"):
        assert f"import {name}" not in source and f"from {name}" not in source
    assert "\nimport acados" not in source and "\nfrom acados" not in source  # lazy only


def test_export_round_trips_and_matches_the_env(env_agent) -> None:
    env, agent = env_agent
    spec = json.loads(json.dumps(acados_peer.export_ocp(env, agent)))
    model = env.unwrapped.nominal_model
    task = model.task
    assert spec["nominal_params"] == dict(model.params)
    assert spec["plant_params"] == dict(gp_envs.oracle_model(env).params)
    assert spec["dt"] == model.dt and spec["plant_substeps"] == model.substeps
    assert spec["horizon"] == agent.config.schedule.horizon
    assert spec["our_nodes"] == mesh_of(agent).n_collocation
    for key, value in (("Q", task.Q), ("R", task.R), ("Qf", task.Qf), ("goal", task.goal),
                       ("u_ref", task.u_ref), ("u_lb", model.u_lb), ("u_ub", model.u_ub),
                       ("x_lb", model.x_lb), ("x_ub", model.x_ub)):
        np.testing.assert_array_equal(np.array(spec[key]), value)
    np.testing.assert_array_equal(spec["start"], env.unwrapped._state)
    assert spec["state_margin"] == agent.config.constraints.state_margin
    assert spec["state_penalty"] == agent.config.constraints.state_penalty
    assert spec["yaw_drag_ratio"] == quadrotor.YAW_DRAG_RATIO
    labels = [c["label"] for c in spec["configs"]]
    assert labels == [f"acados N={mesh_of(agent).n_collocation}", "acados N=30"]
    for config in spec["configs"]:
        steps = np.array(config["time_steps"])
        assert steps[0] == pytest.approx(model.dt)
        assert steps.sum() == pytest.approx(agent.config.schedule.horizon)


def test_worker_ode_and_plant_match_the_physics(env_agent) -> None:
    env, _ = env_agent
    spec = acados_peer.export_ocp(env, env_agent[1])
    rng = np.random.default_rng(0)
    plant = gp_envs.oracle_model(env)
    for params, model in ((spec["nominal_params"], env.unwrapped.nominal_model),
                          (spec["plant_params"], plant)):
        p = model.param_vector
        for _ in range(20):
            x = rng.uniform(model.x_lb * 0.5, model.x_ub * 0.5)
            u = rng.uniform(model.u_lb, model.u_ub)
            ours = np.asarray(ca.evalf(quadrotor.ode(ca.DM(x), ca.DM(u), ca.DM(p)))).ravel()
            theirs = acados_peer_worker.numpy_ode(x, u, params, spec["yaw_drag_ratio"])
            np.testing.assert_allclose(theirs, ours, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(
                acados_peer_worker.rk4_step(x, u, params, spec["yaw_drag_ratio"], spec["dt"],
                                            spec["plant_substeps"]),
                model.step(x, u), rtol=1e-10, atol=1e-12)


def test_worker_shrunk_box_is_the_mpc_margin(env_agent) -> None:
    env, agent = env_agent
    spec = acados_peer.export_ocp(env, agent)
    lb, ub = acados_peer_worker.shrunk_box(spec)
    model = env.unwrapped.nominal_model
    half = 0.5 * (model.x_ub - model.x_lb)
    np.testing.assert_allclose(lb, model.x_lb + agent.config.constraints.state_margin * half)
    np.testing.assert_allclose(ub, model.x_ub - agent.config.constraints.state_margin * half)


def test_failed_setup_writes_a_skip_report(tmp_path: Path, monkeypatch) -> None:
    def failing(cmd, **kwargs) -> subprocess.CompletedProcess:
        return subprocess.CompletedProcess(cmd, 1, "", "ERROR: No matching distribution found "
                                           "for comma-deps-acados\n")

    monkeypatch.setattr(acados_peer.subprocess, "run", failing)
    monkeypatch.setattr(acados_peer, "find_python", lambda explicit=None: sys.executable)
    monkeypatch.setattr(acados_peer.shutil, "which", lambda name: f"/usr/bin/{name}")
    out = tmp_path / "out"
    code = acados_peer.main(["--steps", "3", "--repeats", "1", "--out", str(out),
                             "--venv", str(tmp_path / "venv")])
    assert code == 0
    report = (out / "report.md").read_text()
    assert "**Skipped:** creating the venv failed (exit 1): ERROR: No matching" in report
    reason_lines = [ln for ln in report.splitlines() if ln.startswith("**Skipped:**")]
    assert len(reason_lines) == 1
    rows = (out / "summary.csv").read_text().splitlines()
    assert rows[0] == "status,reason" and rows[1].startswith("skipped,")


def test_missing_compiler_tools_are_a_one_line_reason(monkeypatch, tmp_path: Path) -> None:
    monkeypatch.setattr(acados_peer.shutil, "which", lambda name: None)
    with pytest.raises(acados_peer.AcadosUnavailableError, match="'make' not found"):
        acados_peer.ensure_venv(tmp_path / "venv")
    assert not (tmp_path / "venv").exists()
