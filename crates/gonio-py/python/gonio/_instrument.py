"""Acquisition, and the simulated goniometer on pseudo-terminals."""

from __future__ import annotations

import json
import os
from types import TracebackType

from gonio import _native
from gonio._run import Run


def acquire(
    instrument: str | os.PathLike[str],
    plan: str | os.PathLike[str],
    out: str | os.PathLike[str],
    seed: int | None = None,
    progress: bool = True,
    *,
    sim: str | os.PathLike[str] | None = None,
    notes: str | None = None,
) -> Run:
    """Measures ``plan`` with ``instrument`` into a new run file ``out``, as
    ``gonio acquire`` does (a simulated instrument config runs the simulator in
    this process; ``sim`` is its config, ``seed`` its seed). Blocks until the run
    completes, and returns it.

    Ctrl-C (KeyboardInterrupt) is the safe stop: the stages stop, every reading
    taken is in the file, and the interrupt is re-raised once they have;
    ``resume(out)`` continues. A fault raises ``InstrumentError``; a bad config
    ``ConfigError``; an existing ``out`` ``RunFileError``."""
    out = os.fspath(out)
    words = ["acquire", "--instrument", os.fspath(instrument), "--plan", os.fspath(plan)]
    words += ["--out", out]
    if seed is not None:
        words += ["--seed", str(int(seed))]
    if sim is not None:
        words += ["--sim", os.fspath(sim)]
    if notes is not None:
        words += ["--notes", notes]
    report = json.loads(_native.acquire(words, out, progress=progress))
    run = Run(out)
    run.session = report
    return run


def resume(run: Run | str | os.PathLike[str], progress: bool = True) -> Run:
    """Continues an interrupted or killed run where it stopped, as ``gonio
    resume`` does; Ctrl-C stops it safely again."""
    path = run.path if isinstance(run, Run) else os.fspath(run)
    report = json.loads(_native.resume(path, progress=progress))
    out = Run(path)
    out.session = report
    return out


class Simulator:
    """The simulated goniometer — SMC100 stage controllers and an SR830 lock-in —
    served on two pseudo-terminals in this process, speaking the instruments' own
    bytes, so that pyserial, PyMeasure or any client can drive it::

        with gonio.Simulator() as sim:
            port = serial.Serial(sim.ports["motion"], 57600)

    ``config`` is a simulator config file (default: the embedded one); ``seed``
    and ``time_scale`` (wall seconds per physical second) override it."""

    def __init__(
        self,
        config: str | os.PathLike[str] | None = None,
        *,
        seed: int | None = None,
        time_scale: float | None = None,
    ) -> None:
        self._native = _native.NativeSimulator(
            None if config is None else os.fspath(config), seed, time_scale
        )

    @property
    def ports(self) -> dict[str, str]:
        """The pseudo-terminals: ``{"motion": …, "detector": …}``."""
        motion, detector = self._native.ports
        return {"motion": motion, "detector": detector}

    @property
    def seed(self) -> int:
        """The seed in use."""
        return int(self._native.seed)

    @property
    def time_scale(self) -> float:
        """Wall seconds per physical second."""
        return float(self._native.time_scale)

    @property
    def serving(self) -> bool:
        """Whether the ports are open."""
        return bool(self._native.serving)

    def close(self) -> None:
        """Stops serving (idempotent)."""
        self._native.close()

    def __enter__(self) -> Simulator:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "serving" if self.serving else "closed"
        return f"<gonio.Simulator {state} {self.ports} seed={self.seed}>"


__all__ = ["Simulator", "acquire", "resume"]
