"""The package's layers: studies and RL tooling stand apart from the engine and the library."""

from __future__ import annotations

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
    assert STUDIES, "benchmarks/studies has the studies"
    pattern = re.compile(r"benchmarks\.studies|from benchmarks import .*\b("
                         + "|".join(STUDIES) + r")\b")
    code = _sources("gp_envs", "gp_agents", "benchmarks",
                    skip=("benchmarks/studies/", "benchmarks/rl/"))
    hits = [path for path, text in code.items()
            if any(pattern.search(line) and not line.lstrip().startswith(("#", '"', "``"))
                   and ("import" in line) for line in text.splitlines())]
    assert hits == []


def test_no_library_module_names_a_results_file():
    code = _sources("gp_envs", "gp_agents")
    assert [p for p, text in code.items() if "benchmarks/results" in text] == []
