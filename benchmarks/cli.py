"""Command line of the benchmark suite: ``python -m benchmarks`` or ``gp-bench``.

Examples::

    python -m benchmarks --quick                         # the README's command (minutes)
    python -m benchmarks --preset full --workers 2       # everything (hours on 2 cores)
    python -m benchmarks --controllers nominal-mpc,ssgp-mpc --envs cartpole --seeds 0-4
    python -m benchmarks --preset dubins --scheduler tcp://10.0.0.5:8786   # on a Dask cluster
    python -m benchmarks --list-presets

A run writes ``<out>/runs/<trial>.npz`` (one file per finished trial, written atomically),
``metrics.csv``, ``summary.csv``, PNG figures and ``report.md``. Rerunning the same command
skips finished trials, so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import shlex
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from benchmarks.controllers import CONTROLLERS, ENVS, UnknownNameError, check_name
from benchmarks.presets import PRESETS, Preset, custom_experiment, get_preset
from benchmarks.trial import TrialSpec

RESULTS_DIR = Path(__file__).resolve().parent / "results"
"""Default parent of the results directories (``results/<preset>``)."""


def parse_seeds(text: str) -> list[int]:
    """``"0-4"`` -> [0, 1, 2, 3, 4]; ``"0,3,7"`` -> [0, 3, 7]; ranges and lists combine."""
    seeds: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            if "-" in part[1:]:
                lo, hi = part.split("-", 1) if not part.startswith("-") else (part, part)
                seeds.extend(range(int(lo), int(hi) + 1))
            else:
                seeds.append(int(part))
        except ValueError as err:
            raise argparse.ArgumentTypeError(f"bad seed list {text!r}: use e.g. 0-4 or 0,2,5"
                                             ) from err
    if not seeds or any(s < 0 for s in seeds):
        raise argparse.ArgumentTypeError(f"bad seed list {text!r}: need seeds >= 0")
    return list(dict.fromkeys(seeds))


def _names(text: str | None) -> list[str] | None:
    return None if text is None else [t.strip() for t in text.split(",") if t.strip()]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (also documents the CLI)."""
    p = argparse.ArgumentParser(
        prog="gp-bench", description="Run controllers x envs x scenarios x seeds through "
        "gym.make and agent.act; write trajectories, metrics, plots and a Markdown report.",
        epilog="Presets: " + ", ".join(PRESETS) + ". Controllers: " + ", ".join(CONTROLLERS)
        + ". Envs: " + ", ".join(ENVS) + ".")
    p.add_argument("--preset", help="named preset (default: quick, unless --controllers is "
                   "given); see --list-presets")
    p.add_argument("--quick", dest="preset", action="store_const", const="quick",
                   help="same as --preset quick (a couple of minutes; the README's command)")
    p.add_argument("--full", dest="preset", action="store_const", const="full",
                   help="same as --preset full (every experiment; hours)")
    p.add_argument("--controllers", help="comma-separated controller names: a custom grid, or "
                   "a filter of the preset's episodes")
    p.add_argument("--envs", help="comma-separated env short names (custom grid / filter)")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: each env's "
                   "default scenario for a custom grid)")
    p.add_argument("--seeds", type=parse_seeds, help="seeds, e.g. 0-4 or 0,2,5 (custom grid: "
                   "default 0; with a preset: a filter)")
    p.add_argument("--max-steps", type=int, help="stop every episode after this many steps "
                   "(smoke runs; stored as different trials)")
    p.add_argument("--out", type=Path, help="results directory (default: "
                   "benchmarks/results/<preset or 'custom'>)")
    p.add_argument("--workers", type=int, default=1, help="parallel trial processes (default 1; "
                   "0 runs in this process; with --scheduler local: Dask workers)")
    p.add_argument("--scheduler", help="Dask scheduler address (tcp://host:8786) to submit "
                   "trials to an existing cluster, or 'local' for a LocalCluster")
    p.add_argument("--max-memory-gb", type=float, default=8.0, help="memory limit of each "
                   "local worker process in GiB, 0 for none (default 8): a trial exceeding it is "
                   "recorded as an error instead of exhausting a shared machine")
    p.add_argument("--report-only", action="store_true", help="only rebuild the report from the "
                   "trial files already written")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--list-presets", action="store_true", help="list presets and exit")
    p.add_argument("--list-controllers", action="store_true", help="list controllers, envs and "
                   "scenarios and exit")
    return p


def _filter(preset: Preset, controllers: list[str] | None, envs: list[str] | None,
            scenarios: list[str] | None, seeds: list[int] | None,
            max_steps: int | None) -> Preset:
    def keep(s: TrialSpec) -> bool:
        return ((controllers is None or s.kind != "episode" or s.controller in controllers)
                and (envs is None or s.env in envs)
                and (scenarios is None or s.scenario in scenarios)
                and (seeds is None or s.seed in seeds))

    def change(s: TrialSpec) -> TrialSpec:
        return s if max_steps is None or s.kind not in ("episode", "ssgp-act-scaling") else (
            dataclasses.replace(s, max_steps=max_steps))

    experiments = tuple(dataclasses.replace(e, specs=tuple(change(s) for s in e.specs if keep(s)))
                        for e in preset.experiments)
    return dataclasses.replace(preset, experiments=tuple(e for e in experiments if e.specs))


def resolve(args: argparse.Namespace) -> tuple[Preset, Path]:
    """The preset (possibly custom or filtered) and the output directory of parsed ``args``.

    Raises:
        UnknownNameError: unknown preset, controller, env or scenario names.
    """
    controllers, envs, scenarios = (_names(args.controllers), _names(args.envs),
                                    _names(args.scenarios))
    for c in controllers or ():
        check_name("controller", c, list(CONTROLLERS))
    for e in envs or ():
        check_name("env", e, list(ENVS))
    valid_scenarios = sorted({s for e in ENVS.values() for s in e.scenarios})
    for s in scenarios or ():
        check_name("scenario", s, valid_scenarios)
    if args.max_steps is not None and args.max_steps < 1:
        raise ValueError("--max-steps must be >= 1")
    if args.preset is None and controllers is not None:
        exp = custom_experiment(controllers, envs or list(ENVS), scenarios, args.seeds or [0],
                                args.max_steps)
        preset = Preset("custom", "a custom grid of controllers x envs x scenarios x seeds",
                        (exp,))
    else:
        preset = _filter(get_preset(args.preset or "quick"), controllers, envs, scenarios,
                         args.seeds, args.max_steps)
        if not preset.experiments:
            raise UnknownNameError("the filters leave no trial of preset "
                                   f"{args.preset or 'quick'!r}")
    out = args.out or RESULTS_DIR / preset.name
    return preset, out


def _list_presets() -> str:
    lines = []
    for p in PRESETS.values():
        lines.append(f"{p.name:18s} {p.description} ({len(p.specs)} trials)")
        for e in p.experiments:
            lines.append(f"{'':18s}   - {e.name}: {len(e.specs)} trials; sections "
                         f"{', '.join(e.sections)}")
    return "\n".join(lines)


def _list_controllers() -> str:
    lines = ["controllers:"]
    lines += [f"  {c.name:18s} {c.description}" for c in CONTROLLERS.values()]
    lines.append("envs (scenarios, default first):")
    for name, e in ENVS.items():
        others = [s for s in e.scenarios if s != e.default_scenario]
        lines.append(f"  {name:18s} {e.env_id}: {', '.join([e.default_scenario, *others])}")
    return "\n".join(lines)


def _command(argv: Sequence[str]) -> str:
    prog = "gp-bench" if Path(sys.argv[0]).name == "gp-bench" else "python -m benchmarks"
    return " ".join([prog, shlex.join(list(argv))]).strip()


def _terminate(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 if some trial failed, 2 usage error)."""
    from benchmarks.report import write_report
    from benchmarks.runner import run_trials

    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.list_presets:
        print(_list_presets())
        return 0
    if args.list_controllers:
        print(_list_controllers())
        return 0
    try:
        preset, out = resolve(args)
    except (UnknownNameError, ValueError) as err:
        parser.error(str(err))
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    with contextlib.suppress(ValueError):  # only possible in the main thread
        signal.signal(signal.SIGTERM, _terminate)  # finished trials are kept; see runner
    start = time.perf_counter()
    run_info: dict[str, object] = {"workers": args.workers, "scheduler": args.scheduler}
    status = 0
    if not args.report_only:
        summary = run_trials(preset.specs, out, workers=args.workers, scheduler=args.scheduler,
                             progress=not args.no_progress,
                             max_memory_gb=args.max_memory_gb or None)
        failed = summary.count("error")
        run_info.update(ran=len(summary.ran), skipped=len(summary.skipped))
        if failed:
            print(f"{failed} trial(s) failed; see {out / 'metrics.csv'}", file=sys.stderr)
            status = 1
    run_info["wall_s"] = time.perf_counter() - start
    command = _command(argv)
    last = out / "runs" / "last_run.json"  # the report names the command that ran trials
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
