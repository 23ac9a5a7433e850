"""Long calls release the interpreter's lock and Ctrl-C interrupts them. (What that
buys in time, two fits side by side on two cores, is a benchmark:
``benches/threads.py``.)"""

from __future__ import annotations

import _thread
import threading
import time

import numpy as np
import pandas as pd
import pytest

import gonio
from conftest import CONFIG

PAINT = CONFIG / "models" / "blue-paint-550nm.toml"


@pytest.fixture(scope="module")
def dense() -> pd.DataFrame:
    """The blue paint sampled on 400 000 pairs with 1% noise (seeded)."""
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


def test_the_lock_is_released_during_a_fit(dense):
    done = threading.Event()
    worker = threading.Thread(target=lambda: (fit_once(dense), done.set()))
    count = 0
    worker.start()
    while not done.is_set():
        count += 1
    worker.join()
    # Had the fit held the lock, this loop could not have run while it did.
    assert count > 10_000


def test_the_same_fit_on_any_number_of_threads(dense):
    a = gonio.fit(dense, lobes=2, threads=1)
    b = gonio.fit(dense, lobes=2)
    assert a.model_file == b.model_file


def test_ctrl_c_interrupts_a_long_simulation(ctrl_c_raises):
    """A trace of minutes stops within a round of blocks of the interrupt."""
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        gonio.micro.simulate(CONFIG / "micro-gaussian-gold.toml", rays=5_000_000)
    assert time.perf_counter() - t0 < 2.0
    # The process carries on: the next call runs normally.
    df = gonio.micro.simulate(CONFIG / "micro-gaussian-gold.toml", grid=(30, 90), rays=200)
    assert len(df) > 0
