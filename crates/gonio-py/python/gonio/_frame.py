"""Columns across the boundary: the native module's columns as DataFrames, and
DataFrames, runs, models and paths as the inputs the native module takes."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np
import pandas as pd

from gonio import _native

#: The key of ``DataFrame.attrs`` under which Gonio keeps a frame's sidecar: what
#: the CSV's ``PATH.json`` holds (format, channels, isotropy, a table's grid).
SIDECAR = "gonio"


def to_frame(columns: list[tuple[str, Any]], sidecar: str | None = None) -> pd.DataFrame:
    """A DataFrame of the native module's ``[(name, ndarray)]`` columns, without a
    copy per element; ``sidecar`` (JSON text) goes to ``df.attrs["gonio"]``."""
    df = pd.DataFrame(dict(columns), copy=False)
    if sidecar is not None:
        df.attrs[SIDECAR] = json.loads(sidecar)
    return df


def to_input(data: Any) -> Any:
    """What the native module takes for ``data``: a path (``str``), a native model,
    or a DataFrame's columns as ``(columns, isotropic, label)``. A ``Run`` or a
    ``Model`` says what it is through its ``_gonio_input`` method, so that this
    module, which they import, imports neither of them."""
    own = getattr(data, "_gonio_input", None)
    if callable(own):
        return own()
    if isinstance(data, pd.DataFrame):
        meta = data.attrs.get(SIDECAR, {})
        cols = []
        for name in data.columns:
            values = np.ascontiguousarray(data[name].to_numpy(dtype=np.float64, na_value=np.nan))
            cols.append((str(name), values))
        return (cols, bool(meta.get("isotropic", False)), "DataFrame")
    if isinstance(data, (str, os.PathLike)):
        return os.fspath(data)
    raise TypeError(
        f"expected a path, a Run, a Model or a DataFrame of samples, got {type(data).__name__}"
    )


def grid_words(grid: tuple[float, float] | str | None) -> list[str]:
    """``--grid DTHETA,DPHI`` for ``grid`` (degrees), or nothing."""
    if grid is None:
        return []
    if isinstance(grid, str):
        return ["--grid", grid]
    dtheta, dphi = grid
    return ["--grid", f"{float(dtheta)!r},{float(dphi)!r}"]


def reduce_words(calibration: str, drift: str) -> list[str]:
    """``--calibration`` and ``--drift`` (how a run's readings are reduced)."""
    return ["--calibration", str(calibration), "--drift", str(drift)]


def write_atomic(path: str, data: bytes) -> None:
    """Writes ``path`` whole or not at all: a unique temporary name beside it (hidden,
    ``.tmp-…``), synced, renamed over it."""
    import uuid

    tmp = os.path.join(os.path.dirname(path), f".tmp-{uuid.uuid4().hex}-{os.path.basename(path)}")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def write_new(path: str | os.PathLike[str], data: str | bytes, force: bool) -> None:
    """Writes ``path`` whole or not at all (a temporary file renamed over it);
    an existing file is replaced only with ``force``."""
    path = os.fspath(path)
    if os.path.exists(path) and not force:
        raise _native.InputError(f"{path}: exists; give force=True to replace it")
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise _native.InputError(f"{path}: the directory {directory} does not exist")
    write_atomic(
        os.path.join(directory, os.path.basename(path)),
        data if isinstance(data, bytes) else data.encode(),
    )


def read_csv(path: str | os.PathLike[str]) -> pd.DataFrame:
    """A table or sample CSV that Gonio wrote, with its sidecar in
    ``df.attrs["gonio"]`` when there is one."""
    path = os.fspath(path)
    df = pd.read_csv(path, comment="#")
    side = path + ".json"
    if os.path.exists(side):
        with open(side) as f:
            df.attrs[SIDECAR] = json.load(f)
    return df


__all__ = ["SIDECAR", "read_csv", "to_frame", "to_input", "write_atomic", "write_new"]
