"""Acquisition, and the simulated goniometer on pseudo-terminals."""

from __future__ import annotations

import json
import os
from types import TracebackType

from gonio import _native
from gonio._progress import ProgressArg, Reporter
from gonio._run import Run


def _serve_words(serve: bool | int | str | None, control: bool) -> list[str]:
    """``--serve [ADDR]`` and ``--control`` for ``serve`` (True: 127.0.0.1 at a
    free port; a port; an IP; or IP:PORT)."""
    words: list[str] = []
    if serve is not None and serve is not False:
        words.append("--serve")
        if serve is not True:
            words.append(str(serve))
    if control:
        words.append("--control")
    return words


def acquire(
    instrument: str | os.PathLike[str],
    plan: str | os.PathLike[str],
    out: str | os.PathLike[str],
    seed: int | None = None,
    progress: ProgressArg = True,
    *,
    sim: str | os.PathLike[str] | None = None,
    notes: str | None = None,
    serve: bool | int | str = False,
    control: bool = False,
) -> Run:
    """Measures ``plan`` with ``instrument`` into a new run file ``out``, as
    ``gonio acquire`` does (a simulated instrument config runs the simulator in
    this process; ``sim`` is its config, ``seed`` its seed). Blocks until the run
    completes, and returns it (``run.session``: the session's ``--json`` object).

    ``serve`` serves the run's live page while it measures, as ``--serve`` does:
    ``True`` at 127.0.0.1 on a free port, or an address (``"IP:PORT"``, a port, an
    IP); ``control`` adds its Stop and Pause buttons. The page's address is shown
    when it starts (in a notebook, as a link) and kept in ``run.live_url``; the
    page stops when the call returns (``gonio view`` serves it afterwards).

    ``progress``: in a notebook, a tqdm bar (when tqdm is installed); in a
    terminal, the command's bar on stderr; or a callable given a
    ``gonio.Progress`` at every step; ``False`` for nothing.

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
    words += _serve_words(serve, control)
    with Reporter(progress, terminal_bar=True) as reporter:
        reporter.control = control
        report, url = _native.acquire(words, out, progress=reporter.terminal, report=reporter)
    run = Run(out)
    run.session = json.loads(report)
    run.live_url = url
    return run


def resume(
    run: Run | str | os.PathLike[str],
    progress: ProgressArg = True,
    *,
    serve: bool | int | str = False,
    control: bool = False,
) -> Run:
    """Continues an interrupted or killed run where it stopped, as ``gonio
    resume`` does; Ctrl-C stops it safely again. ``progress``, ``serve`` and
    ``control`` as for ``acquire``."""
    path = run.path if isinstance(run, Run) else os.fspath(run)
    words = ["resume", path, *_serve_words(serve, control)]
    with Reporter(progress, terminal_bar=True) as reporter:
        reporter.control = control
        report, url = _native.resume(words, progress=reporter.terminal, report=reporter)
    out = Run(path)
    out.session = json.loads(report)
    out.live_url = url
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
