"""Provenance of a report: package versions, the git commit, and facts of the trial records."""

from __future__ import annotations

import importlib.metadata
import math
import platform
import subprocess
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from benchmarks.trial import EPISODE_KINDS

PACKAGES = ("gp-pseudospectral-mpc", "numpy", "scipy", "casadi", "gymnasium", "matplotlib",
            "torch", "stable-baselines3", "do-mpc", "dask", "distributed", "tqdm")


def package_versions() -> dict[str, str]:
    """Installed versions of the packages the results depend on (``"-"`` if absent)."""
    out = {"python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = "-"
    return out


def _git_commit() -> str:
    try:
        res = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10, cwd=Path(__file__).resolve().parent)
        return res.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _record_counts(trials: Iterable[Any], key: str) -> str:
    """``"value (trials), ..."`` of a trial-record field (e.g. the code version, the CPU)."""
    counts: dict[str, int] = defaultdict(int)
    for t in trials:
        if t.record is not None:
            counts[str(t.record.get(key, "not recorded"))] += 1
    return ", ".join(f"{v} ({n})" for v, n in sorted(counts.items()))


def _capped(trials: Iterable[Any]) -> str:
    capped = [int(c) for t in trials if t.ok and t.spec.kind in EPISODE_KINDS
              for c in [t.metrics.get("capped_solves", math.nan)]
              if isinstance(c, int | float) and math.isfinite(c)]
    return (f"{sum(capped)} in {sum(c > 0 for c in capped)} of {len(capped)} MPC episode(s)"
            if capped else "no MPC episodes")
