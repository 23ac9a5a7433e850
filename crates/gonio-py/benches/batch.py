"""Benchmark: ``gonio.batch`` on 1 and 2 Dask workers of this machine, beside what a
user would otherwise run (the ``gonio`` command in a serial loop, or one ``gonio
micro`` process using every core).

Usage (from the repository root, after ``scripts/pyenv``)::

    target/pyenv/bin/python crates/gonio-py/benches/batch.py [--runs 20] \
        [--workdir target/bench-batch] [--skip-report]

What is timed, whole processes as a user times them (cluster start-up included):

1. reprocess: ``python -m gonio.batch reprocess RUNS --out DIR --workers N`` for
   ``--runs`` simulated hemisphere runs (seeds 1..N; all four steps), N = 1 and 2,
   each into a fresh directory; beside it the serial loop of ``gonio reduce``,
   ``check``, ``fit`` and ``report`` per run.
2. micro sweep: ``python -m gonio.batch micro SWEEP.toml`` (the Gaussian gold
   surface, 4 incident angles × ``--sweep-rays`` (2²⁵) rays, chunks of
   ``--chunk-rays`` (2²²): 32 tasks) on 1 and 2 workers; beside it ``gonio micro``
   with the same seed and rays in one process (both cores), whose table must be the
   same bytes.
3. Dask's own cost per task: 400 no-op tasks through a 1-worker LocalCluster
   (client round trip, scheduling, serialisation), beside the tasks' own times.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
GONIO = ROOT / "target" / "release" / "gonio"
PY = [sys.executable, "-m", "gonio.batch"]


def timed(argv: list[str], **kw: object) -> float:
    t = time.perf_counter()
    subprocess.run([str(a) for a in argv], check=True, capture_output=True, **kw)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--workdir", default=str(ROOT / "target" / "bench-batch"))
    ap.add_argument("--skip-report", action="store_true", help="reduce, check, fit only")
    ap.add_argument("--sweep-rays", type=int, default=1 << 25, help="rays an incident angle")
    ap.add_argument("--chunk-rays", type=int, default=1 << 22)
    a = ap.parse_args()
    subprocess.run(["cargo", "build", "--release", "-p", "gonio-cli"], cwd=ROOT, check=True)
    work = Path(a.workdir)
    shutil.rmtree(work, ignore_errors=True)
    runs_dir = work / "runs"
    runs_dir.mkdir(parents=True)
    inst, plan = ROOT / "config" / "instrument-sim.toml", ROOT / "config" / "plan-hemisphere.toml"
    runs = []
    for seed in range(1, a.runs + 1):
        p = runs_dir / f"run{seed:03d}.gonio"
        subprocess.run(
            [
                GONIO,
                "acquire",
                "--instrument",
                inst,
                "--plan",
                plan,
                "--out",
                p,
                "--seed",
                str(seed),
            ],
            check=True,
            capture_output=True,
        )
        runs.append(p)
    steps = "reduce,check,fit" if a.skip_report else "reduce,check,fit,report"
    out: dict[str, object] = {"runs": a.runs, "steps": steps, "cores": os.cpu_count()}

    # 1. The serial loop a user would otherwise write.
    t = time.perf_counter()
    for p in runs:
        d = work / "loop" / p.stem
        d.mkdir(parents=True)
        subprocess.run(
            [GONIO, "reduce", p, "--out", d / "reduced.csv", "--json"],
            check=True,
            capture_output=True,
        )
        subprocess.run([GONIO, "check", p, "--json"], check=True, capture_output=True)
        subprocess.run(
            [GONIO, "fit", p, "--out", d / "model.toml", "--json"], check=True, capture_output=True
        )
        if not a.skip_report:
            subprocess.run(
                [GONIO, "report", p, "--out", d, "--json"], check=True, capture_output=True
            )
    out["reprocess_cli_loop_s"] = time.perf_counter() - t
    for n in (1, 2):
        d = work / f"re{n}"
        out[f"reprocess_{n}w_s"] = timed(
            [*PY, "reprocess", runs_dir, "--out", d, "--workers", n, "--steps", steps]
        )
    import pandas as pd

    rows = pd.read_csv(work / "re1" / "reprocess.csv")
    out["reprocess_task_median_s"] = float(rows["seconds"].median())
    out["reprocess_identical_1w_2w"] = all(
        (work / "re1" / k / f).read_bytes() == (work / "re2" / k / f).read_bytes()
        for k in rows["key"]
        for f in os.listdir(work / "re1" / k)
    )
    out["reprocess_efficiency_2w"] = out["reprocess_1w_s"] / (2 * out["reprocess_2w_s"])

    # 2. The micro sweep: 4 incident angles (the grid 22.5°, 90°: θi 11.25° … 78.75°),
    # which `gonio micro` also traces, in one process on both cores.
    sweep = work / "sweep.toml"
    rays = a.sweep_rays
    gold = ROOT / "config" / "micro-gaussian-gold.toml"
    sweep.write_text(
        f'surfaces = ["{gold}"]\nseed = 0\n'
        f"chunk_rays = {a.chunk_rays}\n\n[[params]]\nrays = {rays}\nseed = 11\n"
        "grid = [22.5, 90]\nisotropic = true\n"
    )
    out["sweep_rays"] = 4 * rays
    for n in (1, 2):
        out[f"sweep_{n}w_s"] = timed(
            [*PY, "micro", sweep, "--out", work / f"sw{n}", "--workers", n]
        )
    out["sweep_efficiency_2w"] = out["sweep_1w_s"] / (2 * out["sweep_2w_s"])
    ref = work / "micro-cli.csv"
    out["micro_cli_s"] = timed(
        [
            GONIO,
            "micro",
            gold,
            "--rays",
            rays,
            "--seed",
            11,
            "--grid",
            "22.5,90",
            "--isotropic",
            "--out",
            ref,
        ]
    )
    tables = [p for p in (work / "sw2").glob("*.csv") if p.name != "sweep.csv"]
    out["micro_sweep_equals_cli"] = [p.read_bytes() == ref.read_bytes() for p in tables] == [True]
    tasks = json.loads(next((work / "sw1").glob("*.json")).read_text())
    out["sweep_tasks"] = 4 * -(-rays // a.chunk_rays)
    out["sweep_rays_traced"] = tasks["rays"]

    # 3. Dask's cost per task.
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as c,
        Client(c) as cl,
    ):
        cl.submit(int, 0).result()
        samples = []
        for _ in range(3):
            t = time.perf_counter()
            cl.gather(cl.map(lambda i: i, range(400), pure=False))
            samples.append((time.perf_counter() - t) / 400)
        out["dask_task_overhead_ms"] = 1e3 * statistics.median(samples)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
