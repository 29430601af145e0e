"""Scheduling and storage of trials: serial, a local process pool, or a Dask cluster; resume.

Every finished trial is one file, ``<out>/runs/<trial key>.npz`` (``np.savez_compressed``):
its arrays (trajectory, per-step diagnostics) plus ``__record__``, a JSON string with the spec,
status, message and metrics. The file is written to a temporary name in the same directory and
moved into place with :func:`os.replace`, so a killed run leaves either the complete file or
none; a truncated or unreadable file counts as not finished and is run again. On a rerun,
trials whose file holds ``status == "ok"`` are skipped; errors and unavailable controllers are
tried again (a model may have been added since).

Executors (:func:`run_trials`):

- ``workers=0``: in this process, one after the other (debugging, tests);
- ``workers=N >= 1``: a ``concurrent.futures.ProcessPoolExecutor`` of ``N`` spawned processes;
- ``scheduler=ADDRESS``: submit to an existing Dask distributed cluster (``"tcp://host:8786"``),
  or ``"local"`` for a throw-away ``LocalCluster`` of ``max(workers, 1)`` single-threaded
  processes. Workers return results to this process, which writes the files: the cluster needs
  the package installed but no shared file system. An unreachable scheduler fails after
  ``connect_timeout`` seconds; while no worker is connected the run waits (and says so) for up
  to ``worker_timeout`` seconds, and a worker that joins picks the trials up; a trial lost with
  its workers is retried (:data:`DASK_RETRIES`). Either failure raises :class:`SchedulerError`.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import multiprocessing
import os
import sys
import tempfile
import threading
import time
import uuid
from collections.abc import Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from benchmarks.trial import STATUS_ERROR, STATUS_OK, TrialSpec, execute

RECORD_KEY = "__record__"
RUNS_DIR = "runs"


# ----------------------------------------------------------------------------- storage
def trial_path(out_dir: Path, spec: TrialSpec) -> Path:
    """Where the file of ``spec`` lives in the results directory ``out_dir``."""
    return Path(out_dir) / RUNS_DIR / f"{spec.key}.npz"


def save_trial(path: Path, result: dict[str, Any]) -> None:
    """Write a trial result atomically (temporary file in the same directory, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {k: v for k, v in result.items() if k != "arrays"}
    arrays = {k: np.asarray(v) for k, v in result.get("arrays", {}).items()}
    arrays[RECORD_KEY] = np.array(json.dumps(record, default=_json_default))
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(buffer.getvalue())
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serializable: {type(value).__name__}")


def load_record(path: Path) -> dict[str, Any] | None:
    """The record (spec, status, metrics, ...) of a trial file, or None if missing/unreadable."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return json.loads(str(data[RECORD_KEY][()]))
    except (OSError, ValueError, KeyError, EOFError, json.JSONDecodeError):
        return None
    except Exception:  # a truncated zip raises zipfile.BadZipFile and friends
        return None


def load_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of a trial file (without the record)."""
    with np.load(path, allow_pickle=False) as data:
        return {k: data[k] for k in data.files if k != RECORD_KEY}


def is_finished(out_dir: Path, spec: TrialSpec) -> bool:
    """True when the trial's file exists, is readable and holds a successful result."""
    record = load_record(trial_path(out_dir, spec))
    return record is not None and record.get("status") == STATUS_OK


# ----------------------------------------------------------------------------- scheduling
@dataclass
class RunSummary:
    """What a call of :func:`run_trials` did.

    Attributes:
        skipped: trials already finished before the call (kept as they were).
        ran: trials run in this call, by key, with their status.
    """

    skipped: list[str] = field(default_factory=list)
    ran: dict[str, str] = field(default_factory=dict)

    def count(self, status: str) -> int:
        """Number of trials run in this call with ``status``."""
        return sum(1 for s in self.ran.values() if s == status)


def _exit_with_parent(parent: int) -> None:
    while True:
        time.sleep(1.0)
        if os.getppid() != parent:  # the run was killed: do not finish its queue
            os._exit(1)


DEFAULT_MAX_MEMORY_GB = 8.0
"""Default address-space limit of one local worker process (protects a shared machine)."""


def _init_worker(max_memory_bytes: int | None = None) -> None:
    os.environ["OMP_NUM_THREADS"] = "1"
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()
    if max_memory_bytes:  # a runaway trial fails (recorded) instead of invoking the OOM killer
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (max_memory_bytes, max_memory_bytes))
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:
        pass


def _serial(specs: Sequence[TrialSpec]) -> Iterator[dict[str, Any]]:
    for spec in specs:
        yield execute(spec)


def _died(spec: TrialSpec, err: BaseException) -> dict[str, Any]:
    return {"spec": spec.to_dict(), "status": STATUS_ERROR, "metrics": {}, "arrays": {},
            "message": f"the worker process running this trial died ({type(err).__name__}: "
                       f"{err}); e.g. killed by the OS for lack of memory"}


def _local_pool(specs: Sequence[TrialSpec], workers: int,
                max_memory_gb: float | None = DEFAULT_MAX_MEMORY_GB) -> Iterator[dict[str, Any]]:
    """Run ``specs`` in ``workers`` spawned processes, at most ``workers`` trials in flight.

    A worker that dies (segfault, OOM kill) breaks the pool: the trial it ran is recorded as an
    error when it was the only one in flight (or when it breaks the pool a second time), the
    other in-flight trials are retried once, and a fresh pool runs the rest.
    """
    ctx = multiprocessing.get_context("spawn")
    limit = int(max_memory_gb * 2**30) if max_memory_gb else None
    queue = list(specs)
    attempts: dict[TrialSpec, int] = {}
    while queue:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                   initializer=_init_worker, initargs=(limit,))
        in_flight: dict[Any, TrialSpec] = {}
        broken: list[TrialSpec] = []
        try:
            while queue or in_flight:
                while queue and len(in_flight) < workers:
                    spec = queue.pop(0)
                    in_flight[pool.submit(execute, spec)] = spec
                done, _ = wait(in_flight, return_when=FIRST_COMPLETED)
                for fut in done:
                    spec = in_flight.pop(fut)
                    try:
                        result = fut.result()
                    except BrokenProcessPool:
                        broken.append(spec)
                        continue
                    yield result
                if broken:
                    broken += list(in_flight.values())
                    in_flight.clear()
                    break
        except BaseException:  # interrupted: drop the queue and stop the running trials now
            processes = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in processes:  # (Python >= 3.14 has pool.terminate_workers())
                proc.terminate()
            raise
        pool.shutdown(wait=True)
        retry = []
        for spec in broken:
            attempts[spec] = attempts.get(spec, 0) + 1
            if len(broken) == 1 or attempts[spec] >= 2:
                yield _died(spec, BrokenProcessPool("worker terminated abruptly"))
            else:
                retry.append(spec)
        queue = retry + queue


class SchedulerError(RuntimeError):
    """The Dask engine cannot go on: the scheduler is unreachable or lost, or no worker has been
    connected for longer than the timeout. Finished trials are kept; rerun to resume."""


DEFAULT_CONNECT_TIMEOUT_S = 10.0
"""Default time to reach a Dask scheduler before :class:`SchedulerError`."""

DEFAULT_WORKER_TIMEOUT_S = 600.0
"""Default time a Dask run waits while no worker is connected before :class:`SchedulerError`."""

DASK_RETRIES = 1
"""Resubmissions of a trial whose Dask future failed for infrastructure reasons (its worker
was lost more often than the scheduler's ``allowed-failures``, or it was cancelled) before it
is recorded as an error. The scheduler itself already reruns a task lost with its worker."""

_POLL_S = 0.2
_WORKER_CHECK_S = 1.0
_WAITING_REPORT_S = 30.0


class _Status:
    """Progress bar plus status lines (waiting for workers, retries) of a run.

    With the bar enabled, the waiting state is the bar's description and notes are written above
    it; without it, both are plain lines on stderr (the waiting line at most every
    ``_WAITING_REPORT_S`` seconds).
    """

    def __init__(self, total: int, initial: int, enabled: bool) -> None:
        self.enabled = enabled
        self.bar = tqdm(total=total, initial=initial, desc="trials", unit="trial",
                        disable=not enabled, dynamic_ncols=True)
        self._waiting_since: float | None = None
        self._last_line = -math.inf

    def finished(self, key: str, status: str) -> None:
        """One more trial finished with ``status``."""
        self.bar.set_postfix_str(f"{key}: {status}", refresh=False)
        self.bar.update(1)

    def note(self, text: str) -> None:
        """A one-off message (e.g. a retry)."""
        if self.enabled:
            self.bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def waiting(self, text: str | None) -> None:
        """Show the waiting state ``text``; None: no longer waiting."""
        now = time.monotonic()
        if text is None:
            if self._waiting_since is not None:
                self._waiting_since = None
                if self.enabled:
                    self.bar.set_description_str("trials")
                else:
                    self.note("Dask workers connected: running")
            return
        if self._waiting_since is None:
            self._waiting_since, self._last_line = now, -math.inf
        if self.enabled:
            self.bar.set_description_str(text)
        elif now - self._last_line >= _WAITING_REPORT_S:
            self._last_line = now
            self.note(text)

    def close(self) -> None:
        """Close the bar."""
        self.bar.close()


def _lost(spec: TrialSpec, err: BaseException, attempts: int) -> dict[str, Any]:
    return {"spec": spec.to_dict(), "status": STATUS_ERROR, "metrics": {}, "arrays": {},
            "message": f"the Dask worker(s) running this trial were lost {attempts} time(s) "
                       f"({type(err).__name__}: {err}); e.g. killed by the OS for lack of "
                       "memory"}


def _worker_failed(spec: TrialSpec, err: BaseException) -> dict[str, Any]:
    return {"spec": spec.to_dict(), "status": STATUS_ERROR, "metrics": {}, "arrays": {},
            "message": f"the Dask worker could not run the trial ({type(err).__name__}: {err}); "
                       "is this package installed on the workers?"}


def check_scheduler_address(scheduler: str) -> None:
    """Raise :class:`SchedulerError` if ``scheduler`` is neither ``"local"`` nor a well-formed
    Dask address (``tcp://host:port``, ``tls://...``, ...); does not connect."""
    if scheduler == "local":
        return
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError as err:  # pragma: no cover - depends on the optional extra
        raise SchedulerError("--scheduler needs Dask distributed: pip install distributed"
                             ) from err
    try:
        protocol, location = parse_address(scheduler)
        if protocol in ("tcp", "tls"):
            parse_host_port(location)
    except ValueError as err:
        raise SchedulerError(f"bad Dask scheduler address {scheduler!r} ({err}); use e.g. "
                             "tcp://host:8786, or 'local' for a local cluster") from None


def _connect(scheduler: str, workers: int, max_memory_gb: float | None,
             connect_timeout: float) -> tuple[Any, Any]:
    """A Dask client (and the LocalCluster it owns, for ``scheduler="local"``)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as err:  # pragma: no cover - depends on the optional extra
        raise SchedulerError("--scheduler needs Dask distributed: pip install distributed"
                             ) from err
    if scheduler == "local":
        cluster = LocalCluster(n_workers=max(workers, 1), threads_per_worker=1, processes=True,
                               dashboard_address=None,
                               memory_limit=f"{max_memory_gb}GiB" if max_memory_gb else None)
        return Client(cluster), cluster
    check_scheduler_address(scheduler)  # first: a Client with a bad address hangs on cleanup
    try:
        return Client(scheduler, timeout=connect_timeout, set_as_default=False), None
    except (OSError, TimeoutError, ValueError, TypeError) as err:
        raise SchedulerError(f"cannot reach the Dask scheduler {scheduler!r} within "
                             f"{connect_timeout:g} s ({err}); is `dask scheduler` running "
                             "there? (--connect-timeout sets the wait)") from None


def _dask(specs: Sequence[TrialSpec], scheduler: str, workers: int,
          max_memory_gb: float | None = None, status: _Status | None = None,
          connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S,
          worker_timeout: float | None = DEFAULT_WORKER_TIMEOUT_S) -> Iterator[dict[str, Any]]:
    """Run ``specs`` on a Dask cluster, yielding results as they finish.

    While no worker is connected the run waits (the scheduler keeps the tasks; a worker that
    joins picks them up), shows that it waits, and gives up with :class:`SchedulerError` after
    ``worker_timeout`` seconds (None: never). A trial whose future fails because its workers
    were lost (``KilledWorker``) or because it was cancelled is resubmitted up to
    :data:`DASK_RETRIES` times, then recorded as an error; any other failure of the future (not
    of the trial, which :func:`benchmarks.trial.execute` records itself) is recorded as an
    error.
    """
    from concurrent.futures import CancelledError

    from distributed import KilledWorker

    status = status or _Status(len(specs), 0, enabled=False)
    client, cluster = _connect(scheduler, workers, max_memory_gb, connect_timeout)
    address = client.scheduler.address
    token = uuid.uuid4().hex[:8]
    attempts: dict[TrialSpec, int] = {}
    pending: dict[Any, TrialSpec] = {}

    def submit(spec: TrialSpec) -> None:
        attempts[spec] = attempts.get(spec, 0) + 1
        key = f"trial-{spec.key}-{token}-{attempts[spec]}"
        pending[client.submit(execute, spec, key=key, pure=False)] = spec

    try:
        for spec in specs:
            submit(spec)
        no_workers_since: float | None = None
        next_check = -math.inf
        while pending:
            done = [fut for fut in pending if fut.done()]
            for fut in done:
                spec = pending.pop(fut)
                try:
                    result = fut.result()
                except (KilledWorker, CancelledError) as err:
                    if attempts[spec] <= DASK_RETRIES:
                        why = ("lost with its Dask worker (KilledWorker)"
                               if isinstance(err, KilledWorker) else f"cancelled by Dask ({err})")
                        status.note(f"trial {spec.key}: {why}; retrying")
                        submit(spec)
                        continue
                    result = _lost(spec, err, attempts[spec])
                except Exception as err:
                    result = _worker_failed(spec, err)
                no_workers_since = None  # a worker delivered it
                status.waiting(None)
                yield result
            now = time.monotonic()
            if pending and now >= next_check:
                next_check = now + _WORKER_CHECK_S
                try:
                    n_workers = len(client.nthreads())
                except OSError as err:
                    raise SchedulerError(f"lost the connection to the Dask scheduler {address} "
                                         f"({err}); finished trials are kept: rerun the same "
                                         "command to resume") from None
                if n_workers:
                    no_workers_since = None
                    status.waiting(None)
                else:
                    no_workers_since = no_workers_since if no_workers_since is not None else now
                    waited = now - no_workers_since
                    if worker_timeout is not None and waited > worker_timeout:
                        raise SchedulerError(
                            f"no Dask worker connected to {address} for {worker_timeout:g} s "
                            f"({len(pending)} trial(s) not run; finished trials are kept): "
                            f"start workers (`dask worker {address}`) and rerun the same "
                            "command to resume, or raise --worker-timeout")
                    limit = "" if worker_timeout is None else f" of {worker_timeout:g}"
                    status.waiting(f"waiting for Dask workers: none connected to {address} "
                                   f"({waited:.0f}{limit} s)")
            if not done:
                time.sleep(_POLL_S)
    finally:
        with contextlib.suppress(Exception):
            client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()


def run_trials(specs: Iterable[TrialSpec], out_dir: Path, workers: int = 1,
               scheduler: str | None = None, progress: bool = True,
               max_memory_gb: float | None = DEFAULT_MAX_MEMORY_GB,
               connect_timeout: float = DEFAULT_CONNECT_TIMEOUT_S,
               worker_timeout: float | None = DEFAULT_WORKER_TIMEOUT_S) -> RunSummary:
    """Run every trial of ``specs`` not finished yet in ``out_dir`` and store each result.

    Args:
        specs: the trials (validated here: unknown names raise before anything runs).
        out_dir: results directory; trial files go to ``out_dir/runs/``.
        workers: 0 runs in this process; N >= 1 a local pool of N processes (or, with
            ``scheduler="local"``, a local Dask cluster of N workers).
        scheduler: a Dask scheduler address, ``"local"``, or None for no Dask.
        progress: show a tqdm progress bar.
        max_memory_gb: address-space limit of each local worker process (None: no limit); a
            trial exceeding it fails and is recorded as an error. For ``"local"`` Dask
            clusters it is the workers' ``memory_limit``.
        connect_timeout: seconds to reach the Dask ``scheduler``.
        worker_timeout: seconds a Dask run waits while no worker is connected (it says so
            on the progress line, or on stderr without one) before giving up; None: forever.

    Returns:
        The run's :class:`RunSummary`.

    Raises:
        benchmarks.controllers.UnknownNameError: a spec with an unknown name.
        ValueError: ``workers < 0``.
        SchedulerError: the Dask scheduler is unreachable or lost, or no worker connected
            within ``worker_timeout`` (the trials finished so far are stored).
    """
    specs = list(dict.fromkeys(specs))  # unique, in order
    for spec in specs:
        spec.validate()
    if workers < 0:
        raise ValueError(f"workers must be >= 0, got {workers}")
    out_dir = Path(out_dir)
    (out_dir / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    summary = RunSummary()
    pending = []
    for spec in specs:
        if is_finished(out_dir, spec):
            summary.skipped.append(spec.key)
        else:
            pending.append(spec)
    status = _Status(len(specs), len(summary.skipped), enabled=progress)
    if scheduler is not None:
        results = _dask(pending, scheduler, workers, max_memory_gb, status, connect_timeout,
                        worker_timeout)
    elif workers == 0:
        results = _serial(pending)
    else:
        results = _local_pool(pending, min(workers, max(len(pending), 1)), max_memory_gb)
    try:
        for result in results:
            spec = TrialSpec(**result["spec"])
            save_trial(trial_path(out_dir, spec), result)
            summary.ran[spec.key] = result["status"]
            status.finished(spec.key, result["status"])
    finally:
        if hasattr(results, "close"):
            results.close()  # stop the engine now (e.g. a Dask client) when interrupted
        status.close()
    return summary
