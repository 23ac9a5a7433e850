"""Type stubs of the native module (Rust, pyo3). The public API is the package
``gonio``; these are its building blocks."""

from typing import Any, Callable

import numpy as np
import numpy.typing as npt

__version__: str

class GonioError(Exception):
    """Any failure Gonio reports; ``exit_code`` is the command line's exit status."""

    exit_code: int

class InputError(GonioError):
    """Bad input: an argument, a file or a value (exit status 2)."""

class ConfigError(InputError):
    """A config, plan, model or surface file is wrong (file, line, field)."""

class DataError(InputError):
    """Data that cannot be processed as asked."""

class RunFileError(GonioError):
    """A run file is missing, not a run file, damaged, locked or already exists."""

class InstrumentError(GonioError):
    """The instrument (or the simulator) failed: a port, a timeout, a fault."""

Columns = list[tuple[str, npt.NDArray[Any]]]
Frame = tuple[list[tuple[str, npt.NDArray[np.float64]]], bool, str]
Input = str | "NativeModel" | Frame
#: ``(seq, stage, done, total, unit, message, url)``: a long call's state, handed
#: to a report callable every 50 ms and once at the end; ``seq`` changes with it.
State = tuple[int, str, int, int | None, str, str, str | None]
Report = Callable[[State], Any]

def init_logging(verbose: int = 0) -> None:
    """Logs to stderr at warn (0), debug (1) or trace (2); ``RUST_LOG`` overrides."""

def run_open(path: str) -> tuple[str, dict[str, str]]:
    """``gonio show --json`` (JSON text) and the ``meta`` rows of an intact run file."""

def run_readings(path: str) -> list[tuple[str, Any]]:
    """The readings as columns: arrays, ``(int64 array, NULL mask or None)``, or lists."""

def run_events(path: str) -> list[tuple[float, str, int | None, str]]:
    """``(wall_s, kind, step_id, message)`` of every event."""

def run_reduce(words: list[str]) -> tuple[Columns, str, str]:
    """``gonio reduce WORDS``: columns, sidecar JSON, reduction JSON."""

def toml_to_json(text: str) -> str:
    """TOML text as JSON text."""

def json_to_toml(text: str) -> str:
    """JSON text as TOML text."""

def check(input: Input, words: list[str]) -> str:
    """``gonio check``'s ``--json`` object (JSON text)."""

def correct(input: Input, words: list[str]) -> tuple[Columns, str, str]:
    """``gonio correct``: the table's columns, its sidecar and the ``--json`` object."""

def harmonics(input: Input, words: list[str]) -> tuple[str, str]:
    """``gonio harmonics``: the file's text and the ``--json`` object."""

def fit(
    input: Input, words: list[str], threads: int | None = None, report: Report | None = None
) -> tuple[str, str, str]:
    """``gonio fit``: the model file, the ``--json`` object, the report."""

def micro(
    words: list[str],
    theta_i: tuple[float, float, int] | None = None,
    threads: int | None = None,
    report: Report | None = None,
) -> tuple[Columns, str, str]:
    """``gonio micro``: the table's columns, its sidecar and the ``--json`` object;
    with ``report``, traced an incident direction a thread, each reported done."""

def acquire(
    words: list[str], out: str, progress: bool = False, report: Report | None = None
) -> tuple[str, str | None]:
    """``gonio acquire WORDS``: the session's ``--json`` object and the live page's
    address (``--serve``); ``progress`` draws the command's bar on stderr."""

def resume(
    words: list[str], progress: bool = False, report: Report | None = None
) -> tuple[str, str | None]:
    """``gonio resume WORDS``: as ``acquire``."""

def colour(words: list[str], text: str | None = None) -> str:
    """``gonio colour WORDS``: the ``--json`` object; ``text`` the spectra file's
    contents from memory."""

def export(input: Input, words: list[str], write: bool) -> tuple[bytes, str | None, str]:
    """``gonio export``: the file's bytes, a CSV's sidecar and the ``--json``
    object; ``write`` writes the file as the command does."""

def verify(words: list[str]) -> tuple[str, GonioError | None]:
    """``gonio verify WORDS``: the ``--json`` object, and the command's error when
    the file is damaged."""

def report(words: list[str], write: bool) -> tuple[str, str | None]:
    """``gonio report WORDS``: the ``--json`` object and, when not written, the
    page's HTML."""

def plan_check(words: list[str]) -> str:
    """``gonio plan check WORDS``: the ``--json`` object."""

def plan_compare(words: list[str], report: Report | None = None) -> str:
    """``gonio plan compare WORDS``: the ``--json`` object."""

def instrument_check(words: list[str]) -> str:
    """``gonio instrument check WORDS``: the ``--json`` object."""

class NativeModel:
    """An analytic model."""

    @staticmethod
    def load(path: str) -> NativeModel: ...
    @staticmethod
    def from_toml(text: str, label: str | None = None) -> NativeModel: ...
    def to_toml(self) -> str: ...
    def kind(self) -> str: ...
    def channels(self) -> list[str]: ...
    def eval(
        self,
        theta_i: npt.NDArray[np.float64],
        phi_i: npt.NDArray[np.float64],
        theta_o: npt.NDArray[np.float64],
        phi_o: npt.NDArray[np.float64],
        threads: int | None = None,
    ) -> npt.NDArray[np.float64]: ...
    def albedo(self, theta_i: list[float], phi_i: float = 0.0) -> npt.NDArray[np.float64]: ...

class NativeBsdf:
    """An RGL material."""

    @staticmethod
    def load(path: str) -> NativeBsdf: ...
    def description(self) -> str: ...
    def channels(self) -> list[str]: ...
    def isotropic(self) -> bool: ...
    def node_pairs(self) -> npt.NDArray[np.float64]: ...
    def eval(
        self,
        theta_i: npt.NDArray[np.float64],
        phi_i: npt.NDArray[np.float64],
        theta_o: npt.NDArray[np.float64],
        phi_o: npt.NDArray[np.float64],
        threads: int | None = None,
    ) -> npt.NDArray[np.float64]: ...
    def albedo(self, theta_i: list[float], phi_i: float = 0.0) -> npt.NDArray[np.float64]: ...

class NativeSimulator:
    """The simulated goniometer on two pseudo-terminals."""

    def __init__(
        self, config: str | None = None, seed: int | None = None, time_scale: float | None = None
    ) -> None: ...
    @property
    def ports(self) -> tuple[str, str]: ...
    @property
    def seed(self) -> int: ...
    @property
    def time_scale(self) -> float: ...
    @property
    def serving(self) -> bool: ...
    def close(self) -> None: ...

SEGMENT_RAYS: int

def run_command(words: list[str], threads: int | None = None) -> str:
    """``gonio WORDS…`` (an offline command) in this process: writes what it writes,
    returns what it prints."""

def validate(words: list[str]) -> None:
    """Checks ``gonio WORDS…`` as the command would before reading its input."""

def micro_plan(
    words: list[str], theta_i: tuple[float, float, int] | None, surface: str | None
) -> tuple[int, int]:
    """``(incident nodes, segments a node)`` of ``gonio micro``'s table."""

def micro_part(
    words: list[str],
    theta_i: tuple[float, float, int] | None,
    surface: str | None,
    incident: int,
    first: int,
    end: int,
    threads: int | None = None,
) -> bytes:
    """Segments ``first..end`` of one incident node of the table, as bytes."""

def micro_merge(
    words: list[str],
    theta_i: tuple[float, float, int] | None,
    surface: str | None,
    parts: list[bytes],
    out: str | None = None,
    force: bool = False,
) -> tuple[Columns, str, str]:
    """The table from its parts (bit for bit the table traced at once), written to
    ``out`` as ``gonio micro --out`` does when given."""

def micro_part_info(part: bytes) -> tuple[int, int, int, int, int]:
    """``(seed, rays, incident, first, end)`` of a part's bytes, checked whole."""
