"""Benchmark: ``gonio.fit`` against ``scipy.optimize.least_squares`` on the same data.

Usage (from the repository root, after ``scripts/pyenv``)::

    target/pyenv/bin/python crates/gonio-py/benches/fit.py \
        [--lobes 2] [--repeats 7] [--seed 1] [--workdir target/bench-fit] [--process-runs 10]

The data: a simulated acquisition (``config/instrument-sim.toml`` with
``config/plan-hemisphere.toml``, seeded), reduced by ``Run.reduce()``: one channel,
618 samples. The model: ``--lobes`` isotropic generalized cosine lobes (Cx = Cy) plus a
Lambertian term, f_r = rho_d/π + Σ_j max(0, C_j (x_i x_o + y_i y_o) + Cz_j z_i z_o)^n_j.
The objective: gonio's ``cosine`` objective (asked for explicitly; on this data gonio's
default would be χ², every sample having σ > 0), as ``crates/gonio-fit/src/data.rs``
defines it: Σ ((f_model − f_data) cos θi cos θo)², the cosines those of the directions
``gonio_core`` builds from the degrees, over the samples with θi, θo < 90°.

Both fits are scored by the same numpy code (``cost`` below), which is first checked
against the RMS figures gonio reports for its own fit. Then: in-process wall time
(median of ``--repeats``), and whole processes as a user runs them (reading the
DataFrame from a CSV written once), with hyperfine if installed, else a loop of
subprocesses.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy
from scipy.optimize import least_squares

import gonio

ROOT = Path(__file__).resolve().parents[3]


def sin_cos_deg(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``gonio_core::sin_cos_deg``: quadrant-reduced sine and cosine of degrees."""
    r = np.mod(x, 360.0)
    q = np.floor(r / 90.0)
    a = np.deg2rad(r - 90.0 * q)
    s, c = np.sin(a), np.cos(a)
    qi = q.astype(np.int8)
    return (
        np.choose(qi, (s, c, -s, -c), mode="clip"),
        np.choose(qi, (c, -s, -c, s), mode="clip"),
    )


class Data:
    """The fit's view of a samples DataFrame: products of direction components, the
    values and the cosine objective's weights, over the pairs below the horizon."""

    def __init__(self, df: pd.DataFrame) -> None:
        keep = (df["theta_i_deg"] < 90.0) & (df["theta_o_deg"] < 90.0)
        d = df[keep]
        sti, cti = sin_cos_deg(d["theta_i_deg"].to_numpy())
        spi, cpi = sin_cos_deg(d["phi_i_deg"].to_numpy())
        sto, cto = sin_cos_deg(d["theta_o_deg"].to_numpy())
        spo, cpo = sin_cos_deg(d["phi_o_deg"].to_numpy())
        self.px = (sti * cpi) * (sto * cpo)
        self.py = (sti * spi) * (sto * spo)
        self.pz = cti * cto
        self.w = cti * cto  # Metric::Lafortune: cos θi cos θo
        self.y = d["f_r_per_sr"].to_numpy()


def unpack(x: np.ndarray) -> tuple[float, list[tuple[float, float, float]]]:
    """x = [rho_d, C_1, Cz_1, n_1, C_2, Cz_2, n_2, …] (isotropic lobes)."""
    return float(x[0]), [
        tuple(map(float, x[1 + 3 * j : 4 + 3 * j])) for j in range((len(x) - 1) // 3)
    ]


def model_f(x: np.ndarray, d: Data) -> np.ndarray:
    rho, lobes = unpack(x)
    f = np.zeros_like(d.y)
    for c, cz, n in lobes:
        dot = c * d.px + c * d.py + cz * d.pz
        f += np.where(dot > 0.0, np.power(np.maximum(dot, 0.0), n), 0.0)
    return f + rho * 2.0 / (2.0 * np.pi)


def residuals(x: np.ndarray, d: Data) -> np.ndarray:
    return d.w * (model_f(x, d) - d.y)


def jacobian(x: np.ndarray, d: Data) -> np.ndarray:
    """Analytic ∂r/∂x of ``residuals``."""
    _, lobes = unpack(x)
    jac = np.empty((d.y.size, x.size))
    jac[:, 0] = d.w / np.pi
    pxy = d.px + d.py
    for j, (c, cz, n) in enumerate(lobes):
        dot = c * pxy + cz * d.pz
        pos = dot > 0.0
        safe = np.where(pos, dot, 1.0)
        lobe = np.where(pos, np.power(safe, n), 0.0)
        dn = np.where(pos, n * np.power(safe, n - 1.0), 0.0)
        jac[:, 1 + 3 * j] = d.w * dn * pxy
        jac[:, 2 + 3 * j] = d.w * dn * d.pz
        jac[:, 3 + 3 * j] = d.w * lobe * np.log(safe)
    return jac


def cost(x: np.ndarray, d: Data) -> float:
    """Σ ((f_model − f_data) cos θi cos θo)²: the cosine objective, no ½."""
    r = residuals(x, d)
    return float(r @ r)


def gonio_x(result: gonio.FitResult) -> np.ndarray:
    p = result.json["fit"]["channels"][0]["params"]
    assert p["m"] == 0.0, "expected a Lambertian diffuse term"
    x = [p["rho_d"]]
    for cx, cy, cz, n in p["lobes"]:
        assert cx == cy, "expected isotropic lobes"
        x += [cx, cz, n]
    return np.array(x)


def simple_start(d: Data, lobes: int) -> np.ndarray:
    """What one would try first: the Lambert floor π·min(f), then lobes about the
    mirror direction (C = −1, Cz = 1, peak 1/sr), from narrow to broad."""
    x = [np.pi * float(d.y.min())]
    for j in range(lobes):
        x += [-1.0, 1.0, [20.0, 3.0, 8.0][j % 3]]
    return np.array(x)


def bounds(lobes: int) -> tuple[list[float], list[float]]:
    lo, hi = [0.0], [np.inf]
    for _ in range(lobes):
        lo += [-np.inf, -np.inf, 0.0]
        hi += [np.inf, np.inf, 1000.0]
    return lo, hi


def scipy_fit(d: Data, x0: np.ndarray, jac: str) -> least_squares:
    return least_squares(
        residuals,
        x0,
        jac=jacobian if jac == "analytic" else "2-point",
        bounds=bounds((x0.size - 1) // 3),
        method="trf",
        args=(d,),
        x_scale="jac",
        max_nfev=10_000,
    )


def median_time(fn, repeats: int) -> tuple[float, float, float, object]:
    out = fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), max(times), out


GONIO_SCRIPT = """\
import gonio, pandas
df = pandas.read_csv({csv!r})
r = gonio.fit(df, lobes={lobes}, objective="cosine")
print(r.json["fit"]["channels"][0]["params"])
"""

SCIPY_SCRIPT = """\
import numpy as np, pandas
from scipy.optimize import least_squares
df = pandas.read_csv({csv!r})
d2r = np.pi / 180
ti, pi_, to, po = (df[c].to_numpy() * d2r for c in
                   ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"))
y = df["f_r_per_sr"].to_numpy()
pxy = np.sin(ti) * np.sin(to) * np.cos(pi_ - po)
pz = np.cos(ti) * np.cos(to)
w = pz
def res(x):
    f = x[0] / np.pi
    for c, cz, n in x[1:].reshape(-1, 3):
        dot = c * pxy + cz * pz
        f = f + np.where(dot > 0, np.maximum(dot, 0) ** n, 0)
    return w * (f - y)
x0 = np.array({x0})
lo = [0] + [-np.inf, -np.inf, 0] * {lobes}
hi = [np.inf] + [np.inf, np.inf, 1000] * {lobes}
r = least_squares(res, x0, bounds=(lo, hi), x_scale="jac", max_nfev=10000)
print(r.x)
"""


def time_processes(workdir: Path, csv: Path, lobes: int, x0: np.ndarray, runs: int) -> list[dict]:
    """Whole processes: the two user scripts and the imports alone."""
    py = sys.executable
    scripts = {
        "gonio_fit.py": GONIO_SCRIPT.format(csv=str(csv), lobes=lobes),
        "scipy_fit.py": SCIPY_SCRIPT.format(csv=str(csv), lobes=lobes, x0=list(map(float, x0))),
    }
    for name, text in scripts.items():
        (workdir / name).write_text(text)
    commands = [
        ("gonio.fit script", f"{py} {workdir / 'gonio_fit.py'}"),
        ("scipy least_squares script", f"{py} {workdir / 'scipy_fit.py'}"),
        ("reference: import gonio, pandas", f"{py} -c 'import gonio, pandas'"),
        (
            "reference: import pandas, scipy.optimize",
            f"{py} -c 'import numpy, pandas, scipy.optimize'",
        ),
        ("reference: python -c pass", f"{py} -c pass"),
    ]
    for _, cmd in commands[:2]:
        subprocess.run(cmd, shell=True, check=True, capture_output=True)
    out = []
    if shutil.which("hyperfine"):
        export = workdir / "hyperfine.json"
        subprocess.run(
            [
                "hyperfine",
                "-N",
                "--warmup",
                "2",
                "--runs",
                str(runs),
                "--export-json",
                str(export),
            ]
            + [c for _, c in commands],
            check=True,
            capture_output=True,
        )
        for (name, cmd), r in zip(commands, json.loads(export.read_text())["results"]):
            out.append(
                {
                    "what": name,
                    "command": cmd,
                    "median_s": r["median"],
                    "min_s": r["min"],
                    "max_s": r["max"],
                }
            )
        tool = "hyperfine -N"
    else:
        for name, cmd in commands:
            times = []
            for _ in range(runs):
                t0 = time.perf_counter()
                subprocess.run(cmd, shell=True, check=True, capture_output=True)
                times.append(time.perf_counter() - t0)
            out.append(
                {
                    "what": name,
                    "command": cmd,
                    "median_s": statistics.median(times),
                    "min_s": min(times),
                    "max_s": max(times),
                }
            )
        tool = "subprocess loop"
    for r in out:
        r["tool"] = tool
    return out


def fmt_params(x: np.ndarray) -> str:
    rho, lobes = unpack(x)
    parts = [f"rho_d={rho:.5f}"] + [f"(C={c:.4f}, Cz={cz:.4f}, n={n:.2f})" for c, cz, n in lobes]
    return " ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lobes", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--workdir", default=str(ROOT / "target" / "bench-fit"))
    ap.add_argument("--process-runs", type=int, default=10, help="0: skip the process timing")
    args = ap.parse_args()

    workdir = Path(args.workdir).resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        run = gonio.acquire(
            ROOT / "config" / "instrument-sim.toml",
            ROOT / "config" / "plan-hemisphere.toml",
            Path(tmp) / "run.gonio",
            seed=args.seed,
            progress=False,
        )
        df = run.reduce()
    csv = workdir / "samples.csv"
    df.to_csv(csv, index=False)
    d = Data(df)
    lobes = args.lobes

    default_objective = gonio.fit(df, lobes=lobes).json["fit"]["objective"]
    res = gonio.fit(df, lobes=lobes, objective="cosine")
    fit_json = res.json["fit"]
    assert fit_json["objective"]["name"] == "cosine", fit_json["objective"]
    ch = fit_json["channels"][0]
    xg = gonio_x(res)

    # Our scoring against gonio's own figures for its fit: the unweighted RMS and the
    # weighted residuals' RMS relative to the weighted data's.
    rms = float(np.sqrt(np.mean((model_f(xg, d) - d.y) ** 2)))
    rel_rms = float(np.sqrt(cost(xg, d) / np.sum((d.w * d.y) ** 2)))
    assert fit_json["samples"] == d.y.size, (fit_json["samples"], d.y.size)
    assert abs(rms / ch["rms"] - 1) < 1e-9, (rms, ch["rms"])
    assert abs(rel_rms / ch["relative_rms"] - 1) < 1e-9, (rel_rms, ch["relative_rms"])
    # The CSV round trip (no attrs) fits to the same parameters.
    xg_csv = gonio_x(gonio.fit(pd.read_csv(csv), lobes=lobes, objective="cosine"))
    csv_same = bool(np.allclose(xg, xg_csv, rtol=1e-9, atol=0))
    # The analytic Jacobian against central differences, at the simple start.
    x0 = simple_start(d, lobes)
    num = np.empty((d.y.size, x0.size))
    for k in range(x0.size):
        h = 1e-6 * max(1.0, abs(x0[k]))
        e = np.zeros_like(x0)
        e[k] = h
        num[:, k] = (residuals(x0 + e, d) - residuals(x0 - e, d)) / (2 * h)
    jac_err = float(np.abs(num - jacobian(x0, d)).max() / np.abs(num).max())
    assert jac_err < 1e-6, jac_err

    rows = []

    def add(name, fn, x_of):
        med, lo, hi, out = median_time(fn, args.repeats)
        x = x_of(out)
        extra = {"nfev": int(out.nfev), "status": int(out.status)} if hasattr(out, "nfev") else {}
        rows.append(
            {
                "what": name,
                "median_s": med,
                "min_s": lo,
                "max_s": hi,
                "cost": cost(x, d),
                "params": x.tolist(),
                **extra,
            }
        )

    add(
        "gonio.fit, default threads",
        lambda: gonio.fit(df, lobes=lobes, objective="cosine"),
        gonio_x,
    )
    add(
        "gonio.fit, threads=1",
        lambda: gonio.fit(df, lobes=lobes, objective="cosine", threads=1),
        gonio_x,
    )
    for jac in ("2-point", "analytic"):
        add(
            f"scipy trf, jac {jac}, simple start",
            lambda jac=jac: scipy_fit(d, x0, jac),
            lambda r: r.x,
        )
    add(
        "scipy trf, jac analytic, from gonio's answer",
        lambda: scipy_fit(d, xg, "analytic"),
        lambda r: r.x,
    )

    best = min(r["cost"] for r in rows)
    print(
        f"data: {d.y.size} samples (simulated run, seed {args.seed}); model: {lobes} isotropic "
        f"lobe(s) + Lambert; objective cosine (gonio's default here: "
        f"{default_objective['name']}, {default_objective['chosen']})"
    )
    print(
        f"checks: our RMS of gonio's fit {rms:.6g} = its own {ch['rms']:.6g}; relative RMS "
        f"{rel_rms:.6g} = {ch['relative_rms']:.6g}; CSV round trip same params: {csv_same}; "
        f"analytic Jacobian vs central differences {jac_err:.1e}"
    )
    print(f"simple start for scipy: {fmt_params(x0)}, cost {cost(x0, d):.6g}")
    print(f"\nin-process, median of {args.repeats} (after one warm-up), {os.cpu_count()} CPUs")
    print(f"{'what':46s} {'median':>9s} {'range':>19s} {'cost':>12s} {'/best-1':>9s} nfev")
    for r in rows:
        print(
            f"{r['what']:46s} {r['median_s'] * 1e3:7.1f}ms {r['min_s'] * 1e3:8.1f}–"
            f"{r['max_s'] * 1e3:6.1f} ms {r['cost']:12.6e} {r['cost'] / best - 1:9.2e} "
            f"{r.get('nfev', '')}"
        )
    for r in rows:
        print(f"  {r['what']:46s} {fmt_params(np.array(r['params']))}")

    procs = []
    if args.process_runs > 0:
        procs = time_processes(workdir, csv, lobes, x0, args.process_runs)
        print(f"\nwhole processes ({procs[0]['tool']}, {args.process_runs} runs, 2 warm-up)")
        for r in procs:
            print(
                f"{r['what']:46s} {r['median_s'] * 1e3:7.0f}ms "
                f"{r['min_s'] * 1e3:6.0f}–{r['max_s'] * 1e3:5.0f} ms"
            )
        print(f"  scripts in {workdir}")

    print(
        json.dumps(
            {
                "bench": "gonio-py fit",
                "samples": int(d.y.size),
                "lobes": lobes,
                "seed": args.seed,
                "repeats": args.repeats,
                "cpus": os.cpu_count(),
                "scipy": scipy.__version__,
                "numpy": np.__version__,
                "default_objective": default_objective["name"],
                "gonio_reported_seconds": fit_json["seconds"],
                "start": x0.tolist(),
                "in_process": rows,
                "processes": procs,
            }
        )
    )


if __name__ == "__main__":
    main()
