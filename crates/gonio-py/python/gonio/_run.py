"""Run files: what ``gonio show`` says of them, their readings and events, and
their reduction as ``gonio reduce`` makes it."""

from __future__ import annotations

import json
import os
from typing import Any

import pandas as pd

from gonio import _native
from gonio._commands import report as _report
from gonio._commands import verify as _verify
from gonio._frame import grid_words, reduce_words, to_frame
from gonio._process import check as _check


class Run:
    """A run file, opened read-only after its integrity check (SQLite's check,
    every row checksum, the integrity record). Each method reads the file afresh,
    so a ``Run`` of an acquisition still going on sees its progress."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path: str = os.fspath(path)
        #: The ``--json`` object of the session that returned this run
        #: (``acquire``, ``resume``), else None.
        self.session: dict[str, Any] | None = None
        #: The live page's address, when that session served it.
        self.live_url: str | None = None
        summary, keys = _native.run_open(self.path)
        self._summary: dict[str, Any] = json.loads(summary)
        self._keys: dict[str, str] = dict(keys)

    def _gonio_input(self) -> str:
        """What the native module takes for this run: its path (``_frame.to_input``)."""
        return self.path

    def __repr__(self) -> str:
        return f"<gonio.Run {self.path!r} {self.status} {self._summary.get('name') or ''}>".replace(
            " >", ">"
        )

    @property
    def status(self) -> str:
        """``created``, ``running``, ``interrupted``, ``faulted``, ``complete``, or
        ``stale`` — stored as running but measured by no process (killed, or its
        status could not be written); ``resume`` continues it (as when opened)."""
        return str(self._summary["status"])

    @property
    def summary(self) -> dict[str, Any]:
        """What ``gonio show --json`` prints: counts, sessions, estimate, events."""
        return self._summary

    @property
    def meta(self) -> dict[str, Any]:
        """The run's record: ``name``, ``status``, ``seed``, ``software``,
        ``created``, ``notes``; the ``plan``, ``instrument`` and (simulated runs)
        ``sim`` configs parsed into dicts (their text under ``plan_text`` and so
        on); and every row of the file's ``meta`` table under ``keys``."""
        s = self._summary
        seed = s.get("seed")
        out: dict[str, Any] = {
            "name": s.get("name"),
            "status": s.get("status"),
            "seed": int(seed) if seed is not None and str(seed).isdigit() else seed,
            "software": s.get("software"),
            "created": s.get("created"),
            "notes": s.get("notes"),
        }
        for key in ("plan", "instrument", "sim"):
            text = s.get(key)
            out[f"{key}_text"] = text
            out[key] = json.loads(_native.toml_to_json(text)) if text else None
        out["keys"] = dict(self._keys)
        return out

    def readings(self) -> pd.DataFrame:
        """One row per reading, in step order: every column the run file keeps
        for it (stage targets ``cmd_*`` and read-backs ``pos_*``, the read-back
        directions ``theta_i`` … ``phi_o`` in degrees, the lock-in settings, R, X,
        Y in volts, flags, retries, clocks) and the step it measures (``kind``,
        ``channel``, ``repeat``, ``plan_index``, ``planned_theta_i`` …)."""
        cols: dict[str, Any] = {}
        for name, value in _native.run_readings(self.path):
            if isinstance(value, tuple):
                values, mask = value
                cols[name] = values if mask is None else pd.arrays.IntegerArray(values, mask)
            else:
                cols[name] = value
        return pd.DataFrame(cols, copy=False)

    def events(self) -> pd.DataFrame:
        """The run's events (start, resume, rehome, retry, fault, interrupt, stop):
        ``time`` (UTC), ``wall_s``, ``kind``, ``step_id``, ``message``."""
        rows = _native.run_events(self.path)
        df = pd.DataFrame(rows, columns=["wall_s", "kind", "step_id", "message"])
        df["step_id"] = df["step_id"].astype("Int64")
        df.insert(0, "time", pd.to_datetime(df["wall_s"], unit="s", utc=True))
        return df

    def reduce(
        self,
        calibration: str = "auto",
        drift: str = "auto",
        *,
        grid: tuple[float, float] | None = None,
        standard_sigma: float = 0.0,
    ) -> pd.DataFrame:
        """BRDF samples with uncertainties (DeYoung Eq. A.15, or relative to the
        run's reference standard), drift-corrected: the columns, units and values
        of ``gonio reduce`` (a table in grid order when the samples form a grid or
        ``grid=(dθ, dφ)`` resamples them, else one row a sample).

        ``df.attrs["gonio"]`` holds the CSV's sidecar (grid, isotropy) and
        ``df.attrs["reduction"]`` the reduction's account (``--json``)."""
        words = ["reduce", self.path, "--out", os.devnull]
        words += reduce_words(calibration, drift) + grid_words(grid)
        words += ["--standard-sigma", repr(float(standard_sigma))]
        cols, sidecar, report = _native.run_reduce(words)
        df = to_frame(cols, sidecar)
        df.attrs["reduction"] = json.loads(report)
        return df

    def check(self, **kwargs: Any) -> dict[str, Any]:
        """``gonio.check(self, **kwargs)``."""
        return _check(self, **kwargs)

    def verify(self, *, check: bool = False) -> dict[str, Any]:
        """``gonio.verify(self, check=check)``: the file checked whole."""
        return _verify(self, check=check)

    def report(self, out: str | os.PathLike[str] | None = None, **kwargs: Any) -> Any:
        """``gonio.report(self, out, **kwargs)``: the run report (its HTML, or
        written to ``out/report.html``)."""
        return _report(self, out, **kwargs)


def open_run(path: str | os.PathLike[str]) -> Run:
    """Opens a run file read-only, after its integrity check: a missing, foreign
    or damaged file raises ``RunFileError`` with the command line's message."""
    return Run(path)
