"""Test-session settings.

One BLAS/OpenMP thread per process, as ``make test`` sets: the suite starts process pools and a
Dask cluster, and with NumPy's and CasADi's default thread counts they oversubscribe this
2-core machine (the whole suite then takes ~3.5x longer). Set before NumPy is imported.

The session's temporary files go to a private directory (``TMPDIR`` and
:func:`tempfile.gettempdir` of this process and of every subprocess it starts), so that what
the code under test leaves behind can be told apart from what other processes on the machine
write to the shared temp directory. At the end of the session :func:`_no_temp_leftovers`
fails, listing them, if entries matching :data:`LEFTOVER_PATTERNS` remain there, and removes
the directory. pytest's own ``tmp_path`` directories stay in the system temp directory
(``PYTEST_DEBUG_TEMPROOT``), kept as pytest keeps them.
"""

import fnmatch
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")

LEFTOVER_PATTERNS = ("SB3-*",)
"""Temp-dir entries this package's code must not leave behind (``SB3-<date>``: the default
folder of a stable-baselines3 logger, made by every ``model.learn`` without a logger set)."""

_SYSTEM_TMP = tempfile.gettempdir()
os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", _SYSTEM_TMP)
SESSION_TMP = Path(tempfile.mkdtemp(prefix="gp-tests-tmp-"))
"""The session's private temp directory (removed at the end of the session)."""
os.environ["TMPDIR"] = str(SESSION_TMP)
tempfile.tempdir = None  # gettempdir() re-reads TMPDIR


@pytest.fixture(scope="session", autouse=True)
def _no_temp_leftovers() -> Iterator[None]:
    """Fail the session if the code under test left :data:`LEFTOVER_PATTERNS` entries in the
    temp directory (listing them); remove the session's temp directory either way."""
    yield
    try:
        names = sorted(os.listdir(SESSION_TMP))
        left = [n for n in names if any(fnmatch.fnmatch(n, p) for p in LEFTOVER_PATTERNS)]
    finally:
        shutil.rmtree(SESSION_TMP, ignore_errors=True)
    if left:
        pytest.fail(f"the tests left {len(left)} temp entries matching {LEFTOVER_PATTERNS} "
                    f"behind: {', '.join(left)} (e.g. an SB3 model trained without a logger: "
                    f"model.set_logger(...) before learn())", pytrace=False)
