"""Gonio at scale, on Dask (``dask.distributed``): reprocess an archive of run
files and sweep microgeometry simulations over a cluster — a ``LocalCluster`` on
a laptop or lab server, a scheduler's address, Slurm or PBS through dask-jobqueue,
Kubernetes.

- ``reprocess(runs, out_dir)``: one task a run, running the command line's own
  ``reduce``, ``check``, ``fit`` and ``report`` in the worker; a row a run.
- ``micro_sweep(surfaces, params)``: ``gonio micro`` tables of every surface under
  every parameter set, each incident direction a task, split into chunks of rays
  merged exactly.

Outputs are named by the input's content and the options, written whole or not at
all, and a rerun skips what is done; a task whose worker dies is retried by Dask
and writes the same bytes. ``python -m gonio.batch`` is the command line of both.
"""

from __future__ import annotations

from gonio.batch._common import client_for
from gonio.batch._reprocess import STEPS, find_runs, reprocess
from gonio.batch._sweep import (
    CHUNK_RAYS,
    SEGMENT_RAYS,
    SweepError,
    incidents,
    load_sweep,
    micro_sweep,
)

__all__ = [
    "CHUNK_RAYS",
    "SEGMENT_RAYS",
    "STEPS",
    "SweepError",
    "client_for",
    "find_runs",
    "incidents",
    "load_sweep",
    "micro_sweep",
    "reprocess",
]
