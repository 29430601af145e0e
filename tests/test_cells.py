"""The robustness envelope's trial cells (benchmarks.trial.Cell): names, data, starts."""

from __future__ import annotations

import numpy as np
import pytest

import gp_envs
from benchmarks.controllers import make_env
from benchmarks.systems import benchmark_system
from benchmarks.trial import Cell, TrialSpec, _data_env, _start_options


def test_the_default_cell_keeps_existing_trial_names_and_round_trips():
    spec = TrialSpec("episode", "cartpole", "online", "ssgp-mpc", 3)
    assert spec.key == "episode_cartpole_online_ssgp-mpc_s3"
    varied = TrialSpec("episode", "cartpole", "online", "ssgp-mpc", 3,
                       cell=Cell(randomize=0.1, data="diff", noise=0.005, start="perturbed",
                                 kappa=2.0))
    assert varied.key == ("episode_cartpole_online_ssgp-mpc_s3_r0.1_ddiff_noise0.005_"
                          "perturbed_k2")
    assert TrialSpec(**varied.to_dict()) == varied  # as the runner rebuilds it from a file
    assert Cell().describe() == "fixed truth"
    assert "randomize 0.1, diff data" in varied.cell.describe()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"data": "other"}, "data"), ({"start": "random"}, "start"), ({"randomize": -0.1}, "randomize"),
    ({"noise": float("nan")}, "noise"), ({"kappa": -1.0}, "kappa")])
def test_bad_cells_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Cell(**kwargs)


def _truth(env):
    return dict(gp_envs.oracle_model(env).params)


def test_same_data_come_from_the_episodes_truth_and_diff_data_from_another_draw():
    spec = TrialSpec("episode", "cartpole", "online", "ssgp-mpc", 7, cell=Cell(randomize=0.1))
    env = make_env("cartpole", "online", randomize=0.1)
    env.reset(seed=7)
    episode_truth = _truth(env)
    same = _data_env(env, spec)
    same.reset(seed=12345)  # any data reset: the truth is fixed to the episode's draw
    assert _truth(same) == pytest.approx(episode_truth)
    diff_spec = TrialSpec("episode", "cartpole", "online", "ssgp-mpc", 7,
                          cell=Cell(randomize=0.1, data="diff"))
    diff = _data_env(env, diff_spec)
    diff.reset(seed=12345)
    other = _truth(diff)
    assert other != pytest.approx(episode_truth)
    for name, value in other.items():  # a draw of the same spread
        assert abs(value / gp_envs.get_system("cartpole").env_class().SCENARIOS[
            "online"].true[name] - 1) <= 0.1 + 1e-12
    assert _data_env(make_env("cartpole", "online"), TrialSpec(
        "episode", "cartpole", "online", "ssgp-mpc", 7)) is None  # fixed truth: the env itself


def test_data_for_a_time_varying_episode_come_from_the_system_before_its_change():
    spec = TrialSpec("episode", "quadrotor", "online-payload", "ssgp-mpc", 0)
    env = make_env("quadrotor", "online-payload")
    data_env = _data_env(env, spec)
    data_env.reset(seed=0)
    hover = np.full(4, data_env.unwrapped.nominal_model.task.u_ref[0], np.float32)
    for _ in range(100):  # past the 3 s change
        data_env.step(hover)
    assert _truth(data_env)["m"] == pytest.approx(1.0)


def test_perturbed_starts_are_seeded_offsets_within_the_stated_widths():
    env = make_env("cartpole", "online")
    spec = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 4,
                     cell=Cell(start="perturbed"))
    a = _start_options(env, spec)["state"]
    b = _start_options(env, spec)["state"]
    np.testing.assert_array_equal(a, b)
    env.reset(seed=4)
    offset = a - gp_envs.oracle_state(env)
    assert np.all(np.abs(offset) <= np.array(benchmark_system("cartpole").perturbation))
    assert np.abs(offset[0]) > 0.0
    c = _start_options(env, TrialSpec("episode", "cartpole", "online", "nominal-mpc", 5,
                                      cell=Cell(start="perturbed")))["state"]
    assert not np.allclose(a, c)
    assert _start_options(env, TrialSpec("episode", "cartpole", "online", "nominal-mpc", 4)
                          ) is None


def test_a_system_without_perturbation_widths_has_no_perturbed_start(monkeypatch):
    import dataclasses

    import benchmarks.trial as trial

    bare = dataclasses.replace(benchmark_system("cartpole"), perturbation=None)
    monkeypatch.setattr(trial, "benchmark_system", lambda name: bare)
    with pytest.raises(ValueError, match="no perturbation widths"):
        _start_options(make_env("cartpole", "online"), TrialSpec(
            "episode", "cartpole", "online", "nominal-mpc", 4, cell=Cell(start="perturbed")))


def _trial(spec: TrialSpec, **metrics):
    from pathlib import Path

    from benchmarks.report import Trial

    m = {"family": "mpc", "mode": "receding", "success": True, "success_held": True,
         "time_to_success_s": 1.0, "cost": 10.0, "final_distance": 0.1,
         "final_position_error": float("nan"), "violations": 0, "data_steps": 5,
         "solver_failures": 0, "fallbacks": 0}
    m.update(metrics)
    return Trial(spec, Path("/nonexistent"), {"status": "ok", "metrics": m},
                 _arrays={"act_time": np.full(3, 1e-3)})


def test_the_robustness_section_reports_each_cell_against_the_oracle():
    from pathlib import Path

    from benchmarks.presets import Experiment
    from benchmarks.report import Context, section_robustness, summarize

    cell = Cell(randomize=0.1, data="diff")
    trials = [_trial(TrialSpec("episode", "cartpole", "online", c, s, cell=cell), success=ok)
              for s in range(4)
              for c, ok in (("nominal-mpc", False), ("ssgp-mpc", s < 3), ("oracle-mpc", True))]
    trials += [_trial(TrialSpec("episode", "quadrotor", "online-payload", "ssgp-mpc", s),
                      final_position_error=0.004 * (s + 1), recovery_s=[0.5, float("nan")][s])
               for s in range(2)]
    trials += [_trial(TrialSpec("episode", "dubins", "paper", "ssgp-mpc", 0), violations=2)]
    exp = Experiment("robustness", "t", "d", tuple(t.spec for t in trials), ("robustness",))
    ctx = Context(Path("/nonexistent"), {t.spec: t for t in trials},
                  {"robustness": summarize("robustness", trials)}, [], [])
    lines = section_robustness(ctx, exp)
    cart = next(line for line in lines if line.startswith("| cartpole"))
    assert "randomize 0.1, diff data" in cart and "0/4" in cart and "3/4" in cart
    assert "| 0.75 |" in cart  # SSGP's success as a share of the oracle's
    quad = next(line for line in lines if line.startswith("| quadrotor"))
    assert "0.008" in quad and "1/2, 0.50" in quad  # largest error; recovered 1 of 2
    dubins = next(line for line in lines if line.startswith("| dubins"))
    assert "`paper-mpc` 1" in dubins  # one episode with obstacle contact


def test_readme_tables_show_cells_and_initial_samples_and_skip_trials_not_run(tmp_path):
    import csv

    from benchmarks.readme_table import readme_table

    base = {"experiment": "robustness", "env": "cartpole", "scenario": "online",
            "label": "SSGP MPC", "status": "ok", "episodes": "20", "success_rate": "0.5",
            "success_ci_low": "0.3", "success_ci_high": "0.7", "cost_mean": "30",
            "cost_ci_low": "25", "cost_ci_high": "35", "final_distance_mean": "0.1",
            "episodes_with_violation": "0", "data_steps_mean": "320", "act_median_ms": "40"}
    rows = [{**base, "cell": "fixed truth", "n_init": "200"},
            {**base, "cell": "randomize 0.1, diff data", "n_init": "50"},
            {**base, "cell": "noise 0.005", "n_init": "200", "status": "missing",
             "episodes": "0"}]
    with open(tmp_path / "summary.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    table = readme_table(tmp_path).splitlines()
    assert table[0].startswith("| env | scenario | cell | initial samples | controller |")
    assert len(table) == 4  # header, rule, two rows: the trials not run yet are left out
    assert "| randomize 0.1, diff data | 50 | SSGP MPC |" in table[3]
