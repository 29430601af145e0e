"""Every code block a user sees runs: the examples (in their smoke setting, like acados' examples
in CI), and each Python block of the README and the user guide, as written."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p for p in (REPO / "examples").rglob("*.py")
                  if p.parent.name != "gp_puck")
DOCUMENTS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
_BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "GP_EXAMPLES_SMOKE": "1", "OMP_NUM_THREADS": "1",
           "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)


def _blocks() -> list[tuple[str, str]]:
    out = []
    for doc in DOCUMENTS:
        if doc.is_relative_to(REPO / "docs" / "results") or not doc.is_file():
            continue
        for i, match in enumerate(_BLOCK.finditer(doc.read_text())):
            out.append((f"{doc.relative_to(REPO)}#{i}", match.group(1)))
    return out


def test_there_are_examples_and_blocks():
    assert len(EXAMPLES) >= 5 and any(name.startswith("README") for name, _ in _blocks())


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: str(p.relative_to(REPO)))
def test_example_runs(script: Path, tmp_path: Path):
    result = _run([str(script)], tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.strip(), "an example prints what it did"
    if script.name == "dask_sweep.py":  # its report outlives the run, in the current directory
        report = tmp_path.resolve() / "benchmark-results" / "dask-sweep-smoke" / "report.md"
        assert report.is_file() and str(report.parent) in result.stdout


@pytest.mark.parametrize(("name", "code"), _blocks(), ids=[name for name, _ in _blocks()])
def test_document_block_runs_as_written(name: str, code: str, tmp_path: Path):
    script = tmp_path / "block.py"
    script.write_text(code)
    result = _run([str(script)], tmp_path)
    assert result.returncode == 0, f"{name}:\n{result.stderr[-3000:]}"


@pytest.mark.parametrize("preset", ["recommended", "own-env"])
def test_readme_results_table_is_generated_from_the_committed_summary(preset: str):
    from benchmarks.readme_table import readme_table

    table = readme_table(REPO / "benchmarks" / "results" / preset).strip()
    readme = (REPO / "README.md").read_text()
    block = readme.split(f"<!-- results:{preset} -->\n")[1].split("<!-- /results")[0]
    assert block.strip() == table


def test_readme_is_a_front_door():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= 250
    assert lines[2:6] == ["```bash", lines[3], lines[4], "```"] and "make test" in lines[4]
    assert not any(re.search(r"\b[0-9a-f]{7,40}\b", line) and "commit" in line for line in lines)
