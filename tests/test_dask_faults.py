"""The Dask engine against real ``dask scheduler`` / ``dask worker`` processes on 127.0.0.1.

A run with no worker says that it waits and gives up after ``worker_timeout`` with a clear
error; a trial whose worker is killed mid-trial is retried and finishes on a worker that joins
later (the scheduler runs with ``allowed-failures=0``, so the retry is the runner's own, not the
scheduler's rescheduling). Every process is started here and killed in a ``finally``; waits poll
with generous deadlines instead of sleeping for fixed times.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from benchmarks.runner import SchedulerError, is_finished, load_record, run_trials, trial_path
from benchmarks.trial import TrialSpec

distributed = pytest.importorskip("distributed")

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
DEADLINE_S = 120.0
"""Generous bound of every wait (a loaded machine is slow; a hang still fails the test)."""


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ, OMP_NUM_THREADS="1", **extra)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _poll(condition: Callable[[], Any], what: str, deadline_s: float = DEADLINE_S) -> Any:
    """Call ``condition`` until it returns something truthy (returned); fail after the
    deadline."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out after {deadline_s:.0f} s waiting for {what}")


def _stop(proc: subprocess.Popen[bytes]) -> None:
    """Kill ``proc`` (started here) and reap it."""
    if proc.poll() is None:
        proc.kill()
    proc.wait(timeout=30)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """Address of a ``dask scheduler`` on a free port of 127.0.0.1 (``allowed-failures=0``)."""
    folder = tmp_path_factory.mktemp("dask")
    info = folder / "scheduler.json"
    log = (folder / "scheduler.log").open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", "0",
         "--no-dashboard", "--scheduler-file", str(info)],
        env=_env(DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="0"), stdout=log,
        stderr=subprocess.STDOUT)
    try:
        def address() -> str | None:
            assert proc.poll() is None, (folder / "scheduler.log").read_text()
            try:
                return json.loads(info.read_text())["address"]
            except (OSError, ValueError, KeyError):
                return None

        yield _poll(address, "the scheduler's address file")
    finally:
        _stop(proc)
        log.close()


@pytest.fixture
def cluster(scheduler: str, tmp_path: Path) -> Iterator[tuple[Any, Callable[[str], Any]]]:
    """A monitoring client of ``scheduler`` and a function that starts a named worker (killed
    at the end of the test)."""
    monitor = distributed.Client(scheduler, set_as_default=False, timeout=DEADLINE_S)
    procs: list[subprocess.Popen[bytes]] = []

    def start_worker(name: str) -> subprocess.Popen[bytes]:
        log = (tmp_path / f"{name}.log").open("wb")
        proc = subprocess.Popen(
            [sys.executable, "-m", "dask", "worker", scheduler, "--name", name, "--nthreads",
             "1", "--no-nanny", "--no-dashboard", "--death-timeout", "60"],
            env=_env(), stdout=log, stderr=subprocess.STDOUT)
        log.close()
        procs.append(proc)
        _poll(lambda: any(w["name"] == name for w in
                          monitor.scheduler_info()["workers"].values()),
              f"worker {name} to connect")
        return proc

    try:
        _poll(lambda: not monitor.nthreads(), "no worker left from an earlier test")
        yield monitor, start_worker
    finally:
        for proc in procs:
            _stop(proc)
        monitor.close()


def test_no_worker_waits_visibly_then_fails_clearly(
        cluster: tuple[Any, Callable[[str], Any]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    monitor, _ = cluster
    spec = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 0, max_steps=2)
    with pytest.raises(SchedulerError, match="no Dask worker connected to tcp://127.0.0.1:.* "
                                             r"for 2 s \(1 trial\(s\) not run"):
        run_trials([spec], tmp_path, scheduler=monitor.scheduler.address, progress=False,
                   worker_timeout=2.0)
    err = capsys.readouterr().err
    assert "waiting for Dask workers: none connected to tcp://127.0.0.1:" in err
    assert not is_finished(tmp_path, spec)


def test_killed_worker_trial_is_retried_on_a_worker_that_joins_later(
        cluster: tuple[Any, Callable[[str], Any]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    monitor, start_worker = cluster
    address = monitor.scheduler.address
    first = start_worker("first")
    spec = TrialSpec("episode", "cartpole", "online", "nominal-mpc", 1, max_steps=12)
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["summary"] = run_trials([spec], tmp_path, scheduler=address, progress=False,
                                            worker_timeout=DEADLINE_S)
        except BaseException as err:  # reported by the assertions below
            outcome["error"] = err

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    # kill the worker as soon as the scheduler has handed it the trial (a trial takes seconds)
    _poll(lambda: any(monitor.processing().values()), "the trial to start on the first worker")
    first.send_signal(signal.SIGKILL)
    first.wait(timeout=30)
    seen: list[str] = []

    def said(text: str) -> bool:
        seen.append(capsys.readouterr().err)
        return text in "".join(seen)

    _poll(lambda: said("waiting for Dask workers: none connected"), "the waiting line")
    _poll(lambda: said(f"trial {spec.key}: lost with its Dask worker (KilledWorker); retrying"),
          "the retry line")
    assert "error" not in outcome and "summary" not in outcome  # still waiting, not failed
    start_worker("second")
    thread.join(timeout=DEADLINE_S)
    assert not thread.is_alive(), "the run did not finish after a worker joined"
    assert "error" not in outcome, outcome.get("error")
    assert outcome["summary"].ran == {spec.key: "ok"}
    seen.append(capsys.readouterr().err)
    assert "Dask workers connected: running" in "".join(seen)
    record = load_record(trial_path(tmp_path, spec))
    assert record["status"] == "ok" and record["metrics"]["steps"] == 12
