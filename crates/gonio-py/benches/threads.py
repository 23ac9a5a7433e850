"""Benchmark: two one-thread ``gonio.fit`` calls side by side, beside one alone.

Usage (from the repository root, after ``scripts/pyenv``)::

    target/pyenv/bin/python crates/gonio-py/benches/threads.py [--tries 5]

A fit releases the interpreter's lock (``tests/test_threads.py`` checks that the lock
is free while one runs); on two cores, two fits in two threads should then take about
the time of one (ratio 1.0), and twice as long (2.0) if they were serialised. The data:
the blue paint (``config/models/blue-paint-550nm.toml``) on 400 896 pairs with 1 %
seeded noise, fitted with 3 lobes on one thread each. Best of ``--tries`` for both, so
that a moment of load elsewhere on a shared machine slows neither figure.
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd

import gonio

ROOT = Path(__file__).resolve().parents[3]
PAINT = ROOT / "config" / "models" / "blue-paint-550nm.toml"


def dense() -> pd.DataFrame:
    """The blue paint sampled on 400 896 pairs with 1 % noise (seed 1)."""
    m = gonio.load_model(PAINT)
    ti, to, po = (
        a.ravel()
        for a in np.meshgrid(
            np.arange(0.0, 80.0, 1.25),
            np.arange(1.0, 88.0, 1.0),
            np.arange(0.0, 360.0, 5.0),
            indexing="ij",
        )
    )
    f = m.eval(ti, 0.0, to, po)[:, 0]
    noise = 1.0 + 0.01 * np.random.default_rng(1).standard_normal(f.size)
    return pd.DataFrame(
        {
            "theta_i_deg": ti,
            "phi_i_deg": 0.0,
            "theta_o_deg": to,
            "phi_o_deg": po,
            "f_r_550nm_per_sr": f * noise,
            "sigma_550nm_per_sr": 0.01 * f,
        }
    )


def fit_once(df: pd.DataFrame) -> float:
    t0 = time.perf_counter()
    gonio.fit(df, lobes=3, threads=1)
    return time.perf_counter() - t0


def side_by_side(df: pd.DataFrame) -> float:
    t0 = time.perf_counter()
    threads = [threading.Thread(target=fit_once, args=(df,)) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tries", type=int, default=5)
    a = p.parse_args()
    df = dense()
    one = min(fit_once(df) for _ in range(a.tries))
    both = min(side_by_side(df) for _ in range(a.tries))
    print(json.dumps({"one_s": one, "two_side_by_side_s": both, "ratio": both / one}))


if __name__ == "__main__":
    main()
