"""acados as a measured peer of the pseudospectral RTI on the quadrotor (issue 43, item 3).

Run (one core; the first run sets up the acados environment and compiles its solvers)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.acados_peer [--env quadrotor] [--steps 120]
        [--repeats 10] [--sqp] [--out benchmarks/results/acados_peer]

``--sqp`` adds the converged schemes to the same blocks: our nominal SQP (``scheme="sqp"``),
``make_mpc(env)`` pretrained (the robust recipe's own scheme on the quadrotor, the SQP) and
acados' converged ``SQP`` (merit backtracking, our SQP's budget, a tolerance on its KKT
residuals) on both grids.

The same OCP (dynamics, horizon, control period, cost, bounds, goal, start) is solved by

- this project: :class:`gp_agents.PseudospectralMPC` ``from_env`` on the nominal model with
  ``scheme="rti"`` (one call per step) and ``scheme="rti-split"`` (preparation after the action,
  feedback with the measured state: the latency), in this process;
- acados (``SQP_RTI``, ``PARTIAL_CONDENSING_HPIPM``, ``GAUSS_NEWTON``, ``ERK``/RK4), in a
  *separate* virtual environment (default ``~/.cache/gp-pseudospectral-mpc/acados-venv``) with
  the ``comma-deps-acados`` wheel (prebuilt acados, HPIPM, BLASFEO and a slim CasADi built for
  CPython 3.12; each solver is still compiled with the system C compiler). That wheel replaces
  ``casadi`` with a build without IPOPT, so it never enters the project's environment: the
  worker :mod:`benchmarks.studies.acados_peer_worker`, run by that environment's Python,
  imports nothing from the project and gets the OCP as JSON (:func:`export_ocp`).

Both sides run closed loops of ``--steps`` control periods on the same plant (the scenario's
true parameters, RK4 with the env's substeps: the gym env here, the worker's numpy copy of the
ODE there, checked equal by ``tests/test_acados_peer.py``) from the same seeded start, in
blocks that alternate within one invocation (``--repeats`` blocks; the order flips every
block). The per-step wall time is the median over each episode's steps after the first (the
first is a converged cold start on both sides). When acados cannot be set up or built the
study writes a report saying so, with the reason on one line, and exits 0.
"""

from __future__ import annotations

import argparse
import copy
import csv
import json
import os
import platform
import shlex
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "benchmarks" / "results" / "acados_peer"
DEFAULT_VENV = Path.home() / ".cache" / "gp-pseudospectral-mpc" / "acados-venv"
WORKER = Path(__file__).with_name("acados_peer_worker.py")
PACKAGE = "comma-deps-acados"
"""The wheel with prebuilt acados, HPIPM, BLASFEO, the Python template and a slim CasADi."""
PYTHON_VERSION = (3, 12)
"""The wheel's vendored CasADi is built for CPython 3.12."""
ENV_IDS = {"quadrotor": "gp_envs/Quadrotor-v0"}
LEARNING = "ours robust"
"""The learning RTI's label: ``make_mpc(env, "robust", scheme=...)`` pretrained on
:data:`LEARNING_SAMPLES` transitions of ``collect_initial_data(env, n, seed=BASE_SEED)``; each
episode starts from that pretrained learner and learns online within the episode."""
LEARNING_SAMPLES = 200
BASE_SEED = 100
"""Block ``k`` starts from ``env.reset(seed=BASE_SEED + k)`` on both sides (tuning seeds)."""
LONG_N = 30
"""acados' horizon of ``horizon / dt`` shooting intervals (1.5 s / 0.05 s)."""
SMOKE = "import acados, casadi, numpy; acados.smoketest()"


class AcadosUnavailableError(RuntimeError):
    """acados cannot be set up, built or run here; the message is the one-line reason."""


@dataclass
class Episode:
    """One closed loop's per-step record (either side)."""

    act_time: np.ndarray
    preparation_time: np.ndarray
    states: np.ndarray
    actions: np.ndarray
    terminated: str | None
    fallbacks: int = 0
    internal_time: np.ndarray | None = None
    """acados only: the solver's own ``time_tot`` per step (both phases of a split step)."""

    @property
    def latency(self) -> np.ndarray:
        """Per-step ``act_time - preparation_time`` (the whole step for a one-call scheme)."""
        return self.act_time - self.preparation_time


# --------------------------------------------------------------------------- the OCP as JSON
SQP_BUDGET, SQP_TOLERANCE = 30, 1e-4
"""acados' converged SQP (``--sqp``): our SQP's defaults (:class:`gp_agents.SQP`), its budget
and a tolerance on acados' KKT residuals (ours: on the full step and the violation)."""
DEFAULT = f"{LEARNING} default"
"""``make_mpc(env)``: the robust recipe with its own scheme (the SQP on the quadrotor)."""


def sqp_configs(grids: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """acados' converged SQP on each of ``grids`` (:func:`acados_grids`), merit backtracking."""
    return [{**g, "label": f"{g['label']} SQP", "nlp_solver_type": "SQP",
             "max_iter": SQP_BUDGET, "tol": SQP_TOLERANCE} for g in grids]


def acados_grids(horizon: float, dt: float, n_collocation: int) -> list[dict[str, Any]]:
    """acados' shooting grids: N = our collocation node count, and N = ``horizon / dt``.

    Each grid's first interval is one control period (the period the plant holds ``u0``, as
    our mesh's held period); the rest of the horizon is split evenly. With N = horizon / dt
    this is the uniform grid.
    """
    grids = []
    for n in dict.fromkeys((n_collocation, round(horizon / dt))):
        rest = (horizon - dt) / (n - 1)
        grids.append({"label": f"acados N={n}", "time_steps": [dt] + [rest] * (n - 1)})
    return grids


def export_ocp(env: Any, agent: Any) -> dict[str, Any]:
    """The OCP of ``agent`` (a nominal :class:`gp_agents.PseudospectralMPC` of ``env``) and the
    plant of ``env`` as JSON-ready data for the acados worker."""
    import gp_envs

    base = env.unwrapped
    model = base.nominal_model
    plant = gp_envs.oracle_model(env)
    task = model.task
    mesh = agent.config.schedule.mesh(agent.model.dt)
    if model.name != "quadrotor":
        raise ValueError(f"the acados worker has the quadrotor's ODE only, got {model.name!r}")
    if agent.config.constraints.state_penalty is None:
        raise ValueError("the acados OCP mirrors the soft state margin; state_penalty is None")
    physics = base.physics
    return {
        "system": model.name,
        "state_names": list(model.state_names),
        "control_names": list(model.control_names),
        "nominal_params": {k: float(v) for k, v in model.params.items()},
        "plant_params": {k: float(v) for k, v in plant.params.items()},
        "yaw_drag_ratio": float(physics.YAW_DRAG_RATIO),
        "dt": float(model.dt),
        "plant_substeps": int(plant.substeps),
        "horizon": float(mesh.horizon),
        "our_mesh": mesh.describe(),
        "our_nodes": int(mesh.n_collocation),
        "Q": np.asarray(task.Q).tolist(), "R": np.asarray(task.R).tolist(),
        "Qf": np.asarray(task.Qf).tolist(),
        "goal": np.asarray(task.goal).tolist(), "u_ref": np.asarray(task.u_ref).tolist(),
        "u_lb": np.asarray(model.u_lb).tolist(), "u_ub": np.asarray(model.u_ub).tolist(),
        "x_lb": np.asarray(model.x_lb).tolist(), "x_ub": np.asarray(model.x_ub).tolist(),
        "state_margin": float(agent.config.constraints.state_margin),
        "state_penalty": float(agent.config.constraints.state_penalty),
        "start": np.asarray(base._state, dtype=float).tolist(),
        "configs": acados_grids(mesh.horizon, model.dt, mesh.n_collocation),
    }


# --------------------------------------------------------------------------- the acados venv
def find_python(explicit: str | None = None) -> str:
    """The interpreter for the acados environment: ``explicit``, else a CPython 3.12 (the
    wheel's vendored CasADi is built for it), else this process's Python (whether the wheel
    works with it is then up to the import check of :func:`ensure_venv`).

    Raises:
        AcadosUnavailableError: ``explicit`` given but not a working Python.
    """
    major, minor = PYTHON_VERSION
    if explicit:
        candidates = [explicit]
    else:
        pyenv = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
        found = sorted(str(p) for p in pyenv.glob(f"{major}.{minor}*/bin/python"))
        candidates = [shutil.which(f"python{major}.{minor}"), *found]
    for cand in candidates:
        if not cand:
            continue
        try:
            out = subprocess.run([cand, "-c", "import sys; print(sys.version_info[:2])"],
                                 capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            continue
        if out.returncode == 0 and (explicit or out.stdout.strip() == str((major, minor))):
            return cand
    if explicit:
        raise AcadosUnavailableError(f"--acados-python {explicit} is not a working Python")
    return sys.executable


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else "(no output)"


def ensure_venv(venv: Path, python: str | None = None,
                run: Callable[..., subprocess.CompletedProcess] | None = None) -> Path:
    """The acados environment's Python: reused if it imports acados, else (re)created.

    Raises:
        AcadosUnavailableError: no C compiler or make, or the environment could not be
            created, installed or import acados; the message says which.
    """
    if shutil.which("make") is None:
        raise AcadosUnavailableError("'make' not found: acados compiles each solver")
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        raise AcadosUnavailableError("no C compiler (gcc/cc): acados compiles each solver")
    run = run or subprocess.run
    vpython = venv / "bin" / "python"
    if vpython.exists():
        ok = run([str(vpython), "-c", SMOKE], capture_output=True, text=True, timeout=300)
        if ok.returncode == 0:
            return vpython
    interpreter = find_python(python)
    steps = [([interpreter, "-m", "venv", "--clear", str(venv)], "creating the venv"),
             ([str(vpython), "-m", "pip", "install", "--quiet", PACKAGE],
              f"pip install {PACKAGE}"),
             ([str(vpython), "-c", SMOKE], "importing acados in the venv")]
    for cmd, what in steps:
        try:
            out = run(cmd, capture_output=True, text=True, timeout=1200)
        except (OSError, subprocess.TimeoutExpired) as err:
            raise AcadosUnavailableError(f"{what} failed: {err}") from err
        if out.returncode != 0:
            raise AcadosUnavailableError(
                f"{what} failed (exit {out.returncode}): {_last_line(out.stderr + out.stdout)}")
    return vpython


class AcadosWorker:
    """The worker process (:mod:`benchmarks.studies.acados_peer_worker`) in the acados venv.

    Args:
        python: the acados environment's interpreter.
        spec: :func:`export_ocp`'s data.
        build_dir: where the worker generates and compiles its solvers.
    """

    def __init__(self, python: Path, spec: dict[str, Any], build_dir: Path) -> None:
        build_dir.mkdir(parents=True, exist_ok=True)
        spec_path = build_dir / "ocp.json"
        spec_path.write_text(json.dumps(spec, indent=1))
        self.log_path = build_dir / "worker.log"
        self._log = self.log_path.open("w")
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        env.pop("PYTHONPATH", None)  # nothing of the project on the worker's path
        self.proc = subprocess.Popen(
            [str(python), str(WORKER), str(spec_path), str(build_dir)], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=self._log, text=True, env=env, cwd=build_dir)
        ready = self._read()
        if not ready.get("ready"):
            self.close()
            raise AcadosUnavailableError(
                f"the acados worker failed: {ready.get('error', 'no answer')} "
                f"(log: {self.log_path})")
        self.versions: dict[str, str] = ready["versions"]
        self.build_seconds: dict[str, float] = ready["build_seconds"]
        self.settings: dict[str, dict[str, Any]] = ready.get("settings", {})

    def _read(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            self.proc.wait(timeout=60)
            tail = _last_line(self.log_path.read_text()) if self.log_path.exists() else ""
            return {"ready": False, "error": f"exited with {self.proc.returncode}: {tail}"}
        return json.loads(line)

    def episode(self, config: str, x0: np.ndarray, steps: int, split: bool) -> Episode:
        """One closed loop of ``config`` from ``x0`` (see the worker's ``episode``)."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"cmd": "episode", "config": config,
                                          "x0": np.asarray(x0, float).tolist(),
                                          "steps": steps, "split": split}) + "\n")
        self.proc.stdin.flush()
        out = self._read()
        if "act_time" not in out:
            raise AcadosUnavailableError(f"the acados worker failed: {out.get('error')}")
        return Episode(np.array(out["act_time"]), np.array(out["preparation_time"]),
                       np.array(out["states"]), np.array(out["actions"]), out["terminated"],
                       fallbacks=int(sum(s != 0 for s in out["status"][1:])),
                       internal_time=np.array(out["internal_time"]))

    def close(self) -> None:
        """Ask the worker to quit and wait for it."""
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write(json.dumps({"cmd": "quit"}) + "\n")
                self.proc.stdin.flush()
                self.proc.wait(timeout=60)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
        self._log.close()


# --------------------------------------------------------------------------- our side
def run_ours(env: Any, agent: Any, seed: int, steps: int) -> tuple[Episode, np.ndarray]:
    """One closed loop of ``agent`` on ``env`` from ``env.reset(seed=seed)``; also the start."""
    obs, _ = env.reset(seed=seed)
    x0 = np.array(env.unwrapped._state, dtype=float)
    agent.reset()
    states, actions, terminated = [x0.copy()], [], None
    for _ in range(steps):
        action = agent.act(obs)
        next_obs, _, term, trunc, info = env.step(action)
        agent.observe(obs, action, next_obs)
        obs = next_obs
        actions.append(np.asarray(action, dtype=float))
        states.append(np.array(env.unwrapped._state, dtype=float))
        if term:
            terminated = info.get("termination_reason")
            break
        if trunc:
            break
    diag = agent.diagnostics_arrays()
    return Episode(np.asarray(diag["act_time"], float), np.asarray(diag["preparation_time"],
                                                                   float),
                   np.array(states), np.array(actions), terminated,
                   fallbacks=int(np.sum(diag["fallback"][1:]))), x0


# --------------------------------------------------------------------------- outcomes
def outcome(ep: Episode, spec: dict[str, Any], task: Any) -> dict[str, Any]:
    """Final position error, success (the env's rule), closed-loop cost of an episode."""
    goal = np.asarray(spec["goal"])
    pos_err = float(np.linalg.norm(ep.states[-1, :3] - goal[:3]))
    hold = round(task.hold_time / spec["dt"])
    within = np.all(np.abs(ep.states[1:, :3] - goal[:3]) <= task.goal_tolerance[:3], axis=1)
    success = ep.terminated is None and len(within) >= hold and bool(np.all(within[-hold:]))
    cost = float(sum(spec["dt"] * task.stage_cost(x, u)
                     for x, u in zip(ep.states[:-1], ep.actions, strict=True)))
    return {"final_position_error": pos_err, "success": success, "cost": cost,
            "terminated": ep.terminated or "", "steps": len(ep.actions),
            "fallbacks": ep.fallbacks}


def step_median(values: np.ndarray) -> float:
    """Median over the steps after the first (the cold start), in milliseconds."""
    rest = values[1:] if len(values) > 1 else values
    return float(np.median(rest) * 1e3)


# --------------------------------------------------------------------------- machine, report
def machine() -> dict[str, str]:
    """nproc, CPU model, OS and the thread settings of this run."""
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    nproc = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {"nproc": str(nproc), "cpu": cpu, "os": platform.platform(),
            "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS", "")}


def load_average() -> str:
    """The 1-, 5- and 15-minute load averages (other work on the machine), or "unknown"."""
    try:
        return " ".join(Path("/proc/loadavg").read_text().split()[:3])
    except OSError:
        return "unknown"


def our_versions() -> dict[str, str]:
    """Python, numpy, CasADi and the project's commit, as installed in the project's venv."""
    import casadi

    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True)
    dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "gp_agents",
                            "gp_envs"], capture_output=True, text=True)
    return {"python": platform.python_version(), "numpy": np.__version__,
            "casadi": casadi.__version__,
            "project commit": (commit.stdout.strip() or "unknown")
            + (" (gp_agents/gp_envs modified)" if dirty.stdout.strip() else "")}


def _setting(value: Any) -> str:
    """A solver option for the report: a per-stage list of equal values as one value; unset
    (acados' template then uses its default) as such."""
    if value is None:
        return "unset (acados' default)"
    if isinstance(value, list) and value and all(v == value[0] for v in value):
        return f"{value[0]} (every stage)"
    return str(value)


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return out


def write_skip(out: Path, command: str, reason: str) -> None:
    """The report of a run in which acados could not be used: skipped, and why (one line)."""
    out.mkdir(parents=True, exist_ok=True)
    m = machine()
    (out / "report.md").write_text("\n".join([
        "# acados as a measured peer: skipped", "",
        f"Command: `{command}`", "",
        f"Machine: {m['nproc']} CPU(s), {m['cpu']}; {m['os']}", "",
        f"**Skipped:** {reason}", "",
        "Nothing was measured: this run has no acados figures and no comparison.", ""]))
    with (out / "summary.csv").open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["status", "reason"])
        writer.writerow(["skipped", reason])


DIFFERENCES = """\
## Differences between the two OCPs

Same: the quadrotor's nominal dynamics (the scenario's nominal parameters), the control period
and zero-order hold of the first control, the horizon, the stage cost
`e' Q e + (u - u_ref)' R (u - u_ref)` integrated over the horizon, the terminal cost `e' Qf e`,
the hard control box, the state box shrunk by `state_margin` of each half-range and made soft
with the quadratic penalty `state_penalty * s^2` (`s` the violation), Gauss-Newton Hessians,
one SQP step per control period after a converged cold start, one core, and the plant.

Different:

- **Transcription.** Ours: Gauss pseudospectral collocation, {our_mesh} ({our_nodes} LG
  collocation nodes; the held period's control is the action sent to the plant, the rest a
  polynomial control), the state at every node a decision variable and the dynamics an equality
  at every node; the integral cost by Gauss quadrature. acados: multiple shooting with one
  explicit RK4 step per shooting interval, a control held per interval; N = {our_nodes} (our
  node count: first interval one control period, the other {rest} evenly over the rest of the
  horizon) and N = {long_n} (uniform, one interval per control period); the integral cost by
  the rectangle rule on the shooting nodes (acados scales each stage's least-squares cost by its
  time step).
- **Soft state box.** Ours penalizes the violation inside the integrand (at the collocation
  nodes, weighted by the quadrature) and keeps the env's box itself as a hard bound; acados
  puts slacks on the shrunk box at the inner shooting nodes 1..N-1 (weight `2 * state_penalty`,
  scaled by the time step like the cost), with no hard outer box and no box at the last node.
- **QP.** Ours: the project's default RTI QP solver for the quadrotor
  (`{qp_solver}`) on the collocation QP through CasADi; acados: HPIPM on the partially
  condensed shooting QP (`qp_solver_cond_N` unset: acados' template then condenses to N
  stages, i.e. HPIPM works on the sparse shooting QP as it is; a smaller `qp_solver_cond_N`
  was not tried here).
- **Warm start.** Ours: the previous plan shifted by one period (RTI linearizes there);
  acados: the previous iterate, not shifted (acados' default closed-loop use).
- **Cold start.** Ours: a converged IPOPT solve at the first step; acados: up to 50 RTI
  iterations until the KKT residuals fall below 1e-6 at the first step. The first step of each
  episode is left out of the timing medians on both sides.
- **Safety net.** Ours replaces a rejected RTI step (a failed or inaccurate QP) with a
  converged solve, timed within that step ("fallbacks"); acados applies whatever its QP
  returned ("non-zero status" counts the steps where HPIPM did not report success).
- **Python glue.** Ours: `agent.act(obs)` (checks, the plan's bookkeeping, CasADi calls from
  Python, the diagnostics record). acados: `set(0, "lbx"/"ubx", x)`, `solve()`, `get(0, "u")`
  through acados' ctypes interface, the generated C code compiled with the system compiler
  (`-O2`). Each side's wall time is measured around that per-step call; the plant step is
  outside it on both sides.
- **Plant.** Ours steps the gym env; the worker steps its own numpy copy of the same ODE with
  the scenario's true parameters and the same RK4 substeps (checked equal to the project's
  physics by `tests/test_acados_peer.py`).
"""


def write_report(out: Path, command: str, spec: dict[str, Any], worker: AcadosWorker,
                 rows: list[dict[str, Any]], ours_versions: dict[str, str], qp_solver: str,
                 seconds: float, loads: tuple[str, str]) -> None:
    """report.md and summary.csv from the measured rows (one per block and controller)."""
    out.mkdir(parents=True, exist_ok=True)
    with (out / "summary.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    labels = list(dict.fromkeys(r["controller"] for r in rows))
    blocks = sorted({r["block"] for r in rows})

    def med(label: str, key: str) -> float:
        return float(np.median([r[key] for r in rows if r["controller"] == label]))

    summary_rows = []
    for label in labels:
        rs = [r for r in rows if r["controller"] == label]
        summary_rows.append([
            label, f"{med(label, 'act_ms'):.3f}", f"{med(label, 'latency_ms'):.3f}",
            f"{np.median([r['act_p90_ms'] for r in rs]):.3f}",
            f"{sum(r['success'] for r in rs)}/{len(rs)}",
            f"{max(r['final_position_error'] for r in rs):.4f}",
            f"{np.median([r['cost'] for r in rs]):.3f}",
            sum(r["fallbacks"] for r in rs),
            "-" if np.isnan(rs[0]["solver_internal_ms"])
            else f"{np.median([r['solver_internal_ms'] for r in rs]):.3f}"])

    by = {(r["block"], r["controller"]): r for r in rows}
    pairs = [(a, b, key) for a, b, key in (
        ("ours rti", f"acados N={LONG_N}", "act_ms"),
        ("ours rti", f"acados N={spec['our_nodes']}", "act_ms"),
        ("ours rti-split", f"acados N={LONG_N} split", "latency_ms"),
        ("ours rti-split", f"acados N={spec['our_nodes']} split", "latency_ms"),
        (f"{LEARNING} rti", f"acados N={LONG_N}", "act_ms"),
        (f"{LEARNING} rti-split", f"acados N={LONG_N} split", "latency_ms"),
        (f"{LEARNING} rti", "ours rti", "act_ms"),
        (f"{LEARNING} rti-split", "ours rti-split", "latency_ms"),
        ("ours sqp", f"acados N={spec['our_nodes']} SQP", "act_ms"),
        ("ours sqp", f"acados N={LONG_N} SQP", "act_ms"),
        (DEFAULT, f"acados N={spec['our_nodes']} SQP", "act_ms"),
        (DEFAULT, f"acados N={LONG_N} SQP", "act_ms"),
        (DEFAULT, "ours rti", "act_ms"))
        if a in labels and b in labels]
    ratio_rows = []
    for b in blocks:
        ratio_rows.append([b, by[(b, labels[0])]["seed"]] + [
            f"{by[(b, x)][key] / by[(b, y)][key]:.2f}" for x, y, key in pairs])
    ratios = {(x, y): [by[(b, x)][key] / by[(b, y)][key] for b in blocks]
              for x, y, key in pairs}
    m = machine()
    lines = [
        "# acados as a measured peer of the pseudospectral RTI (quadrotor)", "",
        f"acados and `ours rti*` plan with the nominal model; `{LEARNING} rti*` is the learning "
        f"RTI, `make_mpc(env, \"robust\", scheme=...)` pretrained on "
        f"`collect_initial_data(env, {LEARNING_SAMPLES}, seed={BASE_SEED})` (each episode from "
        f"that pretrained learner, learning online within the episode: its step includes the "
        f"learner update, with the split scheme in the preparation), measured in the same run "
        f"and blocks.", "",
        f"Command: `{command}` ({seconds / 60:.1f} min, solver builds included)", "",
        f"Machine: {m['nproc']} CPU(s) visible, {m['cpu']}; {m['os']}; "
        f"OMP_NUM_THREADS={m['OMP_NUM_THREADS']} on both sides. Load average (1, 5, 15 min) "
        f"at the start {loads[0]}, at the end {loads[1]}: the machine is shared, so a few "
        f"steps of every controller are slowed by other work (the p90 column); the "
        f"interleaved blocks expose both sides to it alike and the medians are robust to it.",
        "",
        "Versions: ours " + ", ".join(f"{k} {v}" for k, v in ours_versions.items())
        + "; acados side " + ", ".join(f"{k} {v}" for k, v in worker.versions.items())
        + " (its own virtual environment).", "",
        f"Problem: {spec['system']}, horizon {spec['horizon']} s, control period {spec['dt']} s, "
        f"{spec['our_mesh']} on our side; nominal parameters "
        + ", ".join(f"{k} {v:g}" for k, v in spec["nominal_params"].items())
        + "; plant " + ", ".join(f"{k} {v:g}" for k, v in spec["plant_params"].items()) + ".",
        "",
        f"{len(blocks)} blocks; each block runs every controller for one closed-loop episode of "
        f"up to {max(r['steps'] for r in rows)} steps from `env.reset(seed={BASE_SEED} + block)`"
        f", ours and acados alternately (the order flips every block). Per episode: the median "
        f"per-step wall time over the steps after the first (cold start); below, the median "
        f"of those over the blocks. acados solver builds (code generation and C compile): "
        + ", ".join(f"{k} {v:.1f} s" for k, v in worker.build_seconds.items()) + ".", "",
        "acados settings as its solvers stored them: " + "; ".join(
            f"{label}: " + ", ".join(f"{k} {_setting(v)}" for k, v in opts.items())
            for label, opts in worker.settings.items()) + ".", "",
        "## Per-step wall time and closed-loop outcome", "",
        *_table(["controller", "step median (ms)", "latency median (ms)",
                 "step p90 (ms, median over blocks)", "success", "worst final position error (m)",
                 "closed-loop cost (median)", "fallbacks / non-zero QP status",
                 "acados time_tot median (ms)"], summary_rows),
        "",
        "*step*: the whole per-step call; *latency*: the step less its preparation (split "
        "schemes: measured state in, action out; one-call schemes: the whole step). *success*: "
        "the env's rule (position within 0.05 m on every axis for the last 1 s, no "
        "termination). *fallbacks*: ours, RTI steps replaced by a converged solve; acados, steps "
        "whose QP returned a non-zero status (after the first). *acados time_tot*: the solver's "
        "own timer (the C solve alone, both phases for split); the step less this is acados' "
        "Python interface (setting the state, reading the control).", "",
        "## Ratios ours / acados per block", "",
        *_table(["block", "seed"] + [f"{x} / {y} ({'step' if k == 'act_ms' else 'latency'})"
                                     for x, y, k in pairs], ratio_rows), "",
        "Median (min-max) over blocks: " + "; ".join(
            f"{x} / {y}: {np.median(v):.2f} ({min(v):.2f}-{max(v):.2f})"
            for (x, y), v in ratios.items()) + ".", "",
        DIFFERENCES.format(our_mesh=spec["our_mesh"], our_nodes=spec["our_nodes"],
                           rest=spec["our_nodes"] - 1, long_n=LONG_N, qp_solver=qp_solver),
    ]
    (out / "report.md").write_text("\n".join(lines))


# --------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    """Set up acados (or write the skip report), measure both sides in blocks, write the report."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", default="quadrotor", choices=sorted(ENV_IDS))
    parser.add_argument("--steps", type=int, default=120, help="control periods per episode")
    parser.add_argument("--repeats", type=int, default=10, help="interleaved blocks")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--venv", type=Path, default=DEFAULT_VENV,
                        help="the acados virtual environment (created if missing)")
    parser.add_argument("--no-learning", action="store_true",
                        help="leave out the learning RTI (the robust recipe, pretrained)")
    parser.add_argument("--sqp", action="store_true",
                        help="also the converged SQPs: ours (nominal, and make_mpc(env) "
                             "pretrained) and acados' (SQP, merit backtracking)")
    parser.add_argument("--acados-python", default=None,
                        help=f"a CPython {'.'.join(map(str, PYTHON_VERSION))} for the venv")
    args = parser.parse_args(argv)
    if args.steps < 2 or args.repeats < 1:
        parser.error("--steps must be >= 2 and --repeats >= 1")
    command = "OMP_NUM_THREADS=1 python -m benchmarks.studies.acados_peer " + shlex.join(
        sys.argv[1:] if argv is None else argv)
    started = time.perf_counter()
    load_start = load_average()

    import gymnasium as gym

    import gp_envs  # noqa: F401  (registers the envs)
    from gp_agents import PseudospectralMPC

    env = gym.make(ENV_IDS[args.env])
    schemes = ("rti", "rti-split", "sqp") if args.sqp else ("rti", "rti-split")
    agents = {f"ours {s}": PseudospectralMPC.from_env(env, scheme=s) for s in schemes}
    first = next(iter(agents.values()))
    learned: dict[str, Any] = {}
    if not args.no_learning:  # the learning RTI: the robust recipe, pretrained once
        from gp_agents import collect_initial_data, make_mpc

        data = collect_initial_data(env, LEARNING_SAMPLES, seed=BASE_SEED)
        for s in ("rti", "rti-split"):
            agent = make_mpc(env, "robust", scheme=s).pretrain(data)
            agents[f"{LEARNING} {s}"] = agent
            learned[f"{LEARNING} {s}"] = copy.deepcopy(agent.learner)
        if args.sqp:
            agents[DEFAULT] = make_mpc(env).pretrain(data)
            learned[DEFAULT] = copy.deepcopy(agents[DEFAULT].learner)
    env.reset(seed=BASE_SEED)
    spec = export_ocp(env, first)
    if args.sqp:
        spec["configs"] += sqp_configs(spec["configs"])
    try:
        python = ensure_venv(args.venv, args.acados_python)
        worker = AcadosWorker(python, spec, args.venv.parent / "acados-peer-build")
    except AcadosUnavailableError as err:
        reason = str(err).splitlines()[0] if str(err) else "unknown"
        write_skip(args.out, command, reason)
        print(f"acados peer skipped: {reason}")
        return 0

    acados_runs = [(f"{c['label']}{' split' if split else ''}", c["label"], split)
                   for c in spec["configs"] for split in (False, True)
                   if not (split and c.get("nlp_solver_type") == "SQP")]
    task = env.unwrapped.nominal_model.task
    rows: list[dict[str, Any]] = []
    try:
        for block in range(args.repeats):
            seed = BASE_SEED + block
            measured: dict[str, Episode] = {}

            def ours(seed: int = seed, measured: dict[str, Episode] = measured) -> np.ndarray:
                x0 = None
                for label, agent in agents.items():
                    if label in learned:  # every episode from the same pretrained learner
                        agent.learner = agent._term.learner = copy.deepcopy(learned[label])
                    measured[label], x0 = run_ours(env, agent, seed, args.steps)
                assert x0 is not None
                return x0

            def theirs(x0: np.ndarray, measured: dict[str, Episode] = measured) -> None:
                for label, config, split in acados_runs:
                    measured[label] = worker.episode(config, x0, args.steps, split)

            if block % 2 == 0:
                theirs(ours())
            else:  # the start is the env's seeded reset: known before our run
                env.reset(seed=seed)
                theirs(np.array(env.unwrapped._state, dtype=float))
                ours()
            for label, ep in measured.items():
                rows.append({"block": block, "seed": seed, "controller": label,
                             "act_ms": step_median(ep.act_time),
                             "latency_ms": step_median(ep.latency),
                             "act_p90_ms": float(np.percentile(ep.act_time[1:], 90) * 1e3),
                             "solver_internal_ms": (step_median(ep.internal_time)
                                                    if ep.internal_time is not None
                                                    else float("nan")),
                             **outcome(ep, spec, task)})
            print(f"block {block}: " + ", ".join(
                f"{r['controller']} {r['act_ms']:.3f}/{r['latency_ms']:.3f} ms"
                for r in rows if r["block"] == block), flush=True)
    except AcadosUnavailableError as err:
        worker.close()
        write_skip(args.out, command, str(err).splitlines()[0])
        print(f"acados peer skipped: {err}")
        return 0
    worker.close()
    order = list(agents) + [r[0] for r in acados_runs]
    rows.sort(key=lambda r: (r["block"], order.index(r["controller"])))
    qp_solver = first.config.scheme.qp_solver  # the resolved RTI's
    write_report(args.out, command, spec, worker, rows, our_versions(), qp_solver
                 if isinstance(qp_solver, str) else type(qp_solver).__name__,
                 time.perf_counter() - started, (load_start, load_average()))
    print(f"wrote {args.out / 'report.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
