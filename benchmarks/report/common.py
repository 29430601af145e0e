"""What every report section shares: labels and styles of controllers, the benchmark envs'
nominal models, number formatting, Markdown tables and the :class:`Context` a section sees."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import gp_envs
from benchmarks.controllers import CONTROLLERS, ENVS, make_env, scenario_changes
from benchmarks.presets import Experiment
from benchmarks.report.load import Trial
from benchmarks.styles import Style, style
from benchmarks.trial import TrialSpec


def cli_name(controller: str) -> str:
    """The controller's CLI name: its own, or for an older name kept as an alias
    (:data:`benchmarks.controllers.ALIASES`, e.g. ``ssgp-mpc-linearized-parametric``) the
    composed name it stands for (``robust-mpc@converged``). The one vocabulary of reports,
    docs pages and README tables."""
    recipe = CONTROLLERS.get(controller)
    return recipe.alias_of if recipe is not None and recipe.alias_of else controller


def _label(controller: str) -> str:
    """The controller's name in figures: its :func:`cli_name`."""
    return cli_name(controller)


def _name(controller: str) -> str:
    """The controller's name in Markdown: its :func:`cli_name` as code."""
    return f"`{cli_name(controller)}`"


def _description(controller: str) -> str:
    """The recipe's label (the ``label`` column of ``summary.csv``; the name if it has none)."""
    recipe = CONTROLLERS.get(controller)
    return recipe.label if recipe else controller


def controller_legend(controllers: Iterable[str]) -> list[str]:
    """One legend line under a table naming ``controllers``: each :func:`cli_name` with the
    recipe's label and description (none known: no lines)."""
    names = [n for n in dict.fromkeys(cli_name(c) for c in controllers) if n in CONTROLLERS]
    items = [f"`{n}` ({CONTROLLERS[n].label}): {CONTROLLERS[n].description.rstrip('.')}."
             for n in names]
    return ["", "Controllers: " + " ".join(items)] if items else []


def _style(controller: str) -> Style:
    """The controller's fixed style (:data:`benchmarks.styles.STYLES`; raises if it has none)."""
    return style(controller)


@functools.cache
def _env_model(env: str, scenario: str) -> Any:
    """The nominal :class:`gp_envs.ControlModel` of benchmark env ``env`` in ``scenario``
    (its ``dt``, names and task; the Dubins nominal parameters redrawn at each reset do not
    matter here)."""

    made = make_env(env, scenario)
    try:
        return gp_envs.nominal_model(made)
    finally:
        made.close()


@functools.cache
def _system(env: str) -> str | None:
    """The registered system whose physics benchmark env ``env`` plans with (the key of
    :func:`benchmarks.styles.unit`): the env's own, or for an outside env the system of its
    nominal model's physics module (None: a user's ODE, whose units are not known)."""
    from gp_envs.systems import SYSTEMS

    if ENVS[env].outside is None:
        return env
    module = getattr(_env_model(env, ENVS[env].default_scenario).ode, "__module__", "")
    name = module.rsplit(".", 1)[-1]
    return name if module.startswith("gp_envs.physics.") and name in SYSTEMS else None


def _notes(*parts: str | list[str]) -> str:
    """``" (a; b)"`` of the non-empty notes, or empty."""
    flat = [p for part in parts for p in ([part] if isinstance(part, str) else part) if p]
    return f" ({'; '.join(flat)})" if flat else ""


def _fmt(value: Any, digits: int = 2) -> str:
    if value is None:
        return ""
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if not math.isfinite(value):
            return "n/a"
        if abs(value) >= 1000:
            return f"{value:.0f}"
        return f"{value:.{digits}f}"
    return str(value)


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[Any]],
                   align: Sequence[str] | None = None) -> list[str]:
    """Lines of a Markdown table; numbers formatted by :func:`_fmt`."""
    align = align or ["---"] * len(header)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    for row in rows:
        lines.append("| " + " | ".join(_fmt(v) for v in row) + " |")
    return lines


def _interval(low: float, high: float, digits: int = 2) -> str:
    """``[low, high]``, or empty when undefined."""
    if not (isinstance(low, float | int) and math.isfinite(low) and math.isfinite(high)):
        return ""
    return f"[{_fmt(float(low), digits)}, {_fmt(float(high), digits)}]"


def _env_title(env: str, scenario: str) -> str:
    return f"{ENVS[env].env_id or env} ({scenario})"


@dataclass
class Context:
    """What a report section sees."""

    out_dir: Path
    trials: dict[TrialSpec, Trial]
    summaries: dict[str, list[dict[str, Any]]]
    compute_rows: list[dict[str, Any]]
    peer_rows: list[dict[str, Any]]

    def of(self, experiment: Experiment) -> list[Trial]:
        """The experiment's trials."""
        return [self.trials[s] for s in experiment.specs]


SectionFn = Callable[[Context, Experiment], list[str]]


def _first_ok(trials: Sequence[Trial]) -> Trial | None:
    ok = sorted((t for t in trials if t.ok), key=lambda t: t.spec.seed)
    return ok[0] if ok else None


def _row_key(row: dict[str, Any]) -> str:
    return str(row["key"])


def _seconds(n: int, dt: float) -> str:
    return f"{n} ({n * dt:g} s)"


def _max_trials() -> int:
    from benchmarks.trial import MAX_TRIALS

    return MAX_TRIALS


def _time_varying(row: dict[str, Any]) -> bool:
    """Whether a summary row is of a time-varying scenario (it has recovery times to show)."""
    return bool(_env_model_changes(row["env"], row["scenario"]))


@functools.cache
def _env_model_changes(env: str, scenario: str) -> tuple[Any, ...]:
    return scenario_changes(env, scenario)
