"""The benchmark suite: files written, resume, partial files, names, determinism, Dask path."""

from __future__ import annotations

import csv
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
    assert "the nominal MPC's (target 1.5x:" in report  # the ratio, computed in the same run
    assert "error of the per-node expansion" in report
    assert "| quadrotor | gp | SSGP MPC, linearized | 5000 |" in report  # samples learned
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
    names = np.array(agent.residual.input_names)
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


def test_the_residual_trace_records_what_the_nominal_model_missed() -> None:
    """``benchmarks.studies.residual_trace``: the step-0 row is the first transition of the
    benchmark's
    own episode (a separate build of it: same action, the residual model's target of that
    transition) with the *pretrained* learner's prediction (taken before it learns the
    sample); a recipe without a learner, an unknown name or a bad cell is a usage error."""
    from benchmarks.studies import residual_trace as rt
    from benchmarks.trial import build_episode

    spec = TrialSpec("episode", "pendulum", "damped", "ssgp-mpc", 0)
    rows, outputs, inputs = rt.trace(spec, steps=3)
    env, built, _ = build_episode(spec)
    action = built.agent.act(built.obs)
    next_obs = env.step(action)[0]
    Z, Y = built.agent.residual.targets(built.obs[None], np.asarray(action, float)[None],
                                        next_obs[None])
    np.testing.assert_allclose(rows[0]["action"], action)
    np.testing.assert_allclose(rows[0]["target"], Y[0])
    np.testing.assert_allclose(rows[0]["predicted"], built.agent.learner.predict(Z)[0])
    assert [r["step"] for r in rows] == [0, 1, 2] and len(outputs) == len(rows[0]["target"])
    assert all(np.all(np.isfinite(r["predicted"])) and r["distance"] >= 0 for r in rows)
    assert all(r["farthest"] in inputs for r in rows)
    text = rt.format_trace(rows, outputs)
    assert text.count("\n| d(") == len(outputs)  # one summary row per output
    with pytest.raises(ValueError, match="learns nothing"):
        rt.trace(TrialSpec("episode", "pendulum", "damped", "nominal-mpc", 0), steps=1)
    for argv in (["--controller", "nominal-mpc", "--env", "pendulum"], ["--env", "nope"],
                 ["--env", "pendulum", "--data", "other"], ["--env", "pendulum", "--steps", "0"]):
        with pytest.raises(SystemExit):
            rt.main(argv)


def test_the_zero_order_gain_ratio_and_its_tables(tmp_path: Path) -> None:
    """``benchmarks.studies.rti_zero_order``: rho is the documented truth's gain (b = 0.3, the env
    docstring) over the reset's nominal draw; the band table counts what the rows say; a
    metrics file without the recipes' Dubins episodes, or no input at all, is a usage error."""
    from benchmarks.studies import rti_zero_order as zo

    env = make_env("dubins", "paper")
    for seed in (3, 26):
        env.reset(seed=seed)
        nominal = env.unwrapped.nominal_model.params
        q = zo.gain_ratio(seed)
        assert q["b1_true"] == q["b2_true"] == pytest.approx(0.3)
        assert q["rho"] == pytest.approx(max(0.7 / (1 - nominal["b1"]),
                                             0.7 / (1 - nominal["b2"])))
    assert zo.gain_ratio(3)["rho"] >= zo.STABLE_RATIO > zo.gain_ratio(26)["rho"]
    rows = [dict(source="s", recipe=r, seed=seed, success=ok, cost=1.0, contacts=c)
            for r, seed, ok, c in (("ssgp-mpc-rti-zero-order", 3, False, 2),
                                   ("ssgp-mpc-rti-zero-order", 26, True, 0),
                                   ("ssgp-mpc-rti", 3, True, 0), ("ssgp-mpc-rti", 26, True, 0))]
    text = zo.tables(rows)
    assert "| s | < 2 | 1 | 1/1 / 0 | 1/1 / 0 |" in text
    assert "| s | >= 2 | 1 | 0/1 / 1 | 1/1 / 0 |" in text
    empty = tmp_path / "metrics.csv"
    empty.write_text("env,controller,seed,success,cost,violations,status\n"
                     "cartpole,ssgp-mpc-rti,0,True,1.0,0,ok\n")
    with pytest.raises(ValueError, match="no Dubins episodes"):
        zo.metrics_rows(empty)
    for argv in (["--seeds", "none"], ["--seeds", "none", "--metrics", str(empty)]):
        with pytest.raises(SystemExit):
            zo.main(argv)


def test_the_levenberg_marquardt_sweep_counts_what_its_episodes_did() -> None:
    """``benchmarks.studies.rti_levenberg_marquardt``: one row per episode, the RTI steps it
    counts are the planner's (rejected ones among them), a converged reference runs once per
    seed with none, the table has a row per recipe and ``mu``; a negative ``mu``, an unknown
    recipe or an RTI or non-MPC reference is a usage error."""
    from benchmarks.studies import rti_levenberg_marquardt as lm

    rows = lm.run("dubins", [0.0, 0.01], [0], ["nominal-mpc-rti"], progress=False,
                  references=["nominal-mpc"])
    assert [(r["recipe"], r["mu"], r["seed"]) for r in rows] == [
        ("nominal-mpc", None, 0), ("nominal-mpc-rti", 0.0, 0), ("nominal-mpc-rti", 0.01, 0)]
    assert rows[0]["rti_steps"] == rows[0]["rejected"] == 0
    assert all(0 <= r["rejected"] <= r["rti_steps"] and r["rti_steps"] > 100 for r in rows[1:])
    text = lm.table(rows)
    assert "| nominal-mpc-rti | 0 |" in text and "| nominal-mpc-rti | 0.01 |" in text
    assert "| nominal-mpc | - |" in text
    for argv in (["--mu", "-0.1"], ["--mu", "x"], ["--recipes", "nominal-mpc"],
                 ["--scenario", "online"], ["--reference", "nominal-mpc-rti"],
                 ["--reference", "sac"]):
        with pytest.raises(SystemExit):
            lm.main(argv)


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


def test_the_learned_term_comparison_measures_split_latency_against_the_nominal() -> None:
    """``benchmarks.studies.rti_learned_term``: latency is act minus preparation over the replanning
    steps after the first; the table's ratio is per seed against the reference recipe; a
    one-call RTI (no preparation) or an unknown system is refused."""
    from benchmarks.studies import rti_learned_term as lt

    diag = {"replanned": np.array([1, 0, 1, 1, 1]), "act_time": np.array([9.0, 1, 3, 4, 5]),
            "preparation_time": np.array([1.0, 0, 1, 1, 1])}
    assert lt.episode_latency(diag) == 3.0  # median of 2, 3, 4: the first replan left out
    with pytest.raises(ValueError, match="not a split RTI"):
        lt.episode_latency({"replanned": diag["replanned"], "act_time": diag["act_time"]})
    with pytest.raises(ValueError, match="fewer than two"):
        lt.episode_latency({**diag, "replanned": np.array([1, 0, 0, 0, 0])})
    rows = [dict(system="s", scenario="c", recipe=r, seed=k, success=True, cost=1.0,
                 latency=lat) for r, k, lat in (("ref", 0, 1.0), ("ref", 1, 2.0),
                                                ("x", 0, 1.5), ("x", 1, 2.0),
                                                (lt.RECIPES[1], 0, 1.5), (lt.RECIPES[1], 1, 2.2))]
    text = lt.table(rows, reference="ref")
    assert "| s | `c` | x | 2/2 | 1.00 | 1750.00 | 1.25x [1.00, 1.50] | 1/2 |" in text
    assert f"| {lt.RECIPES[1]} | 2/2 | 1.00 | 1850.00 | 1.30x [1.10, 1.50] | - |" in text
    assert lt.recipes("cartpole")[0] == "oracle-mpc-rti-split"  # its nominal RTI never steps
    assert lt.recipes("dubins") == lt.RECIPES
    per_system = [{**r, "system": "cartpole",
                   "recipe": "oracle-mpc-rti-split" if r["recipe"] == "ref" else r["recipe"]}
                  for r in rows]
    assert "| cartpole | `c` | x | 2/2 | 1.00 | 1750.00 | 1.25x [1.00, 1.50] | 1/2 |" in lt.table(
        per_system)
    rows = lt.run("pendulum", "damped", [0], recipes=lt.RECIPES[:2], progress=False)
    assert [r["recipe"] for r in rows] == list(lt.RECIPES[:2])
    assert all(r["latency"] > 0 and np.isfinite(r["cost"]) for r in rows)
    with pytest.raises(SystemExit):
        lt.main(["--systems", "nope"])


@pytest.mark.parametrize("linear", [False, True, (1,)], ids=["none", "all", "column 1"])
def test_residual_decomposition_adds_up_to_the_prediction(linear: Any) -> None:
    """``residual_trace.decompose``: target mean + SE part + linear parts = ``predict``, and a
    column without a linear feature has no linear part."""
    from benchmarks.studies.residual_trace import decompose
    from gp_agents import IncrementalSSGP

    rng = np.random.default_rng(0)
    Z = rng.uniform(-1, 1, (80, 3))
    Y = np.c_[np.sin(2 * Z[:, 0]) + Z[:, 1], 0.5 * Z[:, 2] + 1.0]
    learner = IncrementalSSGP(10, forgetting_factor=0.99, linear_features=linear,
                              n_restarts=0).fit(Z, Y)
    z = np.array([2.0, -0.5, 3.0])
    parts = decompose(learner, z)
    np.testing.assert_allclose([p["total"] for p in parts], learner.predict(z[None])[0],
                               rtol=1e-10, atol=1e-12)
    for p in parts:
        if linear is False:
            assert np.all(p["linear"] == 0.0)
        elif linear == (1,):
            assert p["linear"][0] == 0.0 and p["linear"][2] == 0.0
    with pytest.raises(ValueError, match="fitted SSGP"):
        decompose(IncrementalSSGP(10), z)


@pytest.mark.parametrize("argv", [["--seeds", "200"], ["--cells", "nowhere"],
                                  ["--controllers", "robust-mpc"], ["--controllers", ""]])
def test_the_rti_recovery_study_refuses_evaluation_seeds_unknown_cells_and_non_rti_controllers(
        argv: list[str], tmp_path: Path) -> None:
    """``benchmarks.studies.rti_recovery``: tuning only on tuning seeds, its own cells, RTI
    controllers; a usage error runs nothing and writes nothing."""
    from benchmarks.studies import rti_recovery

    with pytest.raises(SystemExit):
        rti_recovery.main([*argv, "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()


def test_the_trusted_rti_evaluation_pairs_the_two_controllers_seed_by_seed(tmp_path: Path) -> None:
    """``benchmarks.studies.rti_trust_evaluation``: a cell is met only with the converged
    MPC's successes, within the rejection bound; the seeds are paired (lost by the RTI only,
    by both, by the converged MPC only) and the rejected fraction is also given on the seeds
    both won."""
    from benchmarks.studies import rti_trust_evaluation as ev

    key = {"env": "cartpole", "scenario": "online", "cell": "fixed truth", "n_init": "200",
           "status": "ok"}
    # seed: (RTI success, RTI steps, RTI rejected, converged success)
    seeds = {0: (True, 100, 2, True), 1: (False, 100, 80, True), 2: (False, 100, 90, False),
             3: (True, 100, 8, False)}
    metrics = [{**key, "controller": ev.RTI, "seed": s, "success": ok, "rti_steps": n,
                "rti_rejected": rej} for s, (ok, n, rej, _) in seeds.items()]
    metrics += [{**key, "controller": ev.CONVERGED, "seed": s, "success": conv,
                 "rti_steps": 0, "rti_rejected": 0} for s, (*_, conv) in seeds.items()]
    summary = [{**key, "controller": ev.RTI, "episodes": 4, "success_rate": 0.5,
                "rti_rejected_fraction": 180 / 400, "rti_steps": 400, "rti_recovered": 0,
                "rti_rejected": 180, "final_position_error_max": "nan", "cost_mean": 20.0,
                "solver_failures": 0},
               {**key, "controller": ev.CONVERGED, "episodes": 4, "success_rate": 0.5,
                "rti_rejected_fraction": "nan", "rti_steps": 0, "rti_recovered": 0,
                "rti_rejected": 0, "final_position_error_max": "nan", "cost_mean": 18.0,
                "solver_failures": 0}]
    for name, rows in (("metrics.csv", metrics), ("summary.csv", summary)):
        with (tmp_path / name).open("w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    pair = ev.paired(tmp_path / "metrics.csv")[("cartpole", "online", "fixed truth", "200")]
    assert (pair["rti_only"], pair["both"], pair["converged_only"]) == (1, 1, 1)
    assert pair["rejected_both_won"] == pytest.approx(0.02)
    (cell,) = ev.cells(tmp_path / "summary.csv")
    assert (cell["success_rti"], cell["success_converged"]) == (2, 2)
    assert not cell["met"]  # 45% of the RTI steps rejected
    text = ev.write(tmp_path).read_text()
    assert "| 1 / 1 / 1 | 2 |" in text and "**no**" in text
