"""The documentation site builds with zero warnings on the committed tree, and its API
reference lists every public name of ``gp_envs`` and ``gp_agents``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import gp_agents
import gp_envs

REPO = Path(__file__).resolve().parents[1]
sphinx = pytest.importorskip("sphinx", reason="the docs extra is not installed")


def test_docs_build_without_warnings_and_list_every_public_name(tmp_path: Path):
    from sphinx.util.inventory import InventoryFile

    out = tmp_path / "html"
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(REPO / "docs"), str(out)],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]
    with (out / "objects.inv").open("rb") as f:
        inventory = InventoryFile.load(f, "", lambda base, uri: uri)
    by_type = getattr(inventory, "data", inventory)  # a plain dict before Sphinx 8.2
    documented = {name for objects in by_type.values() for name in objects}
    missing = [f"{m.__name__}.{name}" for m in (gp_envs, gp_agents) for name in m.__all__
               if f"{m.__name__}.{name}" not in documented]
    assert missing == []
    # the results pages are generated from the committed summary.csv files
    assert (out / "results" / "recommended.html").is_file()


def test_results_pages_follow_the_results_folders(tmp_path: Path):
    """A page per results folder with a ``summary.csv``, the archive only named in the index,
    and the page of a folder that is gone removed (no stale page outside every toctree)."""
    sys.path.insert(0, str(REPO / "docs"))
    try:
        from results_pages import write_results_pages
    finally:
        sys.path.remove(str(REPO / "docs"))
    results, out = tmp_path / "results", tmp_path / "pages"
    summary = (REPO / "benchmarks" / "results" / "recommended" / "summary.csv").read_text()
    for folder in ("kept", "archive/old"):
        (results / folder).mkdir(parents=True)
        (results / folder / "summary.csv").write_text(summary)
    out.mkdir()
    (out / "moved.md").write_text("# a folder that was moved to the archive\n")
    written = write_results_pages(results, out)
    assert sorted(p.name for p in written) == ["index.md", "kept.md"]
    assert sorted(p.name for p in out.glob("*.md")) == ["index.md", "kept.md"]
    assert "`old`" in (out / "index.md").read_text()
