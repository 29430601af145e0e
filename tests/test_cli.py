"""Misuse of the benchmark CLI: one line ``gp-bench: error: ...`` on stderr, exit status 2,
nothing done; the default results folder is under the current directory."""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

import benchmarks.cli
from benchmarks.cli import main, parse_seeds

ROOT = Path(__file__).resolve().parent.parent
TINY = ["--controllers", "nominal-mpc", "--envs", "cartpole", "--scenarios", "online",
        "--seeds", "0", "--max-steps", "2", "--workers", "0", "--no-progress"]


def _free_port() -> int:
    """A TCP port of 127.0.0.1 nobody listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``main(argv)``, check exit status 2 and a one-line error; return that line."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gp-bench: error: "), captured.err
    assert "report:" not in captured.out
    return lines[0]


@pytest.mark.parametrize(("argv", "message"), [
    (["--workers", "-2"], "argument --workers: '-2' is not an integer >= 0"),
    (["--workers", "two"], "argument --workers: 'two' is not an integer >= 0"),
    (["--controllers", ""], "--controllers '' names nothing"),
    (["--controllers", "nominal-mpc", "--envs", " , "], "--envs ' , ' names nothing"),
    (["--quick", "--scenarios", ""], "--scenarios '' names nothing"),
    (["--seeds", "5-2"], "empty seed range '5-2'"),
    (["--seeds", "-1"], "bad seed '-1'"),
    (["--seeds", "0,,1"], "bad seed ''"),
    (["--max-steps", "0"], "argument --max-steps: '0' is not an integer >= 1"),
    (["--max-memory-gb", "nan"], "argument --max-memory-gb: 'nan' is not a number of GiB"),
    (["--worker-timeout", "-1"], "argument --worker-timeout: '-1' is not a number of seconds"),
    (["--connect-timeout", "0"], "argument --connect-timeout: '0' is not a number of seconds"),
    (["--preset", "nope"], "unknown preset 'nope'; valid presets: quick"),
    (["--quick", "--controllers", "lqr"], "unknown controller 'lqr'; valid controllers: "),
    (["--quick", "--envs", "moon"], "unknown env 'moon'; valid envs: cartpole"),
    (["--quick", "--seeds", "99"], "the filters leave no trial of preset 'quick'"),
    (["--controllers", "nominal-mpc", "--envs", "dubins", "--scenarios", "gp"],
     "unknown scenario 'gp' of env dubins; valid scenarios of dubins: paper"),
    (["--scheduler", "nohost"], "bad Dask scheduler address 'nohost'"),
    (["--bogus"], "unrecognized arguments: --bogus (see gp-bench --help)"),
])
def test_misuse_is_a_one_line_usage_error_and_does_nothing(
        argv: list[str], message: str, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    if argv[0] == "--scheduler":
        pytest.importorskip("distributed")
    line = _usage_error([*argv, "--no-progress", "--out", str(out)], capsys)
    assert message in line
    assert not out.exists()


def test_report_only_without_results_is_an_error(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "missing"
    line = _usage_error(["--report-only", "--out", str(missing)], capsys)
    assert f"results directory {missing} does not exist" in line
    assert not missing.exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    line = _usage_error(["--report-only", "--preset", "rti", "--out", str(empty)], capsys)
    assert f"no trial of 'rti' in {empty / 'runs'}" in line
    assert list(empty.iterdir()) == []


def test_unwritable_out_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    line = _usage_error([*TINY, "--out", str(blocker / "out")], capsys)
    assert f"--out {blocker / 'out'}: cannot write results there (Not a directory)" in line
    if os.geteuid() == 0:  # root writes into read-only directories
        return
    readonly = tmp_path / "readonly"
    readonly.mkdir()
    readonly.chmod(0o555)
    try:
        line = _usage_error([*TINY, "--out", str(readonly / "out")], capsys)
    finally:
        readonly.chmod(0o755)
    assert "cannot write results there (Permission denied)" in line


def test_unreachable_scheduler_is_an_error(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{_free_port()}"
    line = _usage_error([*TINY, "--scheduler", address, "--connect-timeout", "0.5", "--out",
                         str(tmp_path)], capsys)
    assert f"cannot reach the Dask scheduler {address!r} within 0.5 s" in line


def test_misuse_from_the_shell_prints_no_traceback(tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    for argv in (["--workers", "-2"],
                 ["--scheduler", f"tcp://127.0.0.1:{_free_port()}", "--connect-timeout", "0.5",
                  "--out", str(tmp_path / "out")]):
        res = subprocess.run([sys.executable, "-m", "benchmarks", *TINY, *argv], env=env,
                             cwd=tmp_path, capture_output=True, text=True, timeout=300)
        assert res.returncode == 2, res.stderr
        assert res.stderr.count("\n") == 1 and res.stderr.startswith("gp-bench: error: "), (
            res.stderr)


def test_interrupt_exits_130_and_says_how_to_resume(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(benchmarks.cli, "run_trials", interrupted)
    assert main([*TINY, "--out", str(tmp_path)]) == 130
    err = capsys.readouterr().err
    assert "interrupted: finished trials are kept" in err and "Traceback" not in err


def test_default_results_folder_is_under_the_current_directory(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(TINY) == 0
    assert (tmp_path / "benchmark-results" / "custom" / "report.md").is_file()
    assert len(list((tmp_path / "benchmark-results" / "custom" / "runs").glob("*.npz"))) == 1
    assert "report: benchmark-results/custom/report.md" in capsys.readouterr().out
    assert main([*TINY, "--report-only"]) == 0  # finds it again from the same directory


def test_parse_seeds() -> None:
    assert parse_seeds("0-2,5,1") == [0, 1, 2, 5]
    assert parse_seeds(" 3 ") == [3]
    for bad in ("", "a", "1-", "-1", "2-1", "1.5"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_seeds(bad)


def test_cells_filter_keeps_only_the_named_cells_and_rejects_unknown_ones() -> None:
    from benchmarks.cli import build_parser, resolve
    from benchmarks.controllers import UnknownNameError

    args = build_parser().parse_args(["--preset", "robustness", "--envs", "cartpole",
                                      "--cells", "default,r0.1_ddiff"])
    preset, _ = resolve(args)
    assert {s.cell.key for s in preset.specs} == {"", "r0.1_ddiff"}
    assert all(s.env == "cartpole" for s in preset.specs)
    with pytest.raises(UnknownNameError, match="valid cells: default"):
        resolve(build_parser().parse_args(["--preset", "robustness", "--cells", "r9"]))


def test_a_requested_controller_that_cannot_run_exits_3_with_the_reason(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No SAC model ships for the quadrotor: the custom grid says so and exits non-zero."""
    (tmp_path / "models").mkdir()
    status = main(["--controllers", "sac", "--envs", "quadrotor", "--seeds", "0",
                   "--max-steps", "2", "--workers", "1", "--no-progress",
                   "--models", str(tmp_path / "models"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 3
    assert "not available: sac on quadrotor (online): no SAC model" in err


def test_list_controllers_names_the_envs_each_rl_controller_has_a_model_for(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks.controllers import MODELS_DIR

    def rl_lines() -> dict[str, str]:
        out = capsys.readouterr().out
        return {line.split()[0]: line for line in out.splitlines()
                if line.split() and line.split()[0] in ("sac", "ppo", "tqc")}

    assert main(["--list-controllers"]) == 0
    lines = rl_lines()
    for algo, line in lines.items():
        shipped = sorted(p.parent.parent.name for p in MODELS_DIR.glob(f"*/{algo}/model.zip"))
        assert shipped and line.endswith("; models for " + ", ".join(shipped))
    assert "quadrotor" not in lines["sac"]
    # a user's model (--models DIR, <env>/<algo>/ as benchmarks.rl.train saves) is listed too
    (tmp_path / "quadrotor" / "sac").mkdir(parents=True)
    for name in ("model.zip", "metadata.json"):
        (tmp_path / "quadrotor" / "sac" / name).write_text("")
    assert main(["--list-controllers", "--models", str(tmp_path)]) == 0
    assert "quadrotor (yours)" in rl_lines()["sac"]


@pytest.mark.parametrize(("name", "message"), [
    ("robust-mpc@fast", "unknown scheme 'fast' of controller 'robust-mpc' (schemes: "
                        "converged, sqp, rti, rti-split, as robust-mpc@sqp; the recipe's own: "
                        "no suffix)"),
    ("paper-mpc@converged", "the paper recipe's own scheme is the converged one; use "
                            "'paper-mpc'"),
    ("ssgp-mpc@rti", "'ssgp-mpc' is an older name of 'paper-mpc'; use 'paper-mpc@rti'"),
])
def test_a_known_mpc_with_an_unknown_scheme_names_the_schemes(
        name: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = _usage_error(["--controllers", name, "--envs", "cartpole", "--no-progress",
                         "--out", str(tmp_path / "out")], capsys)
    assert message in line
    assert "valid controllers" not in line  # not the whole registry
    assert not (tmp_path / "out").exists()


def test_print_report_prints_and_writes_the_text(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """``print_report``, the tools' (studies') output: printed, and with ``out`` also written
    there, its folders made."""
    from benchmarks.cli import print_report

    print_report("# a table\n")
    assert capsys.readouterr().out == "# a table\n\n"
    print_report("# a table\n", tmp_path / "new" / "report.md")
    assert capsys.readouterr().out == "# a table\n\n"
    assert (tmp_path / "new" / "report.md").read_text() == "# a table\n"
