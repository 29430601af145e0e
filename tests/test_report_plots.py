"""The report's figures: one fixed style per controller, units, control periods, honest titles.

Figures are checked through matplotlib's object model (lines, labels, ticks), not by comparing
images: most tests build them from synthetic trials, one from a tiny real benchmark run.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

import gp_envs
from benchmarks import report
from benchmarks.cli import main
from benchmarks.controllers import CONTROLLERS, ENVS
from benchmarks.presets import Experiment
from benchmarks.report import Trial
from benchmarks.styles import (
    EPISODIC,
    RECEDING,
    RTI,
    SQP_SCHEME,
    STYLES,
    WARM_DUALS,
    axis_label,
    style,
    unit,
)
from benchmarks.trial import TrialSpec
from gp_agents.mpc.diagnostics import StepStatus


# ----------------------------------------------------------------------------- helpers
def _dt(env: str) -> float:
    return float(gym.make(ENVS[env].env_id).unwrapped.nominal_model.dt)


def _metrics(**over: Any) -> dict[str, Any]:
    m: dict[str, Any] = {
        "family": "mpc", "mode": "receding", "success": True, "success_held": True,
        "time_to_success_s": 1.0, "cost": 10.0, "final_distance": 0.1,
        "final_position_error": math.nan, "violations": 0, "data_steps": 5,
        "solver_failures": 0, "fallbacks": 0, "plan_plant_defect": math.nan,
    }
    m.update(over)
    return m


def _episode(env: str, controller: str, seed: int = 0, n: int = 30, obs: np.ndarray | None = None,
             **metrics: Any) -> Trial:
    """A finished synthetic episode trial of ``n`` steps."""
    spec = TrialSpec("episode", env, ENVS[env].default_scenario, controller, seed)
    model = gym.make(ENVS[env].env_id).unwrapped.nominal_model
    rng = np.random.default_rng(seed + len(controller))
    if obs is None:
        obs = np.cumsum(rng.normal(0, 0.1, (n + 1, model.n_states)), axis=0)
    arrays = {"obs": obs, "action": rng.normal(size=(len(obs) - 1, model.n_controls)),
              "act_time": rng.uniform(1e-3, 2e-2, len(obs) - 1)}
    record = {"status": "ok", "metrics": _metrics(**metrics)}
    return Trial(spec, Path("/nonexistent"), record, _arrays=arrays)


def _lines_by_label(ax: Any) -> dict[str, Line2D]:
    return {str(line.get_label()): line for line in ax.get_lines()}


def _control_period_lines(ax: Any) -> list[Line2D]:
    return [line for line in ax.get_lines()
            if str(line.get_label()).startswith("control period")]


# ----------------------------------------------------------------------------- tables
def _scheme(recipe) -> str | None:
    """The scheme's name (None: a recipe's own scheme on each env)."""
    scheme = dict(recipe.settings).get("scheme", recipe.scheme)
    return scheme if scheme is None or isinstance(scheme, str) else scheme.name


def _warm(recipe) -> bool:
    scheme = dict(recipe.settings).get("scheme")
    return bool(getattr(scheme, "warm_start_duals", False))


def test_every_recipe_has_one_fixed_distinct_style() -> None:
    main = {c for c, r in CONTROLLERS.items() if r.alias_of is None}
    assert set(STYLES) == main, "every recipe, and only recipes, have a style"
    for c, r in CONTROLLERS.items():
        if r.alias_of is not None:  # an older name looks like what it stands for
            assert style(c) == style(r.alias_of)
    triples = [(s.color, s.linestyle, s.marker) for s in STYLES.values()]
    assert len(set(triples)) == len(triples)
    markers = [s.marker for s in STYLES.values()]
    assert len(set(markers)) == len(markers)  # points-only plots tell them apart too
    # receding-horizon recipes of different models never share a colour
    receding = [c for c, r in CONTROLLERS.items()
                if r.mode == "receding" and _scheme(r) == "converged" and r.alias_of is None
                and not _warm(r)]
    colours = [style(c).color for c in receding]
    assert len(set(colours)) == len(colours)
    assert style("ssgp-mpc").color != style("ssgp-mpc-linearized").color
    for name, recipe in CONTROLLERS.items():
        expected = (RTI if _scheme(recipe) in ("rti", "rti-split")
                    else SQP_SCHEME if _scheme(recipe) == "sqp"
                    else WARM_DUALS if _warm(recipe)
                    else EPISODIC if recipe.mode == "episodic" else RECEDING)
        assert style(name).linestyle == expected, name
        if recipe.mode == "episodic":  # same model, same colour
            assert style(name).color == style(f"{recipe.base}-mpc").color
    # the nominal is drawn thick and underneath the thin oracle: both visible where they meet
    for nominal, oracle in (("nominal-mpc", "oracle-mpc"), ("nominal-episodic", "oracle-episodic"),
                            ("nominal-mpc-rti", "oracle-mpc-rti"),
                            ("nominal-mpc-warm-duals", "oracle-mpc-warm-duals")):
        assert style(nominal).zorder < style(oracle).zorder
        assert style(nominal).linewidth >= 2 * style(oracle).linewidth
    with pytest.raises(KeyError, match="no plot style"):
        style("lqr")


def test_units_cover_every_state_and_control_of_every_registered_system() -> None:
    systems = set()
    for env_id in gp_envs.ENV_IDS:
        physics = gym.make(env_id).unwrapped.physics
        system = physics.__name__.rsplit(".", 1)[-1]
        systems.add(system)
        for name in (*physics.STATE_NAMES, *physics.CONTROL_NAMES):
            assert unit(system, name), (system, name)
    assert axis_label("cartpole", "theta") == "theta (rad)"
    assert axis_label("quadrotor", "F3") == "F3 (N)"
    assert axis_label("pendulum", "tau") == "tau (N m)"
    with pytest.raises(KeyError, match="no state or control 'x'"):
        unit("pendulum", "x")
    with pytest.raises(KeyError, match="not a registered system"):
        unit("lqr", "x")


def test_render_fps_follows_the_control_period() -> None:
    for env_id in gp_envs.ENV_IDS:
        base = gym.make(env_id).unwrapped
        assert base.metadata["render_fps"] == round(1 / base.DT), env_id


# ----------------------------------------------------------------------------- figures
def test_trajectories_have_units_distinct_colours_and_say_episodic_only_when_it_ran() -> None:
    receding = ["nominal-mpc", "ssgp-mpc", "ssgp-mpc-linearized", "oracle-mpc", "sac"]
    fig = report.trajectories_figure("cartpole", "online",
                                     {c: _episode("cartpole", c) for c in receding})
    axes = fig.axes
    assert [ax.get_ylabel() for ax in axes[:5]] == [
        "x (m)", "theta (rad)", "xdot (m/s)", "thetadot (rad/s)", "f (N)"]
    for ax in axes[:5]:
        lines = _lines_by_label(ax)
        colours = {c: lines[report.cli_name(c)].get_color() for c in receding}
        assert len(set(colours.values())) == len(receding)
        nominal, oracle = lines["nominal-mpc"], lines["oracle-mpc"]
        assert nominal.get_zorder() < oracle.get_zorder()
        assert nominal.get_linewidth() > oracle.get_linewidth()
    assert "episodic" not in fig._suptitle.get_text()

    with_episodic = {c: _episode("cartpole", c) for c in ("nominal-mpc", "nominal-episodic")}
    fig = report.trajectories_figure("cartpole", "online", with_episodic)
    assert "dashed: episodic" in fig._suptitle.get_text()
    assert "dash-dot" not in fig._suptitle.get_text()
    lines = _lines_by_label(fig.axes[0])
    assert lines["nominal-episodic"].get_linestyle() == "--"
    assert lines["nominal-mpc"].get_linestyle() == "-"


def test_step_times_have_the_control_period_of_each_env_and_coloured_boxes() -> None:
    groups = {env: {c: [_episode(env, c).arrays["act_time"]]
                    for c in ("nominal-mpc", "ssgp-mpc", "ssgp-mpc-linearized", "oracle-mpc")}
              for env in ("cartpole", "quadrotor", "dubins")}
    scenarios = {env: ENVS[env].default_scenario for env in groups}
    fig = report.step_times_figure(groups, scenarios)
    assert len(fig.axes) == 3
    periods = []
    for ax, env in zip(fig.axes, groups, strict=True):
        (line,) = _control_period_lines(ax)
        assert np.allclose(line.get_ydata(), 1e3 * _dt(env))
        assert ax.get_ylim()[0] <= 1e3 * _dt(env) <= ax.get_ylim()[1]
        assert "ms" in ax.get_ylabel()
        periods.append(float(line.get_ydata()[0]))
        edges = [tuple(p.get_edgecolor()) for p in ax.patches]
        assert len(edges) == 4 and len(set(edges)) == 4
    assert periods[2] == 2 * periods[0]  # Dubins: 0.1 s, cart pole: 0.05 s
    assert "episodic" not in fig._suptitle.get_text()


def test_scaling_plot_has_the_control_period() -> None:
    group = ("cartpole", "online", "ssgp-mpc")
    trials = []
    for n in (200, 1000):
        t = _episode("cartpole", "ssgp-mpc")
        trials.append(Trial(TrialSpec("ssgp-act-scaling", *group, 0, param=n), t.path,
                            t.record, _arrays=t._arrays))
    fig = report.scaling_figure([group], {group: trials})
    (line,) = _control_period_lines(fig.axes[0])
    assert np.allclose(line.get_ydata(), 1e3 * _dt("cartpole"))


def test_update_time_plot_ticks_at_the_ranks_used_with_a_title_and_units() -> None:
    rows = [{"r": r, "env": "cartpole", "update_median_ms": 0.01 * r, "update_p95_ms": 0.02 * r}
            for r in (25, 50, 100)]
    fig = report.update_time_figure(rows)
    ax = fig.axes[0]
    fig.canvas.draw()
    assert list(ax.get_xticks()) == [25, 50, 100]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["25", "50", "100"]
    assert not ax.get_xticks(minor=True).size
    assert ax.get_title() and "(ms)" in ax.get_ylabel() and "r" in ax.get_xlabel()


def test_paths_figure_draws_the_tasks_obstacles_and_marks_contacts() -> None:
    task = gym.make(ENVS["dubins"].env_id).unwrapped.nominal_model.task
    (obstacle,) = task.obstacles
    through = np.linspace([5.0, 5.0, 0.0], [*obstacle.center, 0.0], 20)  # ends inside
    around = np.concatenate([np.linspace([5.0, 5.0, 0.0], [6.5, -1.0, 0.0], 10),
                             np.linspace([6.5, -1.0, 0.0], [*task.goal[:2], 0.0], 10)])
    assert np.all(obstacle.clearance(around[:, :2], task.body_radius) > 0)
    groups = {"nominal-mpc": [_episode("dubins", "nominal-mpc", obs=through, violations=3,
                                       success=False)],
              "oracle-mpc": [_episode("dubins", "oracle-mpc", obs=around)]}
    fig = report.paths_figure("dubins", "paper", groups)
    ax_nominal, ax_oracle = fig.axes
    for ax in fig.axes:
        circles = [p for p in ax.patches if isinstance(p, Circle)]
        assert sorted(c.get_radius() for c in circles) == pytest.approx(
            [obstacle.radius, obstacle.radius + task.body_radius])
        assert ax.get_xlabel() == "x (m)"
    assert ax_nominal.get_ylabel() == "y (m)"
    contacts = [line for line in ax_nominal.get_lines() if line.get_marker() == "x"]
    assert contacts and len(contacts[0].get_xdata()) > 0
    assert not [line for line in ax_oracle.get_lines() if line.get_marker() == "x"]
    path = max(ax_nominal.get_lines(), key=lambda line: len(line.get_xdata()))
    assert path.get_color() == style("nominal-mpc").color
    assert "1 touched an obstacle" in ax_nominal.get_title()


def test_summary_position_error_max_does_not_depend_on_the_env_name() -> None:
    trials = [_episode("cartpole", "nominal-mpc", seed=s, final_position_error=v)
              for s, v in ((0, 0.1), (1, 0.3), (2, math.nan))]
    trials += [_episode("dubins", "nominal-mpc", seed=s) for s in (0, 1)]  # all NaN
    rows = {r["env"]: r for r in report.summarize("x", trials)}
    assert rows["cartpole"]["final_position_error_max"] == pytest.approx(0.3)
    assert math.isnan(rows["dubins"]["final_position_error_max"])


def test_split_latency_is_act_minus_preparation_and_its_accepted_median_skips_rejections(
        ) -> None:
    trial = _episode("quadrotor", "ssgp-mpc-rti-split", n=6)
    act = np.array([9.0, 2.0, 3.0, 40.0, 4.0, 50.0]) * 1e-3  # seconds
    preparation = np.array([0.0, 1.0, 1.0, 1.0, 1.0, 1.0]) * 1e-3
    trial.arrays.update({
        "diag_replanned": np.array([False, True, True, True, True, True]),
        "diag_solve_time": act / 2, "diag_act_time": act,
        "diag_preparation_time": preparation,
        "diag_status": np.array([StepStatus.REUSE, StepStatus.RTI, StepStatus.RTI,
                                 StepStatus.RTI_REJECTED, StepStatus.RTI,
                                 StepStatus.RTI_REJECTED])})
    (row,) = report.summarize("x", [trial])
    # latencies of the replanning steps: 1, 2, 39, 3, 49 ms; accepted: 1, 2, 3 ms
    assert row["latency_median_ms"] == pytest.approx(3.0)
    assert row["accepted_latency_median_ms"] == pytest.approx(2.0)
    assert row["preparation_median_ms"] == pytest.approx(1.0)


def test_acceptance_counts_rejected_of_accepted_and_rejected_rti_steps_by_the_enum() -> None:
    """A recovered RTI step is neither accepted as it was nor rejected: it is left out of the
    count, as before the statuses were an enum."""
    statuses = [StepStatus.REUSE, StepStatus.RTI, StepStatus.RTI_RECOVERED,
                StepStatus.RTI_REJECTED, StepStatus.RTI, StepStatus.SOLVED]
    trial = _episode("cartpole", "nominal-mpc-rti", n=len(statuses))
    act = np.full(len(statuses), 2e-3)
    trial.arrays.update({"diag_replanned": np.array([s != StepStatus.REUSE for s in statuses]),
                         "diag_solve_time": act / 2, "diag_act_time": act,
                         "diag_status": np.array(statuses)})
    exp = Experiment("acc", "t", "d", (trial.spec,), ("acceptance",))
    ctx = report.Context(Path("/nonexistent"), {trial.spec: trial},
                         {"acc": report.summarize("acc", [trial])}, [], [])
    (line,) = [x for x in report.section_acceptance(ctx, exp) if x.startswith("- cart pole")]
    assert "; 1 of 3 RTI steps rejected (33%)" in line


# ----------------------------------------------------------------------------- end to end
def test_a_tiny_real_run_draws_the_control_period_units_and_the_dubins_paths(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures: dict[str, Any] = {}
    save = report.figures._save

    def keep(fig: Any, out_dir: Path, name: str) -> str:
        figures[name] = fig
        return save(fig, out_dir, name)

    monkeypatch.setattr(report.figures, "_save", keep)
    assert main(["--controllers", "nominal-mpc,oracle-mpc", "--envs", "cartpole,dubins",
                 "--seeds", "0", "--max-steps", "3", "--workers", "0", "--no-progress",
                 "--out", str(tmp_path)]) == 0
    assert {"custom_step_times.png", "custom_dubins_paths.png",
            "custom_trajectories_cartpole_online.png",
            "custom_trajectories_dubins_paper.png"} <= set(figures)
    assert (tmp_path / "custom_dubins_paths.png").is_file()
    assert "custom_dubins_paths.png" in (tmp_path / "report.md").read_text()
    step_axes = figures["custom_step_times.png"].axes
    assert [float(_control_period_lines(ax)[0].get_ydata()[0]) for ax in step_axes] == \
        pytest.approx([1e3 * _dt("cartpole"), 1e3 * _dt("dubins")])
    traj = figures["custom_trajectories_dubins_paper.png"]
    assert [ax.get_ylabel() for ax in traj.axes[:3]] == ["x (m)", "y (m)", "psi (rad)"]
    assert "episodic" not in traj._suptitle.get_text()
    colours = {line.get_label(): line.get_color() for line in traj.axes[0].get_lines()
               if not str(line.get_label()).startswith("_")}
    assert colours == {"nominal-mpc": style("nominal-mpc").color,
                       "oracle-mpc": style("oracle-mpc").color}


def test_step_scaling_figure_has_a_line_per_recipe_at_the_values_run_and_the_period() -> None:
    rows = [{"measurement": kind, "env": "cartpole", "scenario": "gp", "controller": c,
             "param": v, "act_median_ms": 1.0 + v / 100, "solver_failures": 0,
             "rti_rejected": 0}
            for kind, values in (("step-vs-nodes", (24, 6, 10)), ("step-vs-rank", (25, 50)))
            for c in ("nominal-mpc-rti", "ssgp-mpc-rti")
            if kind != "step-vs-rank" or c.startswith("ssgp")
            for v in values]
    fig = report.step_scaling_figure(rows)
    nodes, rank = fig.axes
    lines = _lines_by_label(nodes)
    # figures name controllers by their CLI names (an older alias by the name it stands for)
    assert list(lines["nominal-mpc@rti"].get_xdata()) == [6, 10, 24]  # sorted
    assert lines["nominal-mpc@rti"].get_linestyle() == RTI
    assert lines["paper-mpc@rti"].get_color() == style("ssgp-mpc-rti").color
    assert set(_lines_by_label(rank)) >= {"paper-mpc@rti"}
    assert "nominal-mpc@rti" not in _lines_by_label(rank)
    for ax in (nodes, rank):
        (period,) = _control_period_lines(ax)
        assert np.allclose(period.get_ydata(), 1e3 * _dt("cartpole"))
    assert "nodes" in nodes.get_xlabel() and "(ms)" in nodes.get_ylabel()
