"""The benchmark suite: files written, resume, partial files, names, determinism, Dask path."""

from __future__ import annotations

import csv
import dataclasses
import importlib
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.cli import build_parser, main, parse_seeds, resolve
from benchmarks.controllers import (
    UnknownNameError,
    build_controller,
    check_env_scenario,
    make_env,
)
from benchmarks.presets import PRESETS, get_preset
from benchmarks.readme_table import readme_table
from benchmarks.runner import is_finished, load_record, run_trials, save_trial, trial_path
from benchmarks.trial import TrialSpec, execute

TINY = ["--controllers", "nominal-mpc", "--envs", "cartpole", "--scenarios", "online",
        "--seeds", "0", "--max-steps", "4", "--workers", "0", "--no-progress"]
TINY_SPEC = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 0, max_steps=4)
STUDIES = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "benchmarks" / "studies")
                 .glob("*.py") if p.stem != "__init__")
TIMING = ("act_median_ms", "act_p95_ms", "act_max_ms", "build_s", "episode_s")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tiny")
    assert main([*TINY, "--out", str(out)]) == 0
    return out


def test_tiny_run_writes_trajectories_metrics_plots_and_report(tiny_run: Path) -> None:
    run_file = trial_path(tiny_run, TINY_SPEC)
    assert run_file.is_file() and run_file.parent.name == "runs"
    with np.load(run_file) as data:
        assert data["obs"].shape == (5, 4) and data["action"].shape == (4, 1)
        assert data["act_time"].shape == (4,) and data["diag_replanned"].shape == (4,)
    record = load_record(run_file)
    assert record["status"] == "ok"
    m = record["metrics"]
    assert m["steps"] == 4 and m["termination"] == "max steps" and m["data_steps"] == 4
    assert m["solver_failures"] >= 0 and np.isnan(m["time_to_success_s"])
    # provenance: the commit of the code that ran the trial
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True, cwd=Path(__file__).resolve().parent).stdout.strip()
    assert record["code_version"].removesuffix("-dirty") == (head or "unknown")
    for name in ("metrics.csv", "summary.csv", "report.md", "custom_step_times.png",
                 "custom_trajectories_cartpole_online.png"):
        assert (tiny_run / name).is_file(), name
    report = (tiny_run / "report.md").read_text()
    assert "python -m benchmarks --controllers nominal-mpc" in report
    assert "casadi" in report and "custom_step_times.png" in report
    assert f"trials by code version: {record['code_version']} (1)" in report
    assert "nominal MPC" in readme_table(tiny_run)
    with pytest.raises(ValueError, match="present: custom"):
        readme_table(tiny_run, "dubins")


def test_rerun_skips_finished_trials(tiny_run: Path) -> None:
    path = trial_path(tiny_run, TINY_SPEC)
    before = path.stat().st_mtime_ns
    summary = run_trials([TINY_SPEC], tiny_run, workers=0, progress=False)
    assert summary.skipped == [TINY_SPEC.key] and summary.ran == {}
    assert path.stat().st_mtime_ns == before


def test_partial_trial_file_is_not_finished_and_is_rerun(tiny_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "partial"
    target = trial_path(out, TINY_SPEC)
    target.parent.mkdir(parents=True)
    data = trial_path(tiny_run, TINY_SPEC).read_bytes()
    target.write_bytes(data[: len(data) // 2])  # a write killed half-way
    (target.parent / f".{target.stem}.abc.tmp").write_bytes(data[:10])  # a leftover temp file
    assert not is_finished(out, TINY_SPEC)
    summary = run_trials([TINY_SPEC], out, workers=0, progress=False)
    assert summary.ran == {TINY_SPEC.key: "ok"} and is_finished(out, TINY_SPEC)


def test_failed_trial_is_recorded_and_retried(tmp_path: Path) -> None:
    spec = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 0, max_steps=2)
    save_trial(trial_path(tmp_path, spec), {"spec": spec.to_dict(), "status": "error",
                                            "message": "boom", "metrics": {}, "arrays": {}})
    assert load_record(trial_path(tmp_path, spec))["status"] == "error"
    assert not is_finished(tmp_path, spec)


def test_unknown_names_raise_clear_errors(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(UnknownNameError, match="valid presets: quick"):
        get_preset("nope")
    with pytest.raises(UnknownNameError, match="nominal-mpc"):
        TrialSpec("episode", "cartpole", "online", "lqr", 0).validate()
    with pytest.raises(UnknownNameError,
                       match="valid envs: cartpole, mujoco_cartpole, dubins, pendulum, "
                             "pilco_cartpole, quadrotor, pendulum-v1, dmc-cartpole"):
        check_env_scenario("acrobot", "online")
    with pytest.raises(UnknownNameError, match="gp, online"):
        check_env_scenario("cartpole", "paper")
    with pytest.raises(UnknownNameError):
        run_trials([TrialSpec("episode", "dubins", "paper", "mppi", 0)], Path("/nonexistent"))
    for argv, valid in ((["--preset", "fast"], "full"), (["--controllers", "lqr"], "ssgp-mpc"),
                        (["--controllers", "sac", "--envs", "moon"], "dubins"),
                        (["--controllers", "sac", "--scenarios", "x"], "online")):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        assert valid in capsys.readouterr().err


def test_seed_lists_and_presets_are_listed(capsys: pytest.CaptureFixture[str]) -> None:
    assert parse_seeds("0-3,7") == [0, 1, 2, 3, 7]
    preset, out = resolve(build_parser().parse_args(["--quick", "--envs", "dubins"]))
    assert preset.name == "quick" and out.name == "quick"
    assert {s.env for s in preset.specs} == {"dubins"}
    assert main(["--list-presets"]) == 0
    listing = capsys.readouterr().out
    assert all(name in listing for name in PRESETS)
    full = {s.key for s in PRESETS["full"].specs}
    assert {s.key for s in PRESETS["mpc-acceptance"].specs} <= full


def test_metrics_are_deterministic_for_a_tiny_learning_run() -> None:
    spec = TrialSpec("episode", "dubins", "paper", "ssgp-mpc", 3, max_steps=5, n_init=40)
    a, b = execute(spec), execute(spec)
    assert a["status"] == b["status"] == "ok", a["message"]
    for key, value in a["metrics"].items():
        if key not in TIMING:
            assert value == b["metrics"][key] or (value != value and b["metrics"][key] != b[
                "metrics"][key]), key
    np.testing.assert_array_equal(a["arrays"]["obs"], b["arrays"]["obs"])
    assert a["metrics"]["data_steps"] == 45 and a["metrics"]["initial_data_steps"] == 40


def test_change_detector_changes_are_recorded() -> None:
    """The payload (+20% mass at 3 s = step 60) is a change the adaptive recipe's detector
    declares within a few steps; the episode records how many; a recipe without a detector
    records NaN."""
    before, after = (execute(TrialSpec("episode", "quadrotor", "online-payload",
                                       "ssgp-mpc-linearized-adaptive", 200, max_steps=n))
                     for n in (58, 70))
    assert before["status"] == after["status"] == "ok", after["message"]
    assert after["metrics"]["learner_changes"] == before["metrics"]["learner_changes"] + 1
    plain = execute(TrialSpec("episode", "quadrotor", "online-payload", "ssgp-mpc-linearized",
                              200, max_steps=2))
    assert np.isnan(plain["metrics"]["learner_changes"])


def test_missing_rl_model_is_recorded_as_not_available(tmp_path: Path) -> None:
    spec = TrialSpec("episode", "quadrotor", "gp", "sac", 0, max_steps=2)
    summary = run_trials([spec], tmp_path, workers=0, progress=False)
    assert summary.ran == {spec.key: "unavailable"}
    message = load_record(trial_path(tmp_path, spec))["message"]
    assert "no SAC model for env quadrotor" in message
    assert "python -m benchmarks.rl.train --env quadrotor --algo sac" in message  # the fix


def test_local_process_pool_runs_trials(tmp_path: Path) -> None:
    specs = [TrialSpec("episode", "dubins", "paper", "nominal-mpc", s, max_steps=2)
             for s in (0, 1)]
    summary = run_trials(specs, tmp_path, workers=1, progress=False)
    assert summary.ran == {s.key: "ok" for s in specs}


def test_dask_local_cluster_runs_a_tiny_trial(tmp_path: Path, tiny_run: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        summary = run_trials([TINY_SPEC], tmp_path, scheduler=cluster.scheduler_address,
                             progress=False)
    assert summary.ran == {TINY_SPEC.key: "ok"}
    ours, ref = load_record(trial_path(tmp_path, TINY_SPEC)), load_record(
        trial_path(tiny_run, TINY_SPEC))
    assert ours["metrics"]["cost"] == ref["metrics"]["cost"]
    shutil.rmtree(tmp_path / "runs")


def test_a_trial_exceeding_the_memory_limit_is_an_error_not_a_crash(tmp_path: Path) -> None:
    spec = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 0, max_steps=2)
    summary = run_trials([spec], tmp_path, workers=1, progress=False, max_memory_gb=0.05)
    assert summary.ran == {spec.key: "error"}
    assert not is_finished(tmp_path, spec)


def test_linearized_preset_reports_speed_ratios_expansion_errors_and_scaling(
        tmp_path: Path) -> None:
    argv = ["--preset", "linearized", "--envs", "quadrotor", "--scenarios", "gp", "--seeds", "0",
            "--controllers", "nominal-mpc,ssgp-mpc-linearized", "--max-steps", "3",
            "--workers", "0", "--no-progress", "--out", str(tmp_path)]
    assert main(argv) == 0
    report = (tmp_path / "report.md").read_text()
    assert "SSGP MPC, linearized" in report
    assert "the `nominal-mpc`'s (target 1.5x:" in report  # the ratio, computed in the same run
    assert "error of the per-node expansion" in report
    assert "| quadrotor | gp | `ssgp-mpc-linearized` | 5000 |" in report  # samples learned
    assert (tmp_path / "linearized_ssgp_act_scaling.png").is_file()


@pytest.mark.parametrize(("kind", "controller", "param", "check"), [
    ("step-vs-nodes", "nominal-mpc-rti", 6, lambda m: "x 6 nodes" in m["mesh"]),
    ("step-vs-horizon", "nominal-mpc", 1000, lambda m: m["horizon_s"] == 1.0),
    ("step-vs-rank", "ssgp-mpc-rti", 25, lambda m: m["rank"] == 25),
])
def test_step_scaling_trials_change_exactly_their_setting(
        kind: str, controller: str, param: int, check: Any) -> None:
    out = execute(TrialSpec(kind, "cartpole", "gp", controller, 0, param=param, max_steps=2))
    assert out["status"] == "ok", out["message"]
    m = out["metrics"]
    assert check(m) and m["steps"] == 2 and m["act_median_ms"] > 0
    # the other settings stay the recipe's defaults
    if kind != "step-vs-nodes":
        assert "x 16 nodes" in m["mesh"]


def test_a_nominal_recipe_takes_no_learner() -> None:
    from gp_agents import online_ssgp

    env = make_env("cartpole", "gp")
    with pytest.raises(ValueError, match="learns nothing"):
        build_controller("nominal-mpc", env, "cartpole", 0, learner=online_ssgp(10))


@pytest.mark.parametrize("env_name,scenario", [("dubins", "paper"), ("cartpole", "online")])
def test_the_parametric_recipe_has_linear_features_on_the_sensitivities_only(
        env_name: str, scenario: str) -> None:
    """``ssgp-mpc-linearized-parametric``: the learner's linear features are exactly the
    residual's parameter-sensitivity inputs (by name), the saturated recipe's on every input."""
    env = make_env(env_name, scenario)
    agent = build_controller("ssgp-mpc-linearized-parametric", env, env_name, 0, n_init=60).agent
    names = np.array(agent.config.residual.model(agent.model).input_names)
    assert list(names[agent.learner.linear_mask_ == 1.0]) == [
        n for n in names if n.startswith("d(")]
    saturated = build_controller("ssgp-mpc-linearized-saturated", env, env_name, 0,
                                 n_init=60).agent.learner
    assert np.all(saturated.linear_mask_ == 1.0)


def test_no_preset_schedules_the_same_trial_twice() -> None:
    """A trial listed twice would be counted twice in its experiment's summary."""
    for name in PRESETS:
        for exp in get_preset(name).experiments:
            keys = [s.key for s in exp.specs]
            assert len(keys) == len(set(keys)), (name, exp.name)


def test_interleaved_episodes_are_the_same_trials_seed_by_seed() -> None:
    """The rti preset's step-time ratios compare recipes run back to back: every recipe's
    episode of a seed before the next seed, and exactly the trials of the plain grid."""
    from benchmarks.presets import episodes

    grid = (["nominal-mpc", "ssgp-mpc"], [("cartpole", "online"), ("dubins", "paper")],
            [0, 1, 2])
    plain, mixed = episodes(*grid), episodes(*grid, interleave=True)
    assert sorted(s.key for s in plain) == sorted(s.key for s in mixed)
    assert [(s.env, s.seed, s.controller) for s in mixed[:4]] == [
        ("cartpole", 0, "nominal-mpc"), ("cartpole", 0, "ssgp-mpc"),
        ("cartpole", 1, "nominal-mpc"), ("cartpole", 1, "ssgp-mpc")]
    rti = [s for s in get_preset("rti").experiments[0].specs if s.kind == "episode"]
    for env, scenario in {(s.env, s.scenario) for s in rti}:
        seeds = [s.seed for s in rti if (s.env, s.scenario) == (env, scenario)]
        assert seeds == sorted(seeds), (env, scenario)


def test_the_rti_preset_runs_every_learned_term_once_per_system() -> None:
    """``ssgp-mpc-rti`` is the system's registered learned term; the preset adds the other
    linearized term explicitly (one call and split), so each term runs once per system with
    the paper's learner (the parametric learner's RTI, registered term, is extra) and the
    report's linearization table knows which term a recipe used."""
    from benchmarks.controllers import CONTROLLERS, learned_term
    from benchmarks.presets import RTI_CONTROLLERS, rti_controllers

    assert learned_term(CONTROLLERS["ssgp-mpc-rti"], "quadrotor") == "linearized-pattern"
    assert learned_term(CONTROLLERS["ssgp-mpc-rti-split"], "cartpole") == "linearized"
    assert learned_term(CONTROLLERS["ssgp-mpc-rti-pattern"], "cartpole") == "linearized-pattern"
    assert learned_term(CONTROLLERS["ssgp-mpc"], "dubins") == "exact"
    assert learned_term(CONTROLLERS["nominal-mpc-rti"], "dubins") is None
    for system in ("cartpole", "quadrotor", "dubins"):
        names = rti_controllers(system)
        assert len(names) == len(set(names)) and names[:len(RTI_CONTROLLERS)] == RTI_CONTROLLERS
        terms = [learned_term(CONTROLLERS[n], system) for n in names
                 if n.startswith("ssgp-mpc-rti") and not n.endswith("-split")
                 and CONTROLLERS[n].learner == "ssgp"]
        assert sorted(terms) == ["linearized", "linearized-pattern", "zero-order"], system
    rti = [s for s in get_preset("rti").experiments[0].specs if s.kind == "episode"]
    quad = {s.controller for s in rti if s.env == "quadrotor"}
    assert "ssgp-mpc-rti-linearized-split" in quad and "ssgp-mpc-rti-pattern" not in quad


def test_build_episode_builds_the_episode_execute_runs() -> None:
    """``build_episode`` (with which a study replays a benchmark episode) gives the env, the
    pretrained controller and the first observation of the trial ``execute`` runs: the same
    first observation and action."""
    from benchmarks.trial import build_episode

    spec = TrialSpec("episode", "pendulum", "damped", "ssgp-mpc", 0, max_steps=1)
    record = execute(spec)
    assert record["status"] == "ok", record["message"]
    env, built, _ = build_episode(spec)
    np.testing.assert_allclose(built.obs, record["arrays"]["obs"][0])
    np.testing.assert_allclose(built.agent.act(built.obs), record["arrays"]["action"][0])
    env.close()


@pytest.mark.parametrize("study", STUDIES)
def test_each_study_imports(study: str) -> None:
    """The studies (``benchmarks/studies``: the one-off measurements behind the decision records
    of ``docs/studies``, and the registry's study variants) are not the engine: the suite only
    imports each."""
    module = importlib.import_module(f"benchmarks.studies.{study}")
    assert module.__doc__


def test_every_controller_name_of_a_committed_result_is_registered() -> None:
    """The names that key committed results (every ``controller`` of a committed
    ``metrics.csv``) stay buildable names: the study variants among them included."""
    from benchmarks.controllers import CONTROLLERS

    results = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    names: set[str] = set()
    for path in results.rglob("metrics.csv"):
        with path.open(newline="") as f:
            names |= {row["controller"] for row in csv.DictReader(f) if row.get("controller")}
    assert {"robust-mpc", "ssgp-mpc", "ssgp-mpc-linearized"} <= names
    assert sorted(n for n in names if n not in CONTROLLERS) == []


def test_register_controller_adds_a_name_the_registry_builds() -> None:
    from benchmarks.controllers import CONTROLLERS, ControllerRecipe, register_controller

    recipe = ControllerRecipe("test-nominal-mpc", "test nominal", "mpc", "nominal, registered")
    try:
        register_controller("test-nominal-mpc", recipe)
        register_controller("test-nominal-mpc", recipe)  # the same recipe again: a no-op
        assert CONTROLLERS["test-nominal-mpc"] is recipe
        with pytest.raises(ValueError, match="already registered"):
            register_controller("test-nominal-mpc", dataclasses.replace(recipe, label="other"))
        with pytest.raises(ValueError, match="named 'test-nominal-mpc'"):
            register_controller("other", recipe)
        env = make_env("cartpole", "online")
        built = build_controller("test-nominal-mpc", env, "cartpole", 0)
        assert np.all(np.isfinite(built.agent.act(built.obs)))
    finally:
        CONTROLLERS._controllers.pop("test-nominal-mpc", None)  # type: ignore[attr-defined]
    assert "test-nominal-mpc" not in CONTROLLERS
