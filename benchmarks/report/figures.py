"""The report's figures: one function per figure, each returning the matplotlib figure;
:func:`_save` writes one next to the report."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import (
    FixedFormatter,
    FixedLocator,
    FormatStrFormatter,
    LogLocator,
    NullFormatter,
    NullLocator,
)

from benchmarks.compute import STEP_SCALING
from benchmarks.controllers import CONTROLLERS, ENVS
from benchmarks.report.common import (
    _env_model,
    _env_title,
    _label,
    _max_trials,
    _notes,
    _style,
    _system,
)
from benchmarks.report.load import Trial
from benchmarks.report.published import PUBLISHED_ANCHORS
from benchmarks.styles import EPISODIC, RTI, WARM_DUALS, axis_label


def _control_period_line(ax: Any, dt: float) -> Any:
    """A horizontal line (returned) at the control period ``dt`` (s) on an axis of step times
    in ms: a step above it is not real-time feasible."""
    return ax.axhline(1e3 * dt, color="tab:red", ls=":", lw=1.4, zorder=6,
               label=f"control period ({1e3 * dt:g} ms)")


def _scheme_notes(controllers: Iterable[str]) -> list[str]:
    """``["dashed: episodic", "dash-dot: real-time iteration"]``, naming only the line styles
    of the schemes that ``controllers`` use (empty if all are solid)."""
    used = {_style(c).linestyle for c in controllers}
    return [text for ls, text in ((EPISODIC, "dashed: episodic"),
                                  (RTI, "dash-dot: real-time iteration"),
                                  (WARM_DUALS, "dotted: converged, warm-started multipliers"))
            if ls in used]


def _save(fig: Any, out_dir: Path, name: str) -> str:
    fig.savefig(out_dir / name, dpi=90, bbox_inches="tight")
    plt.close(fig)
    return name


def trajectories_figure(env: str, scenario: str, chosen: dict[str, Trial]) -> Any:
    """States and controls against time, one line per controller (one trial each), each panel
    labelled with its unit; the goal of every weighted state dotted."""
    model = _env_model(env, scenario)
    system = _system(env)
    names = [*model.state_names, *model.control_names]
    n, ncols = len(names), 4 if len(names) > 9 else 3
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 2.6 * nrows), squeeze=False)
    seeds = sorted({t.spec.seed for t in chosen.values()})
    for c, t in chosen.items():
        obs, act = t.arrays["obs"], t.arrays["action"]
        t_obs = np.arange(len(obs)) * model.dt
        st = _style(c)
        for i in range(n):
            ax = axes.flat[i]
            if i < model.n_states:
                ax.plot(t_obs, obs[:, i], label=_label(c), **st.line(len(t_obs)))
            else:
                ax.step(t_obs[:-1], act[:, i - model.n_states], where="post", label=_label(c),
                        **st.line(len(t_obs) - 1))
    goal = model.task.goal
    for i, name in enumerate(names):
        ax = axes.flat[i]
        ax.set_ylabel(axis_label(system, name), fontsize=9)
        ax.grid(alpha=0.3)
        if i < model.n_states and model.task.Q[i, i] > 0:
            ax.axhline(goal[i], color="0.45", lw=0.8, ls=":", zorder=1)
        if i >= n - ncols:
            ax.set_xlabel("time (s)")
    spare = list(axes.flat)[n:]
    for ax in spare:
        ax.axis("off")
    if spare:  # the legend in an empty panel, where it hides no line
        handles, labels = axes.flat[0].get_legend_handles_labels()
        spare[0].legend(handles, labels, loc="center", fontsize=8,
                        ncols=1 if len(labels) <= 8 else 2)
    else:
        axes.flat[0].legend(fontsize=7)
    seed_text = f"seed {seeds[0]}" if len(seeds) == 1 else f"lowest seed each ({seeds})"
    fig.suptitle(f"{_env_title(env, scenario)}: states and controls, {seed_text}"
                 f"{_notes(_scheme_notes(chosen))}", fontsize=10)
    fig.tight_layout()
    return fig


def paths_figure(env: str, scenario: str, groups: dict[str, list[Trial]]) -> Any:
    """Paths in the plane of the first two states of every episode, one panel per controller,
    with the task's obstacles (and obstacle + body radius, dashed), each episode's start, the
    goal, and the points in contact with an obstacle."""
    model = _env_model(env, scenario)
    task, system = model.task, _system(env)
    goal = np.asarray(task.goal, float)[:2]
    points = [goal[None, :]]
    for ob in task.obstacles:
        reach = ob.radius + task.body_radius
        points.append(np.asarray(ob.center, float) + np.array([[-reach, -reach], [reach, reach]]))
    points += [t.arrays["obs"][:, :2] for ts in groups.values() for t in ts]
    allp = np.concatenate(points)
    finite = allp[np.all(np.isfinite(allp), axis=1)]
    low, high = finite.min(axis=0), finite.max(axis=0)
    pad = 0.08 * float(np.max(high - low)) + 0.1
    fig, axes = plt.subplots(1, len(groups), figsize=(4.3 * len(groups), 4.5), squeeze=False,
                             sharex=True, sharey=True)
    for ax, (c, ts) in zip(axes.flat, groups.items(), strict=True):
        for ob in task.obstacles:
            ax.add_patch(plt.Circle(ob.center, ob.radius, color="0.75", zorder=1))
            ax.add_patch(plt.Circle(ob.center, ob.radius + task.body_radius, fill=False,
                                    ls="--", color="0.4", lw=0.8, zorder=1))
        st = _style(c)
        n_viol = n_goal = 0
        for t in ts:
            xy = t.arrays["obs"][:, :2]
            n_viol += t.metrics["violations"] > 0
            n_goal += bool(t.metrics["success"])
            ax.plot(xy[:, 0], xy[:, 1], color=st.color, ls=st.linestyle, lw=1.0, alpha=0.75,
                    zorder=3)
            ax.plot(*xy[0], "o", color="0.2", ms=4, zorder=4)
            contact = np.zeros(len(xy), bool)
            for ob in task.obstacles:
                contact |= ob.clearance(xy, task.body_radius) < 0
            if contact.any():
                ax.plot(xy[contact, 0], xy[contact, 1], "x", color="tab:red", ms=7, mew=1.8,
                        zorder=5)
        ax.plot(*goal, "*", color="tab:green", ms=13, zorder=4)
        ax.set_aspect("equal")
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_xlabel(axis_label(system, model.state_names[0]))
        ax.grid(alpha=0.3)
        ax.set_title(f"{_label(c)}: {len(ts)} episodes\n{n_goal} reached the goal, "
                     f"{n_viol} touched an obstacle", fontsize=9, color=st.color)
    axes.flat[0].set_ylabel(axis_label(system, model.state_names[1]))
    fig.suptitle(f"{_env_title(env, scenario)}: paths"
                 + _notes("dot: start, star: goal, red x: obstacle contact",
                          "dashed circle: obstacle + body radius",
                          [n.replace("dashed", "dashed path") for n in _scheme_notes(groups)]),
                 fontsize=10)
    fig.tight_layout()
    return fig


def _style_boxes(parts: dict[str, Any], controllers: Sequence[str]) -> None:
    """Colour each box of an ``Axes.boxplot(..., patch_artist=True)`` as its controller."""
    for i, c in enumerate(controllers):
        st = _style(c)
        box = parts["boxes"][i]
        box.set(facecolor=matplotlib.colors.to_rgba(st.color, 0.25), edgecolor=st.color,
                linestyle=st.linestyle, linewidth=1.4, label=_label(c))
        for key in ("whiskers", "caps"):
            for artist in parts[key][2 * i: 2 * i + 2]:
                artist.set(color=st.color)
        parts["medians"][i].set(color="k", linewidth=1.6)
        if parts["fliers"]:
            parts["fliers"][i].set(markeredgecolor=st.color, marker=st.marker)


def step_times_figure(groups: dict[str, dict[str, list[np.ndarray]]], scenarios: dict[str, str]
                      ) -> Any:
    """Box plots of the per-step ``act`` times, one panel per env (``groups[env][controller]``
    are the trials' ``act_time`` arrays in seconds), each with the env's control period."""
    fig, axes = plt.subplots(1, len(groups), figsize=(5.2 * len(groups), 4.4), squeeze=False)
    for ax, (env, per) in zip(axes.flat, groups.items(), strict=True):
        names = list(per)
        data = [1e3 * np.concatenate(per[c]) for c in names]
        parts = ax.boxplot(data, whis=(5, 95), showfliers=True, patch_artist=True,
                           flierprops={"markersize": 2})
        _style_boxes(parts, names)
        period = _control_period_line(ax, _env_model(env, scenarios[env]).dt)
        ax.set_xticks(range(1, len(names) + 1), [_label(c) for c in names], rotation=60,
                      ha="right", fontsize=8)
        ax.set_yscale("log")
        ax.set_ylabel("act() time per step (ms)")
        ax.set_title(ENVS[env].env_id or env, fontsize=9)
        ax.grid(alpha=0.3, axis="y")
        ax.legend(handles=[period], fontsize=7, loc="best")
    controllers = {c for per in groups.values() for c in per}
    fig.suptitle("Per-step compute" + _notes("whiskers 5-95%",
                                             "above the control period: not real-time",
                                             [n.replace("dashed", "dashed box").replace(
                                                 "dash-dot", "dash-dot box")
                                              for n in _scheme_notes(controllers)]),
                 fontsize=10)
    fig.tight_layout()
    return fig


def scaling_figure(groups: Sequence[tuple[str, str, str]],
                   trials: dict[tuple[str, str, str], list[Trial]]) -> Any:
    """Box plots of the ``act`` times against the samples learned, one panel per (env,
    scenario, controller), each with the env's control period."""
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 3.8), squeeze=False)
    for ax, group in zip(axes.flat, groups, strict=True):
        env, scenario, controller = group
        st = _style(controller)
        params = []
        for t in trials[group]:
            if t.ok:
                params.append(t.spec.param)
                parts = ax.boxplot([1e3 * t.arrays["act_time"]], positions=[t.spec.param],
                                   widths=[0.25 * t.spec.param], whis=(5, 95),
                                   showfliers=False, patch_artist=True)
                _style_boxes(parts, [controller])
        period = _control_period_line(ax, _env_model(env, scenario).dt)
        ax.set_xscale("log")
        ax.set_xticks(params, [str(p) for p in params])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("samples learned before the episode")
        ax.set_ylabel("act() time per step (ms)")
        ax.set_title(f"{_label(controller)}, {env} `{scenario}`", fontsize=9, color=st.color)
        ax.grid(alpha=0.3)
        ax.legend(handles=[period], fontsize=7, loc="best")
    fig.suptitle("Per-step compute against the samples learned (whiskers 5-95%)", fontsize=10)
    fig.tight_layout()
    return fig


def step_scaling_figure(rows: Sequence[dict[str, Any]]) -> Any:
    """Median step time against each scaled setting (one column per kind of
    :data:`benchmarks.compute.STEP_SCALING`, one row per env), one line per recipe."""
    kinds = [k for k in STEP_SCALING if any(r["measurement"] == k for r in rows)]
    envs = list(dict.fromkeys((r["env"], r["scenario"]) for r in rows))
    fig, axes = plt.subplots(len(envs), len(kinds), figsize=(4.2 * len(kinds), 3.3 * len(envs)),
                             squeeze=False)
    for i, (env, scenario) in enumerate(envs):
        for j, kind in enumerate(kinds):
            ax = axes[i, j]
            mine = [r for r in rows if (r["env"], r["scenario"], r["measurement"])
                    == (env, scenario, kind)]
            for c in dict.fromkeys(r["controller"] for r in mine):
                pts = sorted((r["param"], r["act_median_ms"]) for r in mine
                             if r["controller"] == c)
                ax.plot(*zip(*pts, strict=True), **_style(c).line(len(pts), len(pts)),
                        label=_label(c))
            _control_period_line(ax, _env_model(env, scenario).dt)
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
            ax.yaxis.set_minor_formatter(NullFormatter())
            ax.set_xticks(sorted({r["param"] for r in mine}))
            ax.set_xlabel(STEP_SCALING[kind])
            ax.set_ylabel("act median (ms)")
            ax.set_title(f"{env} `{scenario}`", fontsize=9)
            ax.grid(alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=7)
    fig.suptitle("Step time against one setting at a time (seed 0, medians)", fontsize=10)
    fig.tight_layout()
    return fig


def update_time_figure(rows: Sequence[dict[str, Any]]) -> Any:
    """Median and p95 single-sample update time against the rank r (rows of
    :func:`compute_rows`, measurement ``ssgp-update-time``); ticks at the ranks measured."""
    ranks = [int(r["r"]) for r in rows]
    fig, ax = plt.subplots(figsize=(5.2, 3.8))
    color = _style("ssgp-mpc").color
    ax.plot(ranks, [r["update_median_ms"] for r in rows], "o-", color=color, label="median")
    ax.plot(ranks, [r["update_p95_ms"] for r in rows], "s--", color=color, mfc="none",
            label="p95")
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(FixedLocator(ranks))
    ax.xaxis.set_major_formatter(FixedFormatter([str(r) for r in ranks]))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_yscale("log")
    ax.set_xlabel("rank r (frequencies, count; 2r features per output)")
    ax.set_ylabel("update time per sample (ms)")
    envs = sorted({str(r["env"]) for r in rows})
    ax.set_title(f"IncrementalSSGP.update, one sample at a time ({', '.join(envs)})",
                 fontsize=9)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def data_efficiency_figure(env: str, rows: Sequence[dict[str, Any]], dt: float) -> Any:
    """Success rate and mean interaction time before success against the initial samples, per
    controller (the references as horizontal lines), with the published anchors of ``env``."""
    fig, (ax_s, ax_t) = plt.subplots(1, 2, figsize=(11, 4))
    by: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        by[r["controller"]].append(r)
    for c, group in by.items():
        st = _style(c)
        if CONTROLLERS[c].learner is None:
            r = group[0]
            ax_s.axhline(r["success_rate"], color=st.color, ls=":", lw=1, label=c)
            if math.isfinite(r["interaction_mean_s"]):
                ax_t.axhline(r["interaction_mean_s"], color=st.color, ls=":", lw=1,
                             label=c)
            continue
        group = sorted(group, key=lambda r: r["n_init"])
        x = [r["n_init"] * dt for r in group]
        ax_s.plot(x, [r["success_rate"] for r in group], **st.line(len(x), len(x)),
                  label=f"{c} (trial 1)")
        ax_s.plot(x, [r["trials_success_rate"] for r in group], color=st.color, ls="--",
                  lw=0.8, label=f"{c} (within {_max_trials()} trials)")
        ax_t.plot(x, [r["interaction_trials_mean_s"] for r in group],
                  **st.line(len(x), len(x)), label=c)
    for a in PUBLISHED_ANCHORS.get(env, ()):  # whole trials counted: see the table's notes
        rate = f", {a.success:.0%} success" if math.isfinite(a.success) else ""
        ax_t.axhline(a.interaction_s, color="0.5", ls="-.", lw=0.8)
        ax_t.annotate(f"{a.method} (published{rate})", (0, a.interaction_s), fontsize=7,
                      color="0.3", xytext=(2, 2), textcoords="offset points")
    ax_s.set_xlabel("initial data (s of interaction)")
    ax_s.set_ylabel("success rate")
    ax_s.set_ylim(-0.05, 1.05)
    ax_t.set_xlabel("initial data (s of interaction)")
    ax_t.set_ylabel(f"interaction before success, within {_max_trials()} trials (s)")
    ax_s.legend(fontsize=6)
    ax_t.legend(fontsize=6)
    fig.suptitle(f"{env}: data efficiency")
    fig.tight_layout()
    return fig
