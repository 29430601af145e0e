"""Command line of the benchmark suite: ``python -m benchmarks`` or ``gp-bench``.

Examples::

    python -m benchmarks --quick                         # the README's command (minutes)
    python -m benchmarks --preset full --workers 2       # everything (hours on 2 cores)
    python -m benchmarks --controllers robust-mpc,oracle-mpc --envs cartpole --seeds 0-4
    python -m benchmarks --controllers robust-mpc@rti-split --envs cartpole --randomize 0.1 \
        --data own --seeds 100-119                       # any cell, any seeds
    python -m benchmarks --preset dubins --scheduler tcp://10.0.0.5:8786   # on a Dask cluster
    python -m benchmarks --list-presets
    python -m benchmarks --envs mysystem --controllers nominal-mpc,sac   # your own system

Your own system (a package declaring it under ``[project.entry-points."gp_envs.systems"]``,
see ``docs/guide/own-system.md``) is an env like the built-in ones; the RL controllers load
your models from ``--models DIR`` or ``./benchmarks/models`` (where ``python -m
benchmarks.rl.train`` saves) before the shipped ones.

A run writes ``<out>/runs/<trial>.npz`` (one file per finished trial, written atomically),
``metrics.csv``, ``summary.csv``, PNG figures and ``report.md``; ``<out>`` defaults to
``./benchmark-results/<preset or 'custom'>`` under the current directory. Rerunning the same
command skips finished trials, so an interrupted run resumes where it stopped.

A custom grid whose controller cannot run on a requested env (no RL model for it, say) is
recorded and exits with status 3, each reason on stderr.

Misuse (unknown names, empty name lists, bad seeds or numbers, an unwritable ``--out``,
``--report-only`` without results, an unreachable Dask scheduler, no Dask worker within
``--worker-timeout``) prints one line ``gp-bench: error: ...`` on stderr and exits with status 2.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import re
import shlex
import signal
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from benchmarks import USER_MODELS_DIR
from benchmarks.controllers import (
    CONTROLLERS,
    ENVS,
    N_INITIAL_POINTS,
    UnknownNameError,
    check_name,
    rl_models,
    user_models_dir,
)
from benchmarks.presets import PRESETS, Preset, custom_experiment, get_preset
from benchmarks.runner import (
    DEFAULT_CONNECT_TIMEOUT_S,
    DEFAULT_WORKER_TIMEOUT_S,
    RUNS_DIR,
    SchedulerError,
    check_scheduler_address,
    run_trials,
    trial_path,
)
from benchmarks.trial import DATA_SOURCES, EPISODE_KINDS, STARTS, Cell, TrialSpec

RESULTS_DIR = Path("benchmark-results")
"""Default parent of the results directories, relative to the current directory
(``benchmark-results/<preset>``): never inside the installed package. The repository's own
committed reports live in ``benchmarks/results/<preset>``; the Makefile passes ``--out``."""


_SEED_PART = re.compile(r"(\d+)(?:-(\d+))?")


def parse_seeds(text: str) -> list[int]:
    """``"0-4"`` -> [0, 1, 2, 3, 4]; ``"0,3,7"`` -> [0, 3, 7]; ranges and lists combine.

    Raises:
        argparse.ArgumentTypeError: not a list of seeds >= 0 and ranges ``LO-HI``, ``LO <= HI``.
    """
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        match = _SEED_PART.fullmatch(part)
        if match is None:
            raise argparse.ArgumentTypeError(
                f"bad seed {part!r} in {text!r}: use seeds >= 0 and ranges, e.g. 0-4 or 0,2,5")
        lo = int(match[1])
        hi = lo if match[2] is None else int(match[2])
        if hi < lo:
            raise argparse.ArgumentTypeError(f"empty seed range {part!r}: use LO-HI with LO <= HI")
        seeds.extend(range(lo, hi + 1))
    return list(dict.fromkeys(seeds))


def print_report(text: str, out: Path | None = None) -> None:
    """Print a tool's Markdown ``text`` and, with ``out``, also write it there (parents made)."""
    print(text)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)


def _number(kind: type[int] | type[float], minimum: float, what: str
            ) -> Callable[[str], int | float]:
    """An argparse ``type``: ``kind(text)``, at least ``minimum`` (``what`` describes it)."""
    def parse(text: str) -> int | float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not value >= minimum:  # also rejects nan
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}")
        return value

    parse.__name__ = what  # argparse names the type in some messages
    return parse


def _names(text: str | None, option: str) -> list[str] | None:
    """The comma-separated names of ``option`` (None when not given).

    Raises:
        ValueError: the option is given but names nothing (e.g. ``--controllers ""``).
    """
    if text is None:
        return None
    names = [t.strip() for t in text.split(",") if t.strip()]
    if not names:
        raise ValueError(f"{option} {text!r} names nothing: give comma-separated names "
                         "(see --list-controllers)")
    return names


class _Parser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` whose errors are one line on stderr (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        """A usage error: print ``prog: error: message (see prog --help)``, exit status 2."""
        self.fail(f"{message} (see {self.prog} --help)")

    def fail(self, message: str) -> NoReturn:
        """Print ``prog: error: message`` on stderr and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> _Parser:
    """The argument parser (also documents the CLI)."""
    p = _Parser(
        prog="gp-bench", description="Run controllers x envs x scenarios x seeds through "
        "gym.make and agent.act; write trajectories, metrics, plots and a Markdown report.",
        epilog="Presets: " + ", ".join(PRESETS) + ". Controllers: "
        + ", ".join(c.name for c in CONTROLLERS.values() if c.main) + " (all: --list-controllers)"
        + ". Envs: " + ", ".join(ENVS) + ". Exit status: 0 done, 1 some trial failed (see "
        "metrics.csv), 2 usage error or no Dask scheduler/worker (one line on stderr), 130 "
        "interrupted; finished trials are always kept.")
    p.add_argument("--preset", help="named preset (default: quick, unless --controllers is "
                   "given); see --list-presets")
    p.add_argument("--quick", dest="preset", action="store_const", const="quick",
                   help="same as --preset quick (a couple of minutes; the README's command)")
    p.add_argument("--full", dest="preset", action="store_const", const="full",
                   help="same as --preset full (every experiment; hours)")
    p.add_argument("--controllers", help="comma-separated controller names: a custom grid, or "
                   "a filter of the preset's episodes")
    p.add_argument("--envs", help="comma-separated env short names (custom grid / filter); "
                   "your own system is one once its package declares the module that calls "
                   "gp_envs.register_system under [project.entry-points.\"gp_envs.systems\"] "
                   "in its pyproject.toml and is installed (docs/guide/own-system.md)")
    p.add_argument("--models", type=Path, metavar="DIR", help="directory of your RL models, "
                   "<env>/<algo>/ folders as python -m benchmarks.rl.train writes them (default: "
                   f"./{USER_MODELS_DIR} if it exists); the RL controllers look there before "
                   "the shipped models, and each trial's record names the model it ran")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: each env's "
                   "default scenario for a custom grid)")
    p.add_argument("--cells", help="comma-separated trial cells of a preset to keep, by "
                   "their names in trial keys (e.g. r0.1,r0.1_ddiff,noise0.005; 'default' "
                   "for the default cell): a filter")
    p.add_argument("--seeds", type=parse_seeds, help="seeds, e.g. 0-4 or 0,2,5 (custom grid: "
                   "default 0; with a preset: a filter)")
    grid = p.add_argument_group(
        "the custom grid's cell (with --controllers and no --preset: any cell on any seeds)")
    grid.add_argument("--randomize", type=_number(float, 0, "a number in [0, 1)"),
                      help="relative spread of the true parameters per reset (env option "
                      "randomize; default 0: the scenario's truth)")
    grid.add_argument("--data", choices=DATA_SOURCES, help="where the learning recipes' "
                      "initial data come from: same (default; the episode's truth draw), diff "
                      "(another draw of the same spread), own (collect_initial_data(env, n, "
                      "seed) on the trial's env, as a user does)")
    grid.add_argument("--noise", type=_number(float, 0, "a number >= 0"), help="observation "
                      "noise standard deviation, in each state's unit (default 0)")
    grid.add_argument("--start", choices=STARTS, help="default (the env's reset) or perturbed "
                      "(a seeded offset within the system's perturbation widths)")
    grid.add_argument("--n-init", type=_number(int, 0, "an integer >= 0"),
                      help=f"initial samples of the learning recipes (default "
                      f"{N_INITIAL_POINTS}; 0: none, learned from the episode's first step)")
    p.add_argument("--max-steps", type=_number(int, 1, "an integer >= 1"),
                   help="stop every episode after this many steps (smoke runs; stored as "
                   "different trials)")
    p.add_argument("--out", type=Path, help=f"results directory (default: ./{RESULTS_DIR}/<preset "
                   "or 'custom'>, under the current directory)")
    p.add_argument("--workers", type=_number(int, 0, "an integer >= 0"), default=1,
                   help="parallel trial processes (default 1; 0 runs in this process; with "
                   "--scheduler local: Dask workers)")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786) to submit "
                   "trials to an existing cluster, or 'local' for a LocalCluster")
    p.add_argument("--connect-timeout", type=_number(float, 0.1, "a number of seconds >= 0.1"),
                   default=DEFAULT_CONNECT_TIMEOUT_S, help="seconds to reach the --scheduler "
                   f"before failing (default {DEFAULT_CONNECT_TIMEOUT_S:g})")
    p.add_argument("--worker-timeout", type=_number(float, 0, "a number of seconds >= 0"),
                   default=DEFAULT_WORKER_TIMEOUT_S, help="seconds a --scheduler run waits "
                   "while no Dask worker is connected (it says so) before failing; 0 waits "
                   f"forever (default {DEFAULT_WORKER_TIMEOUT_S:g}); finished trials are kept")
    p.add_argument("--max-memory-gb", type=_number(float, 0, "a number of GiB >= 0"),
                   default=8.0, help="memory limit of each local worker process in GiB, 0 for "
                   "none (default 8): a trial exceeding it is recorded as an error instead of "
                   "exhausting a shared machine")
    p.add_argument("--report-only", action="store_true", help="only rebuild the report from the "
                   "trial files already written (give the run's --preset/--controllers/... and "
                   "--out)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--list-presets", action="store_true", help="list presets and exit")
    p.add_argument("--list-controllers", action="store_true", help="list the controllers (main "
                   "names first), envs and scenarios and exit; with --all also the older "
                   "names' aliases")
    p.add_argument("--all", action="store_true", help="with --list-controllers: aliases too")
    return p


DEFAULT_CELL = "default"
"""The ``--cells`` name of the default cell (whose trial keys carry no cell part)."""


def _filter(preset: Preset, controllers: list[str] | None, envs: list[str] | None,
            scenarios: list[str] | None, seeds: list[int] | None,
            max_steps: int | None, cells: list[str] | None = None) -> Preset:
    if cells is not None:
        known = sorted({s.cell.key or DEFAULT_CELL for s in preset.specs})
        for c in cells:
            check_name("cell", c, known)

    def keep(s: TrialSpec) -> bool:
        return ((controllers is None or s.kind not in EPISODE_KINDS or s.controller in controllers)
                and (envs is None or s.env in envs)
                and (scenarios is None or s.scenario in scenarios)
                and (seeds is None or s.seed in seeds)
                and (cells is None or (s.cell.key or DEFAULT_CELL) in cells))

    def change(s: TrialSpec) -> TrialSpec:
        return s if max_steps is None or s.kind not in (*EPISODE_KINDS, "ssgp-act-scaling") else (
            dataclasses.replace(s, max_steps=max_steps))

    experiments = tuple(dataclasses.replace(e, specs=tuple(change(s) for s in e.specs if keep(s)))
                        for e in preset.experiments)
    return dataclasses.replace(preset, experiments=tuple(e for e in experiments if e.specs))


def resolve(args: argparse.Namespace) -> tuple[Preset, Path]:
    """The preset (possibly custom or filtered) and the output directory of parsed ``args``.

    Raises:
        UnknownNameError: unknown preset, controller, env or scenario names, or filters that
            leave no trial.
        ValueError: an option that names nothing (``--controllers ""``), or a malformed
            ``--scheduler`` address.
    """
    controllers, envs, scenarios = (_names(args.controllers, "--controllers"),
                                    _names(args.envs, "--envs"),
                                    _names(args.scenarios, "--scenarios"))
    cells = _names(getattr(args, "cells", None), "--cells")
    for c in controllers or ():
        check_name("controller", c, list(CONTROLLERS))
    for e in envs or ():
        check_name("env", e, list(ENVS))
    valid_scenarios = sorted({s for e in ENVS.values() for s in e.scenarios})
    for s in scenarios or ():
        check_name("scenario", s, valid_scenarios)
    cell_options = {k: getattr(args, k, None) for k in ("randomize", "data", "noise", "start")}
    given = {k: v for k, v in cell_options.items() if v is not None}
    n_init = getattr(args, "n_init", None)
    if args.preset is None and controllers is not None:
        if given.get("randomize", 0) >= 1:
            raise ValueError(f"--randomize must be in [0, 1), got {given['randomize']}")
        exp = custom_experiment(controllers, envs or list(ENVS), scenarios, args.seeds or [0],
                                args.max_steps, Cell(**given),
                                N_INITIAL_POINTS if n_init is None else n_init)
        preset = Preset("custom", "a custom grid of controllers x envs x scenarios x seeds",
                        (exp,))
    else:
        if given or n_init is not None:
            flags = [f"--{k.replace('_', '-')}" for k in (*given, *(["n_init"] if n_init
                                                                   is not None else []))]
            raise ValueError(f"{', '.join(flags)} set the cell of a custom grid (--controllers "
                             f"without --preset); a preset's cells are chosen with --cells")
        preset = _filter(get_preset(args.preset or "quick"), controllers, envs, scenarios,
                         args.seeds, args.max_steps, cells)
        if not preset.experiments:
            raise UnknownNameError(
                f"the filters leave no trial of preset {args.preset or 'quick'!r}; to run any "
                f"cell on any seeds, use a custom grid: --controllers ... --envs ... --seeds "
                f"... with --randomize/--data/--noise/--start/--n-init")
    if args.scheduler is not None:
        try:
            check_scheduler_address(args.scheduler)
        except SchedulerError as err:
            raise ValueError(str(err)) from None
    try:
        models = user_models_dir(getattr(args, "models", None))
    except FileNotFoundError as err:
        raise ValueError(str(err)) from None
    if models is not None:
        preset = _with_models(preset, models)
    out = args.out or RESULTS_DIR / preset.name
    return preset, out


def _with_models(preset: Preset, models: Path) -> Preset:
    """``preset`` whose RL episodes look for their models in ``models`` first (the spec carries
    the directory to the worker processes; the trial keys stay)."""
    def change(s: TrialSpec) -> TrialSpec:
        rl = s.kind in EPISODE_KINDS and CONTROLLERS[s.controller].family == "rl"
        return dataclasses.replace(s, models=str(models)) if rl else s

    return dataclasses.replace(preset, experiments=tuple(
        dataclasses.replace(e, specs=tuple(change(s) for s in e.specs))
        for e in preset.experiments))


def _writable(out: Path) -> str | None:
    """Why results cannot be written to ``out`` (created if missing), or None if they can."""
    try:
        (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out / RUNS_DIR):
            pass
    except OSError as err:
        return f"--out {out}: cannot write results there ({err.strerror or err})"
    return None


def _report_only_problem(out: Path, preset: Preset) -> str | None:
    """Why ``--report-only`` has nothing to report in ``out``, or None."""
    if not out.is_dir():
        return (f"--report-only: results directory {out} does not exist; run without "
                "--report-only first (or pass --out)")
    if not any(trial_path(out, spec).is_file() for spec in preset.specs):
        return (f"--report-only: no trial of {preset.name!r} in {out / RUNS_DIR}; run without "
                "--report-only first, or pass the --preset/--controllers/... of the run that "
                "wrote it")
    return None


def _list_presets() -> str:
    lines = []
    for p in PRESETS.values():
        lines.append(f"{p.name:18s} {p.description} ({len(p.specs)} trials)")
        for e in p.experiments:
            lines.append(f"{'':18s}   - {e.name}: {len(e.specs)} trials; sections "
                         f"{', '.join(e.sections)}")
    return "\n".join(lines)


def _list_controllers(aliases: bool = False, models: Path | None = None) -> str:
    """The ``--list-controllers`` text; each RL controller with the envs it has a model for
    (the shipped ones, and the user's: ``models`` or ``./benchmarks/models``).

    Raises:
        FileNotFoundError: ``models`` is given but is not a directory.
    """
    main = [c for c in CONTROLLERS.values() if c.main]
    found = rl_models(models)
    user = user_models_dir(models)

    def envs(algo: str) -> str:
        names = [env + ("" if user is None or not path.is_relative_to(user) else " (yours)")
                 for env, path in found[algo].items()]
        return "; models for " + (", ".join(names) if names else "no env")

    lines = ["controllers (MPC recipes: <recipe>-mpc, with @rti or @rti-split for the "
             "real-time iteration; make_mpc(env, recipe) in Python):"]
    lines += [f"  {c.name:20s} {c.description}" + (envs(c.name) if c.family == "rl" else "")
              for c in main]
    schemes = [c.name for c in CONTROLLERS.values() if c.recipe and not c.main
               and c.alias_of is None]
    lines.append("  schemes: " + ", ".join(schemes))
    lines.append("study variants:")
    lines += [f"  {c.name:34s} {c.description}" for c in CONTROLLERS.values()
              if not c.main and c.recipe is None and c.alias_of is None]
    if aliases:
        lines.append("aliases (older names, kept so that committed results load):")
        lines += [f"  {c.name:34s} = {c.alias_of}" for c in CONTROLLERS.values() if c.alias_of]
    else:
        lines.append(f"({sum(1 for c in CONTROLLERS.values() if c.alias_of)} older names are "
                     f"aliases: --list-controllers --all)")
    lines.append("envs (scenarios, default first):")
    for name, e in ENVS.items():
        others = [s for s in e.scenarios if s != e.default_scenario]
        where = e.env_id or f"outside: {e.outside.description}"
        lines.append(f"  {name:18s} {where}: {', '.join([e.default_scenario, *others])}")
    return "\n".join(lines)


def _command(argv: Sequence[str]) -> str:
    prog = "gp-bench" if Path(sys.argv[0]).name == "gp-bench" else "python -m benchmarks"
    return " ".join([prog, shlex.join(list(argv))]).strip()


def _terminate(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)


def _unavailable(out: Path, specs: Sequence[Any]) -> list[str]:
    """One line per (controller, env, scenario) of ``specs`` whose trials were recorded as not
    available (e.g. no RL model ships for that env), with the recorded reason."""
    from benchmarks.runner import load_record, trial_path

    reasons: dict[tuple[str, str, str], str] = {}
    for spec in specs:
        record = load_record(trial_path(out, spec))
        key = (spec.controller, spec.env, spec.scenario)
        if record is not None and record.get("status") == "unavailable" and key not in reasons:
            reasons[key] = (f"{spec.controller} on {spec.env} ({spec.scenario}): "
                            f"{record.get('message', '')}")
    return list(reasons.values())


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 if some trial failed, 3 if a controller
    of a custom grid (``--controllers``) cannot run on a requested env: the reasons on
    stderr).

    Usage errors, and errors that stop a run before it could do its work (an unwritable
    ``--out``, an unreachable Dask scheduler, no Dask worker within ``--worker-timeout``), print
    one line ``gp-bench: error: ...`` on stderr and exit with status 2 (``SystemExit``); an
    interrupt exits with status 130. Finished trials are kept in every case.
    """
    from benchmarks.report import write_report

    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.list_presets:
        print(_list_presets())
        return 0
    if args.list_controllers:
        try:
            print(_list_controllers(args.all, args.models))
        except FileNotFoundError as err:
            parser.fail(str(err))
        return 0
    try:
        preset, out = resolve(args)
    except (UnknownNameError, ValueError) as err:
        parser.fail(str(err))
    problem = _report_only_problem(out, preset) if args.report_only else None
    if problem := problem or _writable(out):
        parser.fail(problem)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    with contextlib.suppress(ValueError):  # only possible in the main thread
        signal.signal(signal.SIGTERM, _terminate)  # finished trials are kept; see runner
    start = time.perf_counter()
    run_info: dict[str, object] = {"workers": args.workers, "scheduler": args.scheduler}
    status = 0
    if not args.report_only:
        try:
            summary = run_trials(preset.specs, out, workers=args.workers,
                                 scheduler=args.scheduler, progress=not args.no_progress,
                                 max_memory_gb=args.max_memory_gb or None,
                                 connect_timeout=args.connect_timeout,
                                 worker_timeout=args.worker_timeout or None)
        except SchedulerError as err:
            parser.fail(str(err))
        except KeyboardInterrupt:
            print(f"\ninterrupted: finished trials are kept in {out / RUNS_DIR}; rerun the same "
                  "command to resume", file=sys.stderr)
            return 130
        failed = summary.count("error")
        run_info.update(ran=len(summary.ran), skipped=len(summary.skipped))
        if failed:
            print(f"{failed} trial(s) failed; see {out / 'metrics.csv'}", file=sys.stderr)
            status = 1
        if preset.name == "custom":  # a requested controller that cannot run is an error
            reasons = _unavailable(out, preset.specs)
            for reason in reasons:
                print(f"gp-bench: not available: {reason}", file=sys.stderr)
            if reasons and not status:
                status = 3
    run_info["wall_s"] = time.perf_counter() - start
    command = _command(argv)
    last = out / RUNS_DIR / "last_run.json"  # the report names the command that ran trials
    if args.report_only:
        previous = json.loads(last.read_text()) if last.is_file() else {}
        command, run_info = previous.get("command", command), previous.get("run_info", {})
    else:
        last.write_text(json.dumps({"command": command, "run_info": run_info}) + "\n")
    report = write_report(out, preset, command, run_info)
    print(f"report: {report} ({time.perf_counter() - start:.0f} s)")
    return status


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
