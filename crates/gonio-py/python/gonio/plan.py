"""Measurement plans against an instrument, as ``gonio plan``: what a plan
measures, what it cannot and why, how long it takes (``check``); and an adaptive
plan measured against uniform plans of the same size (``compare``)."""

from __future__ import annotations

import json
import os
from typing import Any

import pandas as pd

from gonio import _native
from gonio._progress import ProgressArg, Reporter


def check(
    plan: str | os.PathLike[str],
    instrument: str | os.PathLike[str],
    *,
    like: Any = None,
    sim: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Maps every pair of ``plan`` through ``instrument``'s kinematics, as ``gonio
    plan check`` does: returns its ``--json`` dict — the pairs, those accepted,
    those left out with the reason (``rejected``, ``rejected_by_reason``), the
    steps and the time estimate (``estimate``: start-up, motion, band changes,
    detector, total, in seconds), and for adaptive or targeted plans their own estimates.
    For a plan with a ``[reading]`` target, ``like`` (a ``Run`` or run file) gives
    the signals to expect; ``sim`` is the simulator config of a simulated
    instrument. A bad plan or config raises ``ConfigError`` naming the file."""
    words = ["plan", "check", os.fspath(plan), "--instrument", os.fspath(instrument)]
    if like is not None:
        words += ["--like", like.path if hasattr(like, "path") else os.fspath(like)]
    if sim is not None:
        words += ["--sim", os.fspath(sim)]
    return json.loads(_native.plan_check(words))


def compare(
    plan: str | os.PathLike[str],
    instrument: str | os.PathLike[str],
    *,
    sim: str | os.PathLike[str] | None = None,
    seed: int | None = None,
    sample: str | os.PathLike[str] | None = None,
    budget: int | None = None,
    grid: tuple[float, float] = (2.0, 2.0),
    keep: str | os.PathLike[str] | None = None,
    progress: ProgressArg = True,
) -> pd.DataFrame:
    """Measures the adaptive ``plan`` and two uniform plans of the same number of
    points (``lattice``, ``grid``) on the simulated ``instrument``, and judges each
    reconstruction against the simulated sample, as ``gonio plan compare`` does
    (docs/adaptive.md). ``sample`` (a model file) replaces the simulator's sample,
    ``budget`` the plan's points, ``grid`` = (dθ, dφ) degrees is the outgoing grid
    the error is taken on; ``keep`` (a directory) keeps the three run files.

    Returns one row a plan: ``plan``, ``points``, ``steps``, ``physical_s``,
    ``error`` (cosine-weighted relative RMS against the truth),
    ``error_over_adaptive``, ``file``; ``df.attrs["compare"]`` holds the
    ``--json`` dict. ``progress`` as for ``acquire`` (a bar a run); Ctrl-C stops
    the run being measured safely."""
    words = ["plan", "compare", os.fspath(plan), "--instrument", os.fspath(instrument)]
    if sim is not None:
        words += ["--sim", os.fspath(sim)]
    if seed is not None:
        words += ["--seed", str(int(seed))]
    if sample is not None:
        words += ["--sample", os.fspath(sample)]
    if budget is not None:
        words += ["--budget", str(int(budget))]
    words += ["--grid", f"{float(grid[0])!r},{float(grid[1])!r}"]
    if keep is not None:
        words += ["--keep", os.fspath(keep)]
    with Reporter(progress) as reporter:
        result = json.loads(
            _native.plan_compare(words, report=reporter if reporter.active else None)
        )
    df = pd.DataFrame(result["runs"])
    df.attrs["compare"] = result
    return df


__all__ = ["check", "compare"]
