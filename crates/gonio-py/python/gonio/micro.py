"""The virtual gonioreflectometer (Westin et al. 1992): a BRDF table predicted
by tracing rays through a surface file's microgeometry, as ``gonio micro``."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence

import numpy as np
import pandas as pd

from gonio import _native
from gonio._frame import to_frame
from gonio._progress import ProgressArg, Reporter


def _axis(theta_i: float | Sequence[float]) -> tuple[float, float, int]:
    """(first, step, count) of evenly spaced incident polar angles."""
    t = np.atleast_1d(np.asarray(theta_i, dtype=np.float64))
    if t.ndim != 1 or t.size == 0:
        raise ValueError("theta_i: one angle or a non-empty list of angles (degrees)")
    if t.size == 1:
        return float(t[0]), 1.0, 1
    steps = np.diff(t)
    if not (steps[0] > 0 and np.allclose(steps, steps[0], rtol=0, atol=1e-9)):
        raise ValueError("theta_i: the angles must be evenly spaced and increasing")
    return float(t[0]), float(steps[0]), int(t.size)


def simulate(
    surface: str | os.PathLike[str],
    theta_i: float | Sequence[float] | None = None,
    *,
    grid: tuple[float, float] = (10.0, 15.0),
    isotropic: bool = False,
    rays: int = 100_000,
    seed: int = 1,
    max_bounces: int = 100,
    threads: int | None = None,
    progress: ProgressArg = True,
) -> pd.DataFrame:
    """f_r on a hemisphere grid of ``grid`` = (dθ, dφ) degrees, traced with
    ``rays`` rays per incident direction (deterministic in ``seed`` on any number
    of threads): the table ``gonio micro`` writes, with the Monte Carlo standard
    error of every bin in the sigma columns. ``theta_i`` (evenly spaced degrees)
    replaces the grid's incident polar angles. ``df.attrs["micro"]`` holds the
    ray statistics and albedos (``--json``). ``progress``: in a notebook, a tqdm
    bar of the incident directions traced; or a callable given a
    ``gonio.Progress`` as each is done. With either, the directions are traced
    one to a thread (the same table, bit for bit)."""
    words = ["micro", os.fspath(surface), "--out", os.devnull]
    words += ["--grid", f"{float(grid[0])!r},{float(grid[1])!r}"]
    words += ["--rays", str(int(rays)), "--seed", str(int(seed))]
    words += ["--max-bounces", str(int(max_bounces))]
    if isotropic:
        words.append("--isotropic")
    axis = None if theta_i is None else _axis(theta_i)
    with Reporter(progress) as reporter:
        cols, sidecar, report = _native.micro(
            words, axis, threads=threads, report=reporter if reporter.active else None
        )
    df = to_frame(cols, sidecar)
    df.attrs["micro"] = json.loads(report)
    return df


__all__ = ["simulate"]
