"""The RL summary's figures: a plan's learning curves, and an env's sample efficiency against
the MPC anchors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import FormatStrFormatter, FuncFormatter

from benchmarks.rl.anchors import (
    COST_MARGIN,
    MPC_ANCHORS,
    SUCCESS_BAR,
    TRAINING_EVAL_SEEDS,
    EnvAnchors,
)
from benchmarks.rl.runs import Plan
from benchmarks.rl.seeds import METRICS, SeedRun, curve_percentiles, median_curve, policy_metrics
from benchmarks.rl.train import ENV_SHORT_NAMES


def _log_axis(ax: Any) -> None:
    ax.set_yscale("log")
    for axis in (ax.yaxis,):
        axis.set_major_formatter(FormatStrFormatter("%g"))
        axis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.tick_params(axis="y", which="minor", labelsize=7)


def _steps_fmt(v: float, _pos: Any = None) -> str:
    return f"{v / 1000:g}k"


def plot_sample_efficiency(title: str, plans: list[tuple[str, Plan, list[SeedRun]]],
                           anchors: EnvAnchors, path: Path) -> None:
    """One env's sample efficiency on one log axis of env steps: per RL plan the median over
    its seeds' training evaluations with the interquartile band (steps that at least two seeds
    reached); the MPC anchors (:data:`MPC_ANCHORS`) from the data-efficiency preset, one
    marker per initial-sample count at its mean interaction time before success in env steps
    (cells where no seed succeeded have none and are left out; success panel: also within the
    multi-trial protocol's trials, dashed); the criteria's bars dashed (cost:
    :data:`COST_MARGIN` times the oracle MPC's on RL's evaluation seeds). Left: success rate;
    right: mean cost (log)."""
    from benchmarks.styles import style
    from benchmarks.trial import MAX_TRIALS

    oracle, preset, dt = anchors.oracle, anchors.preset, anchors.dt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.4))
    for i, (name, plan, runs) in enumerate(plans):
        for ax, key in zip(axes, ("success_rate", "mean_cost"), strict=True):
            steps, (lo, med, hi) = curve_percentiles(runs, key)
            keep = steps > 0  # log axis
            if not keep.any():
                continue
            ax.fill_between(steps[keep], lo[keep], hi[keep], color=f"C{i}", alpha=0.25, lw=0)
            ax.plot(steps[keep], med[keep], "-", color=f"C{i}", lw=2,
                    label=f"{plan.algo.upper()}, {name}: median of {len(runs)} seeds, IQR band")
    for controller in MPC_ANCHORS:
        cells = sorted((r for r in preset if r["controller"] == controller),
                       key=lambda r: r["n_init"])
        if not cells:
            continue
        st, label = style(controller), f"{cells[0]['label']} (data-efficiency preset)"
        first = [r for r in cells if np.isfinite(r["interaction_mean_s"])]
        x = [r["interaction_mean_s"] / dt for r in first]
        kw = {**st.line(len(x), len(x)), "ls": "-"}
        axes[0].plot(x, [r["success_rate"] for r in first], label=f"{label}, trial 1", **kw)
        axes[1].plot(x, [r["cost_mean"] for r in first], label=f"{label}, trial 1", **kw)
        for r, xi in zip(first, x, strict=True):
            axes[0].annotate(f"{r['n_init']}", (xi, r["success_rate"]), fontsize=6,
                             color=st.color, xytext=(3, -8), textcoords="offset points")
        multi = [r for r in cells if np.isfinite(r["interaction_trials_mean_s"])]
        axes[0].plot([r["interaction_trials_mean_s"] / dt for r in multi],
                     [r["trials_success_rate"] for r in multi], color=st.color, ls="--", lw=0.8,
                     marker=st.marker, ms=4, markerfacecolor="none",
                     label=f"{label}, within {MAX_TRIALS} trials")
    axes[0].axhline(SUCCESS_BAR, color="0.4", ls="--", lw=1,
                    label=f"success {SUCCESS_BAR:g} (criterion)")
    axes[1].axhline(COST_MARGIN * oracle["mean_cost"], color="0.4", ls="--", lw=1,
                    label=f"{COST_MARGIN:g}x the oracle MPC's cost on RL's evaluation seeds")
    for ax, label in zip(axes, ("success rate", "mean cost (log)"), strict=True):
        ax.set_xscale("log")
        ax.set_xlabel("env steps (RL: training; MPC: interaction before success, initial data "
                      "included)", fontsize=8)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylim(-0.03, 1.03)
    _log_axis(axes[1])
    handles: dict[str, Any] = {}
    for ax in axes:  # one legend below both panels, each entry once
        for h, lbl in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lbl, h)
    fig.legend(list(handles.values()), list(handles), fontsize=7, loc="lower center", ncol=3,
               frameon=False)
    fig.suptitle(f"{title}: RL (training evaluations on reset seeds {TRAINING_EVAL_SEEDS.start}.."
                 f"{TRAINING_EVAL_SEEDS.stop - 1}) against the MPC's data-efficiency cells "
                 "(numbers: initial samples)", fontsize=9)
    fig.tight_layout(rect=(0, 0.03 + 0.025 * ((len(handles) + 2) // 3), 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_plan(name: str, plan: Plan, runs: list[SeedRun], path: Path) -> None:
    """Success rate, cost and final distance against env steps: a line per seed and the median
    over seeds; stars: each finished seed's final evaluation on seeds 0..19."""
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    for i, r in enumerate(runs):
        color = f"C{i}"
        steps = [c["timesteps"] for c in r.curve]
        label = f"seed {r.seed}" + ("" if r.finished else " (in progress)")
        for ax, (key, _lbl, _fmt) in zip(axes, METRICS, strict=True):
            ax.plot(steps, [c[key] for c in r.curve], "-", lw=1.0, alpha=0.75, color=color,
                    label=label)
            if r.episodes is not None:
                m = policy_metrics(r.episodes)
                ax.plot(r.metadata["training_steps"], m[key], "*", ms=13, color=color,
                        markeredgecolor="k", zorder=5)
    for ax, (key, lbl, _fmt) in zip(axes, METRICS, strict=True):
        s, m = median_curve(runs, key)
        if s.size:
            ax.plot(s, m, "-", lw=2.6, color="k", label="median over seeds")
        ax.set_xlabel("env steps")
        ax.set_ylabel(lbl + (" (log)" if key != "success_rate" else ""))
        ax.xaxis.set_major_formatter(FuncFormatter(_steps_fmt))
        ax.grid(alpha=0.3)
        if key == "success_rate":
            ax.set_ylim(-0.03, 1.03)
        else:
            _log_axis(ax)
    axes[0].plot([], [], "*", ms=11, color="0.6", markeredgecolor="k",
                 label="final policy, seeds 0..19")
    axes[0].legend(fontsize=7, loc="upper left")
    env_id = ENV_SHORT_NAMES.get(plan.env, plan.env)
    fig.suptitle(f"{env_id} ({plan.scenario}): {plan.description}\n"
                 "lines: deterministic evaluation during training on reset seeds 1000..1019 "
                 "(success, cost = -return on the plain env, final distance)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
