"""The statistics of the report: means, bootstrap intervals of the mean, Wilson intervals."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np


def _max_finite(values: Iterable[float]) -> float:
    """Largest finite value (nan if there is none, e.g. a metric undefined for the env)."""
    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    return float(arr.max()) if arr.size else math.nan


def _mean(values: Sequence[float]) -> float:
    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    return float(arr.mean()) if arr.size else float("nan")


def mean_ci(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """Bootstrap interval of the mean over seeds (scipy's BCa, 9,999 resamples, fixed random
    state so the report is a function of the trials); (nan, nan) below 5 finite values (a
    bootstrap of fewer says nothing), the value twice if they are all equal."""
    from scipy.stats import bootstrap

    arr = np.asarray([v for v in values if v is not None], float)
    arr = arr[np.isfinite(arr)]
    if arr.size < 5:
        return math.nan, math.nan
    if np.ptp(arr) == 0:
        return float(arr[0]), float(arr[0])
    res = bootstrap((arr,), np.mean, confidence_level=confidence, n_resamples=9999,
                    method="BCa", random_state=0)
    low, high = float(res.confidence_interval.low), float(res.confidence_interval.high)
    if not (math.isfinite(low) and math.isfinite(high)):  # BCa degenerate: percentile
        low, high = (float(v) for v in np.percentile(
            bootstrap((arr,), np.mean, n_resamples=9999, method="percentile",
                      random_state=0).bootstrap_distribution, [2.5, 97.5]))
    return low, high


def wilson_ci(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a success rate (nan, nan for n = 0)."""
    from scipy.stats import norm

    if n == 0:
        return math.nan, math.nan
    z = float(norm.ppf(0.5 + confidence / 2))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def _finite_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and math.isfinite(value)
