"""Tables, plots and the Markdown report of a results directory.

:func:`write_report` reads the trial files of a preset (``<out>/runs/*.npz``, see
:mod:`benchmarks.runner`) and writes next to them:

- ``metrics.csv``: one row per episode trial (the tidy table of metrics);
- ``summary.csv``: per experiment, env, scenario and controller: success rate, cost, errors,
  violations, data used, step times;
- ``compute.csv`` and ``peers.csv`` when the preset has those measurements;
- PNG figures, and ``report.md`` embedding them with the command and package versions.

Every number in the report comes from the trial files; nothing is typed in.

The package has one job per module: :mod:`~benchmarks.report.load` (trial files, metric
rows), :mod:`~benchmarks.report.stats` (intervals), :mod:`~benchmarks.report.summarize`
(``summary.csv``), :mod:`~benchmarks.report.figures`, the sections
(:mod:`~benchmarks.report.sections_episodes`, ``sections_compute``, ``sections_acceptance``,
``sections_data``; helpers in :mod:`~benchmarks.report.common`, cited figures in
:mod:`~benchmarks.report.published`), :mod:`~benchmarks.report.provenance` and
:mod:`~benchmarks.report.write` (:func:`write_report`). The public names of every module are
importable from ``benchmarks.report`` itself.
"""

from benchmarks.report.common import Context, SectionFn, cli_name, controller_legend, markdown_table
from benchmarks.report.figures import (
    data_efficiency_figure,
    paths_figure,
    scaling_figure,
    step_scaling_figure,
    step_times_figure,
    trajectories_figure,
    update_time_figure,
)
from benchmarks.report.load import (
    METRIC_COLUMNS,
    SUMMARY_COLUMNS,
    TIME_COLUMNS,
    Trial,
    compute_rows,
    load_trials,
    metric_rows,
    peer_rows,
)
from benchmarks.report.provenance import PACKAGES, package_versions
from benchmarks.report.published import (
    PUBLISHED_ANCHORS,
    PUBLISHED_RETURNS,
    PublishedAnchor,
    PublishedReturn,
)
from benchmarks.report.sections_acceptance import RTI_TARGET, SPEED_TARGET, section_acceptance
from benchmarks.report.sections_compute import (
    section_peers,
    section_scaling,
    section_step_scaling,
    section_update_time,
)
from benchmarks.report.sections_data import section_data_efficiency, section_own_env
from benchmarks.report.sections_episodes import (
    section_paper_tables,
    section_paths,
    section_robustness,
    section_sample_efficiency,
    section_step_times,
    section_summary,
    section_trajectories,
)
from benchmarks.report.stats import mean_ci, wilson_ci
from benchmarks.report.summarize import summarize
from benchmarks.report.write import SECTIONS, write_report

__all__ = [
    "METRIC_COLUMNS",
    "PACKAGES",
    "PUBLISHED_ANCHORS",
    "PUBLISHED_RETURNS",
    "RTI_TARGET",
    "SECTIONS",
    "SPEED_TARGET",
    "SUMMARY_COLUMNS",
    "TIME_COLUMNS",
    "Context",
    "PublishedAnchor",
    "PublishedReturn",
    "SectionFn",
    "Trial",
    "cli_name",
    "compute_rows",
    "controller_legend",
    "data_efficiency_figure",
    "load_trials",
    "markdown_table",
    "mean_ci",
    "metric_rows",
    "package_versions",
    "paths_figure",
    "peer_rows",
    "scaling_figure",
    "section_acceptance",
    "section_data_efficiency",
    "section_own_env",
    "section_paper_tables",
    "section_paths",
    "section_peers",
    "section_robustness",
    "section_sample_efficiency",
    "section_scaling",
    "section_step_scaling",
    "section_step_times",
    "section_summary",
    "section_trajectories",
    "section_update_time",
    "step_scaling_figure",
    "step_times_figure",
    "summarize",
    "trajectories_figure",
    "update_time_figure",
    "wilson_ci",
    "write_report",
]
