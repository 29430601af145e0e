"""The package works outside the repository: shipped RL policies resolve from the installed
package (by name, from any directory, given the benchmark's model directory), the library never
imports the benchmark, and a wheel installed non-editably runs an RL and an MPC trial from an
empty directory, writing its results there."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from benchmarks.runner import load_record

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "benchmarks" / "models"
SHIPPED = sorted(p.parent.relative_to(MODELS).as_posix() for p in MODELS.glob("*/*/model.zip"))
"""The policies in the checkout (``<env>/<algo>``), which the package must ship."""


@pytest.fixture
def rl() -> object:
    return pytest.importorskip("gp_agents.rl")


def test_shipped_policies_load_by_name_from_any_directory(
        rl: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import gymnasium as gym

    import gp_envs  # noqa: F401  (registers the envs)
    from benchmarks.controllers import MODELS_DIR
    from gp_agents.rl import RLAgent, resolve_model_dir, saved_models

    assert MODELS_DIR == MODELS
    assert saved_models(MODELS_DIR) == SHIPPED and "cartpole/sac" in SHIPPED
    monkeypatch.chdir(tmp_path)  # no benchmarks/models/ here
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    for name in ("benchmarks/models/cartpole/sac", "cartpole/sac", "models/cartpole/sac",
                 "benchmarks/models/cartpole/sac/model.zip"):
        assert resolve_model_dir(name, [MODELS_DIR]) == MODELS / "cartpole" / "sac", name
    agent = RLAgent.load("cartpole/sac", env, search=[MODELS_DIR])
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(agent.act(obs))
    # a saved agent in the current directory comes first, whatever its name
    shutil.copytree(MODELS / "cartpole" / "sac", tmp_path / "cartpole" / "sac")
    assert resolve_model_dir("cartpole/sac", [MODELS_DIR]) == Path("cartpole/sac")
    RLAgent.load("cartpole/sac", env)


def test_unknown_policy_names_list_the_shipped_ones(rl: object, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    from benchmarks.controllers import MODELS_DIR
    from gp_agents.rl import resolve_model_dir

    monkeypatch.chdir(tmp_path)
    listed = re.escape(f"in {MODELS_DIR}: " + ", ".join(SHIPPED))
    for name in ("cartpole/ppo", "benchmarks/models/moon/sac", str(tmp_path / "nothing")):
        with pytest.raises(FileNotFoundError, match=listed):
            resolve_model_dir(name, [MODELS_DIR])
    with pytest.raises(FileNotFoundError, match=f"relative to {tmp_path}"):
        resolve_model_dir("cartpole/ppo", [MODELS_DIR])
    with pytest.raises(FileNotFoundError, match="search="):  # the message names the fix
        resolve_model_dir("cartpole/sac")


def test_the_library_never_imports_the_benchmark() -> None:
    """gp_envs -> gp_agents -> benchmarks: no module of the library imports ``benchmarks``,
    neither by an import statement nor by naming it in a string (``importlib`` and
    ``importlib.resources`` take module names as strings)."""
    import ast

    module_name = re.compile(r"benchmarks(\.\w+)*")
    found = []
    for package in ("gp_envs", "gp_agents"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                names: list[str] = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom):
                    names = [node.module or ""]
                elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                    names = [node.value]
                found += [f"{path.relative_to(ROOT)}:{node.lineno}: {n!r}" for n in names
                          if module_name.fullmatch(n)]
    assert not found, found


def _copy_sources(dest: Path) -> Path:
    """The files a build needs, copied from the checkout (a build writes ``build/`` and
    ``*.egg-info`` next to its sources; the checkout stays untouched)."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "results", "checkpoints", "runs",
                                    ".saving", "*.tmp", "*.egg-info", "build")
    for name in ("gp_envs", "gp_agents", "benchmarks"):
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, dest / name)
    return dest


@pytest.mark.slow
def test_wheel_installed_in_a_fresh_venv_runs_rl_and_mpc_trials(rl: object,
                                                                 tmp_path: Path) -> None:
    pytest.importorskip("setuptools")
    src = _copy_sources(tmp_path / "src")
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps",
                    "--no-build-isolation", "--no-index", "-q", "-w", str(tmp_path / "dist")],
                   check=True, cwd=tmp_path, timeout=600)
    wheel = next((tmp_path / "dist").glob("*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for model in SHIPPED:  # every file of every shipped policy
        for f in (MODELS / model).iterdir():
            if f.is_file() and not f.name.endswith(".tmp"):
                assert f"benchmarks/models/{model}/{f.name}" in names
    assert not any(n.startswith("benchmarks/results/") for n in names)

    # a fresh venv; its third-party dependencies come from this interpreter's site-packages
    # through a .pth line (a plain path: that directory's own .pth files, among them this
    # checkout's editable install, are not processed)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True,
                   timeout=300)
    python = venv / "bin" / "python"
    purelib = subprocess.run([str(python), "-c", "import sysconfig; "
                              "print(sysconfig.get_paths()['purelib'])"], check=True,
                             capture_output=True, text=True).stdout.strip()
    deps = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (Path(purelib) / "_deps.pth").write_text("\n".join(sorted(deps)) + "\n")
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q",
                    "--no-deps", "--no-index", str(wheel)], check=True, timeout=600)

    work = tmp_path / "elsewhere"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env["OMP_NUM_THREADS"] = "1"
    probe = subprocess.run([str(python), "-c", """if True:
        import json, sys
        import benchmarks, gp_agents, gp_envs
        import gymnasium as gym
        from benchmarks.trial import code_version
        from benchmarks.controllers import MODELS_DIR
        from gp_agents.rl import RLAgent, saved_models
        env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
        RLAgent.load("benchmarks/models/cartpole/sac", env, search=[MODELS_DIR])
        print(json.dumps({"files": [m.__file__ for m in (benchmarks, gp_agents, gp_envs)],
                          "path": sys.path, "shipped": saved_models(MODELS_DIR),
                          "version": code_version()}))
        """], cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert probe.returncode == 0, probe.stderr
    info = json.loads(probe.stdout.splitlines()[-1])
    assert all(Path(f).is_relative_to(venv) for f in info["files"]), info["files"]
    assert not any(Path(p).resolve() == ROOT for p in info["path"] if p)
    assert info["shipped"] == SHIPPED and info["version"].startswith("v")

    run = subprocess.run([str(venv / "bin" / "gp-bench"), "--controllers", "nominal-mpc,sac",
                          "--envs", "cartpole", "--scenarios", "online", "--seeds", "0",
                          "--max-steps", "3", "--workers", "0", "--no-progress"],
                         cwd=work, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    out = work / "benchmark-results" / "custom"
    assert (out / "report.md").is_file()
    records = [load_record(p) for p in sorted((out / "runs").glob("*.npz"))]
    assert sorted(r["spec"]["controller"] for r in records) == ["nominal-mpc", "sac"]
    assert all(r["status"] == "ok" for r in records), [r["message"] for r in records]
    assert {r["code_version"] for r in records} == {info["version"]}
    assert list(work.iterdir()) == [work / "benchmark-results"]  # nothing else written there
