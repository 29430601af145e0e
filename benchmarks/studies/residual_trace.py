"""Why a learning MPC episode failed: the learned residual against the true one, step by step.

Runs one benchmark episode exactly as the benchmarks do (:func:`benchmarks.trial.build_episode`:
the cell's truth draw, initial data, noise and start) and, at every step, before the learner
sees the new transition: the residual target of that transition (what the nominal model got
wrong, ``benchmarks``' own :meth:`gp_agents.residual.ResidualModel.targets`, from the observed
states), the learner's prediction of it, and how far the transition's input lies from the
initial data (the largest ``|z - mean| / std`` over the learner's inputs, with the
standardization of its fit: the data's mean and spread). A learner whose error exceeds the
target's own size is worse than the nominal model there. Outcomes only. Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.residual_trace --env quadrotor --randomize 0.1 \\
        --data diff --controller ssgp-mpc-linearized-sensitivities --seed 4 [--steps 40] \\
        [--outputs 3,4,5] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

from benchmarks.cli import print_report
from benchmarks.controllers import CONTROLLERS, ENVS, check_env_scenario, check_name
from benchmarks.trial import Cell, TrialSpec, build_episode

__all__ = ["decompose", "format_decomposition", "format_trace", "trace"]


def trace(spec: TrialSpec, steps: int | None = None) -> tuple[list[dict[str, Any]], list[str],
                                                              list[str]]:
    """Run episode ``spec`` (at most ``steps`` steps) and record every transition.

    Returns:
        rows (one per step: ``step``, ``time`` (s), ``action`` (m,), ``target`` and
        ``predicted`` (d_out,) in the residual's units, ``distance``: the largest standardized
        input distance from the initial data, ``farthest``: that input's name, ``status``: the
        step's solver status, ``termination``: why the episode ended, on its last row), the
        residual's output names and its input names.

    Raises:
        ValueError: the controller learns nothing.
    """
    rows, outputs, inputs, _ = _run(spec, steps)
    return rows, outputs, inputs


def _run(spec: TrialSpec, steps: int | None) -> tuple[list[dict[str, Any]], list[str],
                                                     list[str], dict[str, Any]]:
    """:func:`trace`, and the end state: ``{"agent", "obs"}`` after the last step."""
    if CONTROLLERS[spec.controller].learner is None:
        raise ValueError(f"controller {spec.controller!r} learns nothing: no residual to trace")
    env, built, _ = build_episode(spec)
    agent, obs = built.agent, built.obs
    residual, learner = agent.config.residual.model(agent.model), agent.learner
    std = learner.standardizer_
    state_names = env.unwrapped.physics.STATE_NAMES
    outputs = [f"d({state_names[i]})/dt" for i in residual.uncertain_indices]
    inputs = list(residual.input_names)
    rows: list[dict[str, Any]] = []
    limit = steps if steps is not None else env.spec.max_episode_steps
    for k in range(int(limit)):
        action = agent.act(obs)
        next_obs, _, terminated, truncated, info = env.step(action)
        Z, Y = residual.targets(obs[None], np.asarray(action, float)[None], next_obs[None])
        z = np.abs((Z[0] - std.z_mean) / std.z_std)
        far = int(np.argmax(z))
        rows.append(dict(step=k, time=float(info["time"]), action=np.asarray(action, float),
                         target=Y[0], predicted=np.asarray(learner.predict(Z))[0],
                         distance=float(z[far]), farthest=inputs[far],
                         status=agent.diagnostics[-1].status, termination=""))
        agent.observe(obs, action, next_obs)
        obs = next_obs
        if terminated or truncated:
            rows[-1]["termination"] = info.get("termination_reason") or (
                "terminated" if terminated else "time limit")
            break
    env.close()
    return rows, outputs, inputs, {"agent": agent, "obs": obs}


def decompose(learner: Any, z: np.ndarray) -> list[dict[str, Any]]:
    """The learned residual at one input ``z`` (d_in,) split into its parts, per output, in
    the output's units: ``mean`` (the training targets' mean, the standardization's offset),
    ``se`` (the Fourier features' part), ``linear`` ((d_in,) each linear feature's part; zeros
    without linear features) and ``total`` (their sum, :meth:`predict` while the learner's
    residual is on, ``on``).

    Raises:
        ValueError: not a fitted sparse-spectrum learner (:class:`gp_agents.learners.SSGP`).
    """
    from gp_agents.learners import SSGP

    if not isinstance(learner, SSGP) or getattr(learner, "standardizer_", None) is None:
        raise ValueError("decompose needs a fitted SSGP learner")
    std = learner.standardizer_
    zs = std.transform_inputs(np.asarray(z, float).reshape(1, -1))
    n_se = 2 * learner.omega_.shape[2]
    out = []
    for j in range(learner.n_outputs_):
        F, w = learner._features(zs, j)[0], learner.weights_[j]
        linear = std.y_std[j] * F[n_se:] * w[n_se:] if F.size > n_se else np.zeros(zs.shape[1])
        se = float(std.y_std[j] * F[:n_se] @ w[:n_se])
        out.append(dict(mean=float(std.y_mean[j]), se=se, linear=linear,
                        total=float(std.y_mean[j] + se + linear.sum()),
                        on=bool(getattr(learner, "residual_on_", True))))
    return out


def format_decomposition(parts: list[dict[str, Any]], outputs: list[str], inputs: list[str],
                         z: np.ndarray, zs: np.ndarray) -> str:
    """Markdown of :func:`decompose`: one row per output, the linear parts by input (with the
    input's value and its distance from the data in standard deviations)."""
    head = "; ".join(f"{n} = {v:.3g} ({d:+.1f} sd)" for n, v, d in zip(inputs, z, zs,
                                                                         strict=True))
    lines = [f"Inputs (value, distance from the initial data in their standard deviations): "
             f"{head}.", "",
             "| output | total | target mean | SE part | linear parts (input order) | "
             "residual on |", "|---|---:|---:|---:|---|---|"]
    for name, p in zip(outputs, parts, strict=True):
        lin = ", ".join(f"{v:+.3f}" for v in p["linear"])
        lines.append(f"| {name} | {p['total']:+.3f} | {p['mean']:+.3f} | {p['se']:+.3f} | "
                     f"{lin} | {'yes' if p['on'] else 'no'} |")
    return "\n".join(lines)


def format_trace(rows: list[dict[str, Any]], outputs: list[str],
                 show: list[int] | None = None) -> str:
    """Markdown: one row per step (``target / predicted`` per shown output), then the median
    absolute error of the learner and of the nominal model (the target itself) per output."""
    show = list(range(len(outputs))) if show is None else show
    head = " | ".join(f"{outputs[j]}: target / learned" for j in show)
    lines = [f"| step | t (s) | action | {head} | input distance (farthest) | status |",
             "|---:|---:|---|" + "---|" * len(show) + "---|---|"]
    for r in rows:
        cells = " | ".join(f"{r['target'][j]:.2f} / {r['predicted'][j]:.2f}" for j in show)
        end = f" -> {r['termination']}" if r["termination"] else ""
        action = np.array2string(r["action"], precision=2, separator=", ", suppress_small=True)
        lines.append(f"| {r['step']} | {r['time']:.2f} | {action} | {cells} | "
                     f"{r['distance']:.1f} ({r['farthest']}) | {r['status'][:40]}{end} |")
    T = np.array([r["target"] for r in rows])
    P = np.array([r["predicted"] for r in rows])
    lines += ["", "| output | median abs. learned error | median abs. nominal error (target) |"
              " steps where the learner is worse |", "|---|---:|---:|---:|"]
    for j in show:
        err, nom = np.abs(P[:, j] - T[:, j]), np.abs(T[:, j])
        lines.append(f"| {outputs[j]} | {np.median(err):.3g} | {np.median(nom):.3g} | "
                     f"{int(np.sum(err > nom))}/{len(rows)} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Print (and with ``--out`` write) the trace as Markdown."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="quadrotor", help="benchmark env short name")
    parser.add_argument("--scenario", help="the env's scenario (default: its default)")
    parser.add_argument("--controller", default="ssgp-mpc-linearized-sensitivities",
                        help="a learning MPC recipe")
    parser.add_argument("--seed", type=int, default=0, help="the episode's seed")
    parser.add_argument("--randomize", type=float, default=0.0, help="Cell.randomize")
    parser.add_argument("--data", default="same", help="Cell.data: same or diff")
    parser.add_argument("--noise", type=float, default=0.0, help="Cell.noise")
    parser.add_argument("--start", default="default", help="Cell.start: default or perturbed")
    parser.add_argument("--steps", type=int, help="stop after this many steps")
    parser.add_argument("--outputs", help="comma-separated residual output indices to show")
    parser.add_argument("--decompose", metavar="U", help="after the last step, split the "
                        "learned residual at the last state and control U (comma-separated, "
                        "e.g. 0,0: at rest) into target mean, SE part and linear parts")
    parser.add_argument("--out", type=Path, help="also write the trace (Markdown) here")
    args = parser.parse_args(argv)
    try:
        check_name("env", args.env, list(ENVS))
        scenario = args.scenario or ENVS[args.env].default_scenario
        check_env_scenario(args.env, scenario)
        check_name("controller", args.controller, list(CONTROLLERS))
        cell = Cell(randomize=args.randomize, data=args.data, noise=args.noise, start=args.start)
        if args.seed < 0 or (args.steps is not None and args.steps < 1):
            raise ValueError("--seed must be >= 0 and --steps >= 1")
        spec = TrialSpec("episode", args.env, scenario, args.controller, args.seed, cell=cell)
        control = (None if args.decompose is None
                   else np.array([float(v) for v in args.decompose.split(",")]))
        rows, outputs, inputs, end = _run(spec, args.steps)
        show = None if not args.outputs else [int(i) for i in args.outputs.split(",")]
        if show is not None and not all(0 <= j < len(outputs) for j in show):
            raise ValueError(f"--outputs must be indices in 0..{len(outputs) - 1}")
    except ValueError as err:  # unknown names, bad cell values, a recipe that learns nothing
        parser.error(str(err))
    command = "python -m benchmarks.studies.residual_trace " + " ".join(
        sys.argv[1:] if argv is None else argv)
    text = (f"# Residual trace: {args.controller}, {args.env} `{scenario}`, "
            f"{cell.describe()}, seed {args.seed}\n\n`{command.strip()}`\n\n"
            f"{format_trace(rows, outputs, show)}\n")
    if control is not None:
        agent, obs = end["agent"], end["obs"]
        if control.shape != (agent.model.n_controls,):
            parser.error(f"--decompose needs {agent.model.n_controls} control values")
        z = agent.config.residual.model(agent.model).inputs(obs[None], control[None])[0]
        std = agent.learner.standardizer_
        zs = (z - std.z_mean) / std.z_std
        text += (f"\n## The learned residual after step {rows[-1]['step']} at state "
                 f"{np.array2string(np.asarray(obs), precision=3, separator=', ')}, control "
                 f"{np.array2string(control, separator=', ')}\n\n"
                 f"{format_decomposition(decompose(agent.learner, z), outputs, inputs, z, zs)}\n")
    print_report(text, args.out)


if __name__ == "__main__":
    main()
