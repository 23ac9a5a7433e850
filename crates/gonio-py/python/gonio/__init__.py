"""Gonio from Python: measure, model and check BRDFs at Rust speed.

The same crates as the ``gonio`` command, in this process: a run file opens as a
``Run`` whose readings and reduction are DataFrames with the command's columns,
units and values; models and RGL materials (``open_bsdf``) evaluate on numpy
arrays; ``check``, ``correct``,
``harmonics``, ``fit``, ``colour``, ``export``, ``report``, ``verify``,
``plan.check``, ``plan.compare`` and ``instrument.check`` return the command's
numbers and write its files; ``acquire`` drives the instrument (or the
simulator, which ``Simulator`` also serves on pseudo-terminals for any serial
client), its live page served with ``serve=True``. Angles are in degrees, f_r in
1/sr. Long calls release the interpreter's lock, show a progress bar in a
notebook (with tqdm), and Ctrl-C interrupts them (an acquisition stops its
stages first). Errors are ``GonioError`` and its subclasses, with the command's
message and ``exit_code``.
"""

from __future__ import annotations

from gonio import instrument, micro, plan
from gonio._commands import colour, export, report, verify
from gonio._frame import read_csv
from gonio._instrument import Simulator, acquire, resume
from gonio._model import Bsdf, Model, load_model, open_bsdf
from gonio._native import (
    ConfigError,
    DataError,
    GonioError,
    InputError,
    InstrumentError,
    RunFileError,
    __version__,
    init_logging,
)
from gonio._process import FitResult, check, correct, fit, harmonics
from gonio._progress import Progress
from gonio._run import Run, open_run

__all__ = [
    "Bsdf",
    "ConfigError",
    "DataError",
    "FitResult",
    "GonioError",
    "InputError",
    "InstrumentError",
    "Model",
    "Progress",
    "Run",
    "RunFileError",
    "Simulator",
    "__version__",
    "acquire",
    "check",
    "colour",
    "correct",
    "export",
    "fit",
    "harmonics",
    "init_logging",
    "instrument",
    "load_model",
    "micro",
    "open_bsdf",
    "open_run",
    "plan",
    "read_csv",
    "report",
    "resume",
    "verify",
]


def __getattr__(name: str) -> object:
    # matplotlib is an optional extra: gonio.plot is imported when first used.
    if name == "plot":
        import importlib

        return importlib.import_module("gonio.plot")
    raise AttributeError(f"module 'gonio' has no attribute {name!r}")
