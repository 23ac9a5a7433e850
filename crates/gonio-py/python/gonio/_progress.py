"""How long calls show their progress: in a notebook, tqdm's bar (when tqdm is
installed); in a terminal, what the command shows (the acquisition's bar on
stderr); anywhere, a callable given as ``progress=`` instead."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Callable, Union


@dataclass(frozen=True)
class Progress:
    """How far a long call is, as a ``progress=`` callable is given it."""

    #: What it is doing: ``acquire``, ``resume``, ``trace``, ``fit``, or the plan
    #: ``plan.compare`` is measuring (``adaptive``, ``lattice``, ``grid``).
    stage: str
    #: Units done in this stage.
    done: int
    #: Units in the stage, once known (an adaptive run's grows batch by batch).
    total: int | None
    #: What a unit is: ``steps``, ``incidences``, or empty when nothing is counted.
    unit: str
    #: The latest reading or event, one line.
    message: str
    #: The live page's address, once served.
    url: str | None


#: What ``progress=`` takes: ``True`` (a notebook's bar, or the command's bar in a
#: terminal), ``False``, or a callable given a ``Progress`` at every change.
ProgressArg = Union[bool, Callable[[Progress], Any], None]

#: How often a bar without a count is redrawn (its elapsed time), seconds.
_REDRAW_S = 0.5


def in_notebook() -> bool:
    """Whether this is a Jupyter kernel (where stderr is not a terminal and the
    command's own bar is not drawn)."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:
        return False
    return shell is not None and "IPKernelApp" in getattr(shell, "config", {})


def _tqdm() -> Any:
    """tqdm's notebook bar when ipywidgets can draw it, else its text bar; None
    without tqdm."""
    try:
        import tqdm  # noqa: F401
    except ImportError:
        return None
    try:
        import ipywidgets  # noqa: F401
        from tqdm.notebook import tqdm as bar
    except ImportError:
        from tqdm.std import tqdm as bar
    return bar


class Reporter:
    """What a long native call hands its state to, every 50 ms and once at the
    end, on the calling thread: it draws the bar, calls the user's callable, and
    shows the live page's address.

    ``terminal`` tells the native call to draw the command's own bar on stderr
    (and print the address itself)."""

    def __init__(self, progress: ProgressArg, *, terminal_bar: bool = False) -> None:
        self._callback: Callable[[Progress], Any] | None = None
        self._bar_class: Any = None
        self.terminal = False
        if callable(progress) and not isinstance(progress, bool):
            self._callback = progress
        elif progress:
            if in_notebook():
                self._bar_class = _tqdm()
            else:
                self.terminal = terminal_bar
        self._seq = -1
        self._stage: str | None = None
        self._bar: Any = None
        self._drawn = 0.0
        self.url: str | None = None
        self.control = False

    @property
    def active(self) -> bool:
        """Whether anything is shown or called (else the native call needs no
        reporter, and an acquisition none but for its address)."""
        return self._callback is not None or self._bar_class is not None

    def __call__(self, state: tuple[Any, ...]) -> None:
        seq, stage, done, total, unit, message, url = state
        if url and url != self.url:
            self.url = url
            if not self.terminal:
                self._show_url(url)
        if not stage:
            # Nothing begun yet (the call is still setting up).
            return
        if seq == self._seq:
            # Nothing new: a bar without a count still shows the time going by.
            if self._bar is not None and self._bar.total is None:
                now = time.monotonic()
                if now - self._drawn >= _REDRAW_S:
                    self._bar.refresh()
                    self._drawn = now
            return
        self._seq = seq
        p = Progress(
            str(stage), int(done), None if total is None else int(total), unit, message, url
        )
        if self._callback is not None:
            self._callback(p)
        if self._bar_class is not None:
            self._draw(p)

    def _draw(self, p: Progress) -> None:
        if p.stage != self._stage:
            self.close()
            self._stage = p.stage
        if self._bar is None:
            if p.unit and p.total is None:
                # A count without its total yet (a run before its first step).
                return
            options: dict[str, Any] = {"desc": p.stage, "total": p.total, "leave": True}
            if p.unit:
                options["unit"] = " " + p.unit.rstrip("s")
                options["unit_scale"] = False
            else:
                options["bar_format"] = "{desc}: {elapsed}"
            self._bar = self._bar_class(**options)
        bar = self._bar
        if p.total is not None and bar.total != p.total:
            # An adaptive run grows batch by batch. Not reset(): the count and the
            # rate go on; a notebook widget's bar is resized as reset() would.
            bar.total = p.total
            children = getattr(getattr(bar, "container", None), "children", ())
            if len(children) == 3:
                children[1].max = p.total
        bar.n = p.done
        if p.message:
            bar.set_postfix_str(p.message, refresh=False)
        bar.refresh()
        self._drawn = time.monotonic()

    def _show_url(self, url: str) -> None:
        note = " (the token allows Stop and Pause)" if self.control else ""
        text = f"gonio: live view at {url}{note}"
        if in_notebook():
            try:
                from IPython.display import display

                link = f'gonio: live view at <a href="{url}" target="_blank">{url}</a>{note}'
                display({"text/plain": text, "text/html": link}, raw=True)
                return
            except ImportError:
                pass
        print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        """Ends the bar (it stays, showing where the call ended)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Reporter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


__all__ = ["Progress", "ProgressArg", "Reporter", "in_notebook"]
