"""The acados side of :mod:`benchmarks.studies.acados_peer`: the quadrotor OCP in acados.

Run by the *acados* virtual environment's Python (never the project's), this file imports
nothing from the project: everything it knows of the problem comes from the JSON spec that
:func:`benchmarks.studies.acados_peer.export_ocp` writes (dynamics parameters, control period,
horizon, shooting grids, weights, bounds, goal, start). At module level it imports only the
standard library and numpy, so the project's tests can import it to check its numpy dynamics
against the project's physics without acados.

It builds one ``AcadosOcpSolver`` per configuration of the spec (a shooting grid, ``SQP_RTI``
or a converged ``SQP`` with its budget and tolerance, ``PARTIAL_CONDENSING_HPIPM``,
``GAUSS_NEWTON``, ``ERK`` with one RK4 step per shooting interval) and then serves closed-loop
episodes over a line protocol (one JSON object per line):

- on start, after the builds: ``{"ready": true, "versions": ..., "build_seconds": ...}``;
- ``{"cmd": "episode", "config": LABEL, "x0": [...], "steps": T, "split": false}``: one closed
  loop of ``T`` control periods on the plant (the same ODE with the plant's parameters, RK4 with
  the plant's substeps per period, the env's state box terminating it); answers with the
  per-step wall times, statuses, the states and the actions;
- ``{"cmd": "quit"}``.

Protocol lines go to the original standard output; everything else (acados' and the C
compiler's messages) to standard error.

Usage: ``python acados_peer_worker.py SPEC.json BUILD_DIR``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

import numpy as np

YAW_DRAG_KEY = "yaw_drag_ratio"
SETTINGS = ("nlp_solver_type", "qp_solver", "qp_solver_cond_N", "hessian_approx",
            "integrator_type", "sim_method_num_stages", "sim_method_num_steps",
            "nlp_solver_max_iter", "nlp_solver_tol_stat", "globalization")
"""The solver options the worker reports back, as acados stored them."""


def quadrotor_ode(x: Any, u: Any, p: dict[str, float], yaw_drag_ratio: float,
                  sin: Callable[[Any], Any], cos: Callable[[Any], Any],
                  stack: Callable[[list[Any]], Any]) -> Any:
    """The small-attitude quadrotor ``xdot = f(x, u)`` (NED, Euler rates as body rates).

    Written once for numpy and CasADi: ``sin``, ``cos`` and ``stack`` (a list of 12 scalars to a
    vector) come from the library in use.

    Args:
        x: (12,) ``[x, y, z, phi, theta, psi, xdot, ydot, zdot, phidot, thetadot, psidot]``.
        u: (4,) rotor thrusts ``F1..F4`` (N).
        p: ``m, Jx, Jy, Jz, L, g``.
        yaw_drag_ratio: rotor drag torque per unit thrust and arm length.
        sin, cos, stack: the library's functions.
    """
    m, jx, jy, jz, arm, g = (p[k] for k in ("m", "Jx", "Jy", "Jz", "L", "g"))
    phi, theta, psi = x[3], x[4], x[5]
    phid, thetad, psid = x[9], x[10], x[11]
    f1, f2, f3, f4 = u[0], u[1], u[2], u[3]
    thrust = f1 + f2 + f3 + f4
    cphi, sphi, cth, sth = cos(phi), sin(phi), cos(theta), sin(theta)
    cpsi, spsi = cos(psi), sin(psi)
    return stack([
        x[6], x[7], x[8], phid, thetad, psid,
        (cphi * sth * cpsi + sphi * spsi) * thrust / m,
        (cphi * sth * spsi - sphi * cpsi) * thrust / m,
        g - cphi * cth * thrust / m,
        (thetad * psid * (jy - jz) + arm * (f4 - f2)) / jx,
        (phid * psid * (jz - jx) + arm * (f1 - f3)) / jy,
        (phid * thetad * (jx - jy) + yaw_drag_ratio * arm * (f2 + f4 - f1 - f3)) / jz,
    ])


def numpy_ode(x: np.ndarray, u: np.ndarray, p: dict[str, float],
              yaw_drag_ratio: float) -> np.ndarray:
    """:func:`quadrotor_ode` in numpy: (12,) state derivative."""
    return np.asarray(quadrotor_ode(x, u, p, yaw_drag_ratio, np.sin, np.cos,
                                    lambda v: np.array(v, dtype=float)))


def rk4_step(x: np.ndarray, u: np.ndarray, p: dict[str, float], yaw_drag_ratio: float,
             dt: float, substeps: int) -> np.ndarray:
    """State after ``dt`` under zero-order hold on ``u``: ``substeps`` classical RK4 steps."""
    h = dt / substeps
    for _ in range(substeps):
        k1 = numpy_ode(x, u, p, yaw_drag_ratio)
        k2 = numpy_ode(x + h / 2 * k1, u, p, yaw_drag_ratio)
        k3 = numpy_ode(x + h / 2 * k2, u, p, yaw_drag_ratio)
        k4 = numpy_ode(x + h * k3, u, p, yaw_drag_ratio)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def shrunk_box(spec: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The state box shrunk by ``state_margin`` of each half-range (the soft box of the OCP)."""
    lb, ub = np.array(spec["x_lb"], float), np.array(spec["x_ub"], float)
    shrink = spec["state_margin"] * 0.5 * (ub - lb)
    return lb + shrink, ub - shrink


def build_solver(spec: dict[str, Any], config: dict[str, Any], build_dir: str) -> Any:
    """An ``AcadosOcpSolver`` of the spec's OCP on ``config["time_steps"]``.

    Cost (acados scales each stage's least-squares cost and slack penalty by its time step):
    ``sum_i dt_i (e_i' Q e_i + du_i' R du_i) + e_N' Qf e_N`` plus ``dt_i * state_penalty * s^2``
    for a violation ``s`` of the shrunk state box at the inner nodes 1..N-1; controls hard-bounded.
    """
    import casadi as ca
    from acados.acados_template import AcadosModel, AcadosOcp, AcadosOcpSolver

    nx, nu = len(spec["goal"]), len(spec["u_ref"])
    label = config["label"]
    name = "quad_" + "".join(c if c.isalnum() else "_" for c in label)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", nu)
    xdot = ca.SX.sym("xdot", nx)
    model = AcadosModel()
    model.name = name
    model.x, model.u, model.xdot = x, u, xdot
    model.f_expl_expr = quadrotor_ode(x, u, spec["nominal_params"], spec[YAW_DRAG_KEY],
                                      ca.sin, ca.cos, lambda v: ca.vertcat(*v))
    model.f_impl_expr = xdot - model.f_expl_expr

    steps = np.array(config["time_steps"], dtype=float)
    n = len(steps)
    ocp = AcadosOcp()
    ocp.model = model
    ocp.dims.N = n
    ocp.solver_options.tf = float(steps.sum())
    ocp.solver_options.time_steps = steps
    Q, R, Qf = (np.array(spec[k], dtype=float) for k in ("Q", "R", "Qf"))
    goal, u_ref = np.array(spec["goal"], float), np.array(spec["u_ref"], float)
    ocp.cost.cost_type = "LINEAR_LS"
    ocp.cost.cost_type_e = "LINEAR_LS"
    ocp.cost.W = 2.0 * np.block([[Q, np.zeros((nx, nu))], [np.zeros((nu, nx)), R]])
    ocp.cost.W_e = 2.0 * Qf
    ocp.cost.Vx = np.vstack([np.eye(nx), np.zeros((nu, nx))])
    ocp.cost.Vu = np.vstack([np.zeros((nx, nu)), np.eye(nu)])
    ocp.cost.Vx_e = np.eye(nx)
    ocp.cost.yref = np.concatenate([goal, u_ref])
    ocp.cost.yref_e = goal.copy()

    ocp.constraints.x0 = np.array(spec["start"], dtype=float)
    ocp.constraints.idxbu = np.arange(nu)
    ocp.constraints.lbu = np.array(spec["u_lb"], float)
    ocp.constraints.ubu = np.array(spec["u_ub"], float)
    lb, ub = shrunk_box(spec)
    ocp.constraints.idxbx = np.arange(nx)
    ocp.constraints.lbx, ocp.constraints.ubx = lb, ub
    ocp.constraints.idxsbx = np.arange(nx)
    ocp.cost.Zl = ocp.cost.Zu = np.full(nx, 2.0 * spec["state_penalty"])
    ocp.cost.zl = ocp.cost.zu = np.zeros(nx)

    opts = ocp.solver_options
    opts.nlp_solver_type = config.get("nlp_solver_type", "SQP_RTI")
    if opts.nlp_solver_type == "SQP":  # converged: a budget and tolerances, a line search
        opts.nlp_solver_max_iter = int(config["max_iter"])
        for name in ("stat", "eq", "ineq", "comp"):
            setattr(opts, f"nlp_solver_tol_{name}", float(config["tol"]))
        opts.globalization = "MERIT_BACKTRACKING"
    opts.qp_solver = "PARTIAL_CONDENSING_HPIPM"
    opts.hessian_approx = "GAUSS_NEWTON"
    opts.integrator_type = "ERK"
    opts.sim_method_num_stages = 4
    opts.sim_method_num_steps = 1
    opts.print_level = 0
    ocp.code_export_directory = os.path.join(build_dir, f"c_generated_{name}")
    json_file = os.path.join(build_dir, f"{name}.json")
    return AcadosOcpSolver(ocp, json_file=json_file)


def initialize(solver: Any, n: int, x0: np.ndarray, u_ref: np.ndarray) -> None:
    """The cold start's guess: the measured state at every node, the hover thrust as control."""
    for i in range(n + 1):
        solver.set(i, "x", x0)
    for i in range(n):
        solver.set(i, "u", u_ref)


def episode(spec: dict[str, Any], solver: Any, n: int, x0: np.ndarray, steps: int,
            split: bool, converge_iterations: int, converged: bool = False) -> dict[str, Any]:
    """One closed loop of ``steps`` periods from ``x0`` on the plant.

    The first step converges the cold start (``converge_iterations`` RTI iterations at most,
    until the KKT residuals fall below 1e-6): acados' counterpart of the pseudospectral MPC's
    converged first solve. Every later step is one RTI iteration from the previous step's
    iterate (no shift); with a converged ``SQP`` solver (``converged``), every step is one
    ``solve`` to its tolerance within its iteration budget, from the previous iterate.
    ``split``: the feedback phase (``rti_phase`` 2) with the measured state
    is the step's latency, the preparation phase (``rti_phase`` 1) for the next step follows
    once the action is known, as in the project's ``rti-split``.

    Per-step wall time (``act_time``): setting the measured state, the solve(s) and reading
    ``u0`` through the Python interface; ``preparation_time`` is the part after ``u0``.
    """
    plant = spec["plant_params"]
    drag = spec[YAW_DRAG_KEY]
    dt, substeps = spec["dt"], spec["plant_substeps"]
    x_lb, x_ub = np.array(spec["x_lb"], float), np.array(spec["x_ub"], float)
    u_lb, u_ub = np.array(spec["u_lb"], float), np.array(spec["u_ub"], float)
    u_ref = np.array(spec["u_ref"], float)
    solver.reset()
    initialize(solver, n, x0, u_ref)
    x = np.array(x0, dtype=float)
    act, prep, internal, status, iters = [], [], [], [], []
    states, actions = [x.tolist()], []
    terminated = None
    for k in range(steps):
        start = time.perf_counter()
        solver.set(0, "lbx", x)
        solver.set(0, "ubx", x)
        if converged:
            st = solver.solve()
            iters.append(int(np.ravel(solver.get_stats("sqp_iter"))[0]))
        elif k == 0:
            solver.options_set("rti_phase", 0)
            used = 0
            for used in range(1, converge_iterations + 1):  # noqa: B007  (counted after)
                st = solver.solve()
                if float(np.max(solver.get_stats("residuals"))) < 1e-6:
                    break
            iters.append(used)
        elif split:
            solver.options_set("rti_phase", 2)
            st = solver.solve()
            iters.append(1)
        else:
            st = solver.solve()
            iters.append(1)
        u = np.clip(solver.get(0, "u"), u_lb, u_ub)
        feedback_end = time.perf_counter()
        t_int = float(np.ravel(solver.get_stats("time_tot"))[0])
        prepared = 0.0
        if split:
            solver.options_set("rti_phase", 1)
            solver.solve()
            t_int += float(np.ravel(solver.get_stats("time_tot"))[0])
            solver.options_set("rti_phase", 0)
            prepared = time.perf_counter() - feedback_end
        act.append(time.perf_counter() - start)
        prep.append(prepared)
        internal.append(t_int)
        status.append(int(st))
        x = rk4_step(x, u, plant, drag, dt, substeps)
        actions.append(u.tolist())
        states.append(x.tolist())
        if not np.all(np.isfinite(x)):
            terminated = "diverged"
            break
        if np.any((x < x_lb) | (x > x_ub)):
            terminated = "left the state box"
            break
    return {"act_time": act, "preparation_time": prep, "internal_time": internal,
            "status": status, "iterations": iters, "states": states, "actions": actions,
            "terminated": terminated}


def versions() -> dict[str, str]:
    """Python, numpy, casadi and the acados wheel's versions, as installed here."""
    from importlib import metadata

    import casadi as ca

    out = {"python": sys.version.split()[0], "numpy": np.__version__,
           "casadi (vendored)": ca.__version__}
    try:
        out["comma-deps-acados"] = metadata.version("comma-deps-acados")
    except metadata.PackageNotFoundError:
        out["comma-deps-acados"] = "unknown"
    return out


def preload_libraries(lib_dir: str) -> None:
    """Load the wheel's BLASFEO, HPIPM, qpOASES and acados libraries globally.

    The wheel's ``libacados.so`` has no run path to its neighbours; loaded by full path first,
    they satisfy its (and each compiled solver's) dependencies by their sonames, without an
    ``LD_LIBRARY_PATH`` set before this process started.
    """
    import ctypes
    import glob

    for stem in ("libblasfeo", "libhpipm", "libqpOASES_e", "libacados"):
        paths = sorted(glob.glob(os.path.join(lib_dir, stem + ".so*")), key=len, reverse=True)
        if paths:  # the versioned name (the soname) where there is one
            ctypes.CDLL(paths[0], mode=ctypes.RTLD_GLOBAL)


def serve(spec: dict[str, Any], build_dir: str, proto: TextIO) -> None:
    """Build every configuration, say ready, then answer episode commands until quit."""
    import acados

    os.environ.setdefault("ACADOS_SOURCE_DIR", acados.DIR)
    os.environ.setdefault("TERA_PATH", acados.TERA_PATH)
    os.environ.setdefault("ACADOS_PYTHON_INTERFACE_PATH", acados.TEMPLATE_DIR)
    preload_libraries(acados.LIB_DIR)
    solvers, build_seconds, settings = {}, {}, {}
    for config in spec["configs"]:
        start = time.perf_counter()
        solver = build_solver(spec, config, build_dir)
        solvers[config["label"]] = (solver, len(config["time_steps"]),
                                    config.get("nlp_solver_type") == "SQP")
        build_seconds[config["label"]] = time.perf_counter() - start
        settings[config["label"]] = {k: solver.solver_options.get(k) for k in SETTINGS}
    proto.write(json.dumps({"ready": True, "versions": versions(),
                            "build_seconds": build_seconds, "settings": settings}) + "\n")
    proto.flush()
    for line in sys.stdin:
        if not line.strip():
            continue
        cmd = json.loads(line)
        if cmd["cmd"] == "quit":
            break
        solver, n, converged = solvers[cmd["config"]]
        result = episode(spec, solver, n, np.array(cmd["x0"], float), int(cmd["steps"]),
                         bool(cmd.get("split", False)),
                         int(cmd.get("converge_iterations", 50)), converged)
        proto.write(json.dumps(result) + "\n")
        proto.flush()


def main(argv: list[str]) -> int:
    """Entry point: ``SPEC.json BUILD_DIR``; protocol on stdout, all else on stderr."""
    spec_path, build_dir = argv[1], argv[2]
    with open(spec_path) as fh:
        spec = json.load(fh)
    os.makedirs(build_dir, exist_ok=True)
    os.chdir(build_dir)
    proto = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)  # acados' prints and the compiler's output go to stderr
    sys.stdout = sys.stderr
    try:
        serve(spec, build_dir, proto)
    except Exception as err:  # report the failure on the protocol, then fail
        proto.write(json.dumps({"ready": False, "error": f"{type(err).__name__}: {err}"}) + "\n")
        proto.flush()
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
