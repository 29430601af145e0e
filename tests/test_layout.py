"""The package's layers: studies and RL tooling stand apart from the engine and the library."""

from __future__ import annotations

import os
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STUDIES = sorted(p.stem for p in (REPO / "benchmarks" / "studies").glob("*.py")
                 if p.stem != "__init__")


def _sources(*folders: str, skip: tuple[str, ...] = ()) -> dict[str, str]:
    out = {}
    for folder in folders:
        for path in (REPO / folder).rglob("*.py"):
            rel = str(path.relative_to(REPO))
            if not rel.startswith(skip):
                out[rel] = path.read_text()
    return out


def test_no_engine_or_library_module_imports_a_study():
    """No import of a study in the engine or the library, but the registry's one lazy import of
    the study variants (:func:`benchmarks.controllers.load_study_variants`)."""
    assert STUDIES, "benchmarks/studies has the studies"
    pattern = re.compile(r"benchmarks\.studies|from benchmarks import .*\b("
                         + "|".join(STUDIES) + r")\b")
    code = _sources("gp_envs", "gp_agents", "benchmarks",
                    skip=("benchmarks/studies/", "benchmarks/rl/"))
    hits = [path for path, text in code.items()
            if any(pattern.search(line) and not line.lstrip().startswith(("#", '"', "``"))
                   and ("import" in line) for line in text.splitlines())]
    assert hits == []


def test_importing_the_engine_imports_no_study_and_a_study_variant_loads_on_demand():
    import subprocess
    import sys

    code = """if True:
        import sys
        import benchmarks.cli, benchmarks.controllers, benchmarks.presets, benchmarks.report
        import benchmarks.runner, benchmarks.trial
        from benchmarks.controllers import CONTROLLERS
        studies = lambda: sorted(m for m in sys.modules if m.startswith("benchmarks.studies"))
        assert studies() == [], studies()
        assert CONTROLLERS["robust-mpc"].main and studies() == [], studies()
        assert CONTROLLERS["ssgp-mpc-linearized"].recipe is None  # a study variant, registered
        assert "benchmarks.studies.variants" in studies()
        """
    result = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                            text=True, env={**os.environ, "OMP_NUM_THREADS": "1"}, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]


def test_no_library_module_names_a_results_file():
    code = _sources("gp_envs", "gp_agents")
    assert [p for p, text in code.items() if "benchmarks/results" in text] == []


def test_library_docstrings_keep_no_lab_notebook():
    """The library describes behaviour and reasons: which study decided what, on which tuning
    seeds, lives in the decision records (docs/studies), not in gp_envs or gp_agents."""
    code = _sources("gp_envs", "gp_agents")
    notebook = ("docs/studies", "tuning seed", "decision record", "preset's report",
                "study ``")
    found = [(p, phrase) for p, text in code.items() for phrase in notebook
             if phrase in text.lower()]
    assert found == []


RESULTS = REPO / "benchmarks" / "results"


def _results_entries() -> set[str]:
    """The committed top-level entries of ``benchmarks/results`` (folders and files)."""
    import subprocess

    try:
        listed = subprocess.run(["git", "ls-files", "--", "benchmarks/results"], cwd=REPO,
                                capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        import pytest

        pytest.skip("not a git checkout")
    return {Path(line).parts[2] for line in listed.splitlines()
            if len(Path(line).parts) > 2 and (REPO / line).exists()}


def _citing_pages() -> dict[str, str]:
    """The README and every hand-written documentation page (the results pages under
    ``docs/results/`` are generated, see :func:`_rendered_folders`)."""
    docs = REPO / "docs"
    pages = [REPO / "README.md", *(p for ext in ("md", "rst") for p in docs.rglob(f"*.{ext}")
                                   if p.relative_to(docs).parts[0] not in ("results", "_build"))]
    return {str(p.relative_to(REPO)): p.read_text() for p in pages}


def _rendered_folders(tmp_path: Path) -> set[str]:
    """The results folders the documentation's results pages are generated from."""
    import sys

    sys.path.insert(0, str(REPO / "docs"))
    try:
        from results_pages import write_results_pages
    finally:
        sys.path.remove(str(REPO / "docs"))
    return {p.stem for p in write_results_pages(RESULTS, tmp_path) if p.name != "index.md"}


def _uncited(entries: set[str], pages: dict[str, str], rendered: set[str]) -> list[str]:
    def cited(name: str) -> bool:
        # `benchmarks/results/rti` is not a citation of `rti-parametric` nor the reverse
        pattern = re.compile(r"benchmarks/results/" + re.escape(name) + r"(?![\w-]|\.\w)")
        return any(pattern.search(text) for text in pages.values())
    return sorted(name for name in entries if name not in rendered and not cited(name))


def test_every_results_entry_is_cited_by_the_readme_or_a_docs_page(tmp_path: Path):
    entries, pages = _results_entries(), _citing_pages()
    rendered = _rendered_folders(tmp_path)
    assert {"recommended", "quick"} <= rendered <= entries
    assert _uncited(entries, pages, rendered) == []
    # the check is a real one: an entry nothing names is reported, a longer name is no citation
    assert _uncited({"recommended", "no-such-run", "recommended-x"}, pages, set()) == [
        "no-such-run", "recommended-x"]


def test_make_bench_writes_outside_the_committed_results_by_default():
    """``make bench`` on a fresh clone leaves ``git status`` clean: its default ``OUT`` is a
    git-ignored folder; ``make bench OUT=benchmarks/results/quick`` updates the committed run."""
    import subprocess

    makefile = (REPO / "Makefile").read_text()
    default = re.search(r"^OUT \?= (\S+)$", makefile, re.M)
    assert default, "the Makefile sets a default OUT"
    recipe = re.search(r"^bench:.*\n((?:\t.*\n)+)", makefile, re.M)
    assert recipe and "--out $(OUT)" in recipe.group(1)
    out = default.group(1)
    assert not out.startswith("benchmarks/results")
    try:
        ignored = subprocess.run(["git", "check-ignore", "-q", f"{out}/report.md"], cwd=REPO)
    except OSError:
        import pytest

        pytest.skip("git is not installed")
    assert ignored.returncode == 0, f"{out} is not git-ignored"
