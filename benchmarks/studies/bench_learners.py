"""Benchmark of the GP residual learners on cart-pole residual data (measured, not asserted).

Run:  python benchmarks/studies/bench_learners.py [--quick]

Data: the "online" cart-pole scenario of ``gp_envs``; residual targets are the acceleration
components (indices 2, 3) of ``oracle.f - nominal.f`` at states/forces drawn uniformly over a
swing-up region (seeded), inputs ``z = [x, u]`` (d_in = 5).

Reports (CSV + Markdown under ``benchmarks/results/learners/``):

1. accuracy: nMSE of the exact GP and of the SSGP (hyperparameters from the exact GP, and from
   the SSGP's own marginal likelihood) for r in {25, 50, 100, 200, 400}, medians over frequency
   seeds; also the SSGP's deviation from the exact GP's mean;
2. incremental cost: seconds per single-sample ``IncrementalSSGP.update`` (both outputs), with
   and without the weight solve, against r, and the fitted exponent of ``time ~ r^k``;
3. exact-GP refit cost (fixed hyperparameters, O(N^3) Cholesky) as N grows to 5,000.

Targets (reported, not enforced): update < 1 ms per sample at r = 200; SSGP nMSE within 1.2x of
the exact GP's at r = 200.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import csv
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from gp_agents.learners import SSGP, ExactGP, IncrementalSSGP

OUT_DIR = Path(__file__).resolve().parents[1] / "results" / "learners"
R_VALUES = (25, 50, 100, 200, 400)
NOISE_FRAC = 0.05  # training-target noise of the second accuracy run (finite-difference-like)


# ---------------------------------------------------------------------------- data
def cartpole_residuals(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Inputs ``z = [x, u]`` (n, 5) and acceleration residuals (n, 2) of the online cart pole."""
    import gymnasium as gym

    import gp_envs

    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    env.reset(seed=seed)
    nominal = env.unwrapped.nominal_model
    oracle = gp_envs.oracle_model(env)
    rng = np.random.default_rng(seed)
    X = np.column_stack(
        [
            rng.uniform(-2.0, 2.0, n),  # cart position (track |x| <= 2.5)
            rng.uniform(0.0, 2.0 * np.pi, n),  # pole angle over the whole circle
            rng.uniform(-4.0, 4.0, n),  # cart velocity
            rng.uniform(-12.0, 12.0, n),  # pole rate
        ]
    )
    U = rng.uniform(nominal.u_lb, nominal.u_ub, (n, nominal.n_controls))
    Y = (oracle.f(X, U) - nominal.f(X, U))[:, 2:4]
    env.close()
    return np.hstack([X, U]), Y


def nmse(pred: np.ndarray, target: np.ndarray) -> float:
    """Mean over outputs of MSE / variance of the target."""
    return float(np.mean(np.mean((pred - target) ** 2, axis=0) / np.var(target, axis=0)))


def median_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def fit_exponent(x: np.ndarray, y: np.ndarray) -> float:
    """Slope of log y against log x (least squares)."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def write_csv(name: str, rows: list[dict]) -> None:
    with open(OUT_DIR / name, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def md_table(rows: list[dict], fmt: dict[str, str]) -> str:
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        lines.append("| " + " | ".join(format(row[k], fmt.get(k, "")) for k in keys) + " |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------- benchmarks
def bench_accuracy(
    n_train: int, n_test: int, seeds: int, noise_frac: float
) -> tuple[list[dict], ExactGP, np.ndarray, np.ndarray]:
    """nMSE against noise-free test residuals; training targets get Gaussian noise of
    ``noise_frac`` times each output's standard deviation (0: exact residuals)."""
    Z, Y = cartpole_residuals(n_train + n_test, seed=0)
    Ztr, Ytr, Zte, Yte = Z[:n_train], Y[:n_train], Z[n_train:], Y[n_train:]
    rng = np.random.default_rng(123)
    Ytr = Ytr + noise_frac * Ytr.std(0) * rng.standard_normal(Ytr.shape)
    data = f"noise {noise_frac:.0%}"
    t0 = time.perf_counter()
    gp = ExactGP(n_restarts=1, max_optimization_samples=1000, random_state=0).fit(Ztr, Ytr)
    t_exact = time.perf_counter() - t0
    m_ex = gp.predict(Zte)
    exact_nmse = nmse(m_ex, Yte)
    rows = [
        {
            "data": data,
            "model": "ExactGP",
            "r": 0,
            "nmse": exact_nmse,
            "nmse_vs_exact_mean": 0.0,
            "ratio_to_exact": 1.0,
            "fit_s": t_exact,
        }
    ]
    jobs = [(src, r) for src in ("exact", "ssgp") for r in R_VALUES]
    for src, r in tqdm(jobs, desc=f"accuracy, {data}"):
        errs, devs, fits = [], [], []
        for seed in range(seeds):
            t0 = time.perf_counter()
            model = SSGP(
                r,
                hyperparameters=gp if src == "exact" else "ssgp",
                n_restarts=1,
                max_optimization_samples=1000,
                random_state=seed,
            ).fit(Ztr, Ytr)
            fits.append(time.perf_counter() - t0)
            pred = model.predict(Zte)
            errs.append(nmse(pred, Yte))
            devs.append(float(np.mean(np.mean((pred - m_ex) ** 2, 0) / np.var(Yte, 0))))
        e = float(np.median(errs))
        rows.append(
            {
                "data": data,
                "model": f"SSGP(hyp={src})",
                "r": r,
                "nmse": e,
                "nmse_vs_exact_mean": float(np.median(devs)),
                "ratio_to_exact": e / exact_nmse,
                "fit_s": float(np.median(fits)),
            }
        )
    return rows, gp, Z, Y


def bench_update(gp: ExactGP, Z: np.ndarray, Y: np.ndarray, n_updates: int, repeats: int):
    rows = []
    n0 = 500
    for r in tqdm(R_VALUES, desc="incremental update cost"):
        model = IncrementalSSGP(r, forgetting_factor=0.99, hyperparameters=gp, random_state=0)
        model.fit(Z[:n0], Y[:n0])
        stream_Z, stream_Y = Z[n0:], Y[n0:]

        def run(
            with_weights: bool,
            model=model,
            stream_Z=stream_Z,
            stream_Y=stream_Y,
            pos=[0],  # noqa: B006
        ) -> None:
            for _ in range(n_updates):
                i = pos[0] % len(stream_Z)
                model.update(stream_Z[i : i + 1], stream_Y[i : i + 1])
                if with_weights:
                    _ = model.weights_
                pos[0] += 1

        run(True)  # warm-up
        t_upd = median_time(lambda run=run: run(False), repeats) / n_updates
        t_w = median_time(lambda run=run: run(True), repeats) / n_updates
        # a batch of 20 samples at once (the MPC's rollout of p steps)
        zb, yb = stream_Z[:20], stream_Y[:20]
        t_b = median_time(lambda model=model, zb=zb, yb=yb: model.update(zb, yb), repeats * 5)
        rows.append(
            {
                "r": r,
                "features_2r": 2 * r,
                "update_ms": 1e3 * t_upd,
                "update_plus_weights_ms": 1e3 * t_w,
                "batch20_ms_per_sample": 1e3 * t_b / 20,
            }
        )
    return rows


def bench_exact_refit(gp: ExactGP, n_max: int, repeats: int) -> list[dict]:
    Z, Y = cartpole_residuals(n_max, seed=1)
    rows = []
    sizes = [n for n in (250, 500, 1000, 2000, 3000, 5000) if n <= n_max]
    for n in tqdm(sizes, desc="exact GP refit cost"):
        fixed = ExactGP(optimize=False, hyperparameters=gp.hyperparameters_)
        reps = repeats if n <= 2000 else max(1, repeats // 2)
        t = median_time(lambda fixed=fixed, n=n: fixed.fit(Z[:n], Y[:n]), reps)
        rows.append({"N": n, "refit_s": t})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="small sizes (smoke run)")
    args = ap.parse_args()
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    if args.quick:
        n_train, n_test, seeds, n_upd, reps, n_max = 400, 400, 1, 50, 3, 1000
    else:
        n_train, n_test, seeds, n_upd, reps, n_max = 2000, 2000, 3, 200, 7, 5000

    acc, gp, Z, Y = bench_accuracy(n_train, n_test, seeds, 0.0)
    acc += bench_accuracy(n_train, n_test, seeds, NOISE_FRAC)[0]
    upd = bench_update(gp, Z, Y, n_upd, reps)
    refit = bench_exact_refit(gp, n_max, reps)

    write_csv("accuracy.csv", acc)
    write_csv("update_cost.csv", upd)
    write_csv("exact_refit_cost.csv", refit)

    r = np.array([u["r"] for u in upd], dtype=float)
    t_u = np.array([u["update_ms"] for u in upd])
    k_all = fit_exponent(r, t_u)
    big = r >= 100
    k_big = fit_exponent(r[big], t_u[big])
    k_local = fit_exponent(r[-2:], t_u[-2:])
    n_arr = np.array([x["N"] for x in refit], dtype=float)
    t_r = np.array([x["refit_s"] for x in refit])
    k_refit = (
        fit_exponent(n_arr[n_arr >= 1000], t_r[n_arr >= 1000])
        if (n_arr >= 1000).sum() > 1
        else float("nan")
    )
    u200 = next(u for u in upd if u["r"] == 200)

    def ratio(model: str, noise: str) -> float:
        return next(
            a["ratio_to_exact"]
            for a in acc
            if a["r"] == 200 and a["model"] == model and a["data"] == noise
        )

    r200 = {
        (m, d): ratio(m, d)
        for m in ("SSGP(hyp=exact)", "SSGP(hyp=ssgp)")
        for d in ("noise 0%", f"noise {NOISE_FRAC:.0%}")
    }
    target_time = u200["update_plus_weights_ms"] < 1.0

    fmt = {
        "nmse": ".4g",
        "nmse_vs_exact_mean": ".3g",
        "ratio_to_exact": ".3f",
        "fit_s": ".2f",
        "update_ms": ".3f",
        "update_plus_weights_ms": ".3f",
        "batch20_ms_per_sample": ".3f",
        "refit_s": ".3f",
    }
    summary = [
        f"- fitted exponent of update time vs r: {k_all:.2f} (all r), {k_big:.2f} (r >= 100)",
        f"- exponent of exact-GP refit time vs N (N >= 1000): {k_refit:.2f}",
        f"- local exponent of update time between r = 200 and r = 400: {k_local:.2f}",
        f"- target update < 1 ms/sample at r = 200 (2 outputs, incl. weight solve): "
        f"{u200['update_plus_weights_ms']:.3f} ms ({u200['update_ms']:.3f} ms without the "
        f"weight solve; {u200['batch20_ms_per_sample']:.3f} ms/sample in batches of 20) -> "
        f"{'MET' if target_time else 'NOT met'}",
        *(
            f"- target SSGP nMSE <= 1.2x exact at r = 200, {m}, {d}: {v:.3g}x -> "
            f"{'MET' if v <= 1.2 else 'NOT met'}"
            for (m, d), v in r200.items()
        ),
    ]
    md = [
        "# GP residual learners: cart-pole benchmark",
        "",
        "Generated by `python benchmarks/studies/bench_learners.py"
        f"{' --quick' if args.quick else ''}`"
        f" on {platform.processor() or platform.machine()}, {os.cpu_count()} cores,"
        f" OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}, Python {platform.python_version()},"
        f" numpy {np.__version__}.",
        "",
        f"Data: online cart-pole residual accelerations, N_train = {n_train}, "
        f"N_test = {n_test}, d_in = 5, d_out = 2; medians over {seeds} frequency seed(s), "
        f"{reps} timing repeats. Accuracy is measured against noise-free test residuals; the "
        f"second run trains on targets with Gaussian noise of {NOISE_FRAC:.0%} of each "
        f"output's std. Load average at the end: {os.getloadavg()[0]:.1f}.",
        "",
        "## Summary",
        *summary,
        "",
        "## Accuracy (nMSE on held-out residuals; lower is better)",
        md_table(acc, fmt),
        "",
        "## IncrementalSSGP update cost (both outputs, lambda = 0.99, one sample per call)",
        md_table(upd, fmt),
        "",
        "## Exact GP refit cost (fixed hyperparameters; both outputs)",
        md_table(refit, fmt),
        "",
    ]
    (OUT_DIR / "README.md").write_text("\n".join(md))
    print("\n".join(md))


if __name__ == "__main__":
    main()
