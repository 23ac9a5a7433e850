"""Gonio from Python: measure, model and check BRDFs at Rust speed.

The same crates as the ``gonio`` command, in this process: a run file opens as a
``Run`` whose readings and reduction are DataFrames with the command's columns,
units and values; models evaluate on numpy arrays; ``check``, ``correct``,
``harmonics`` and ``fit`` return the command's numbers; ``acquire`` drives the
instrument (or the simulator, which ``Simulator`` also serves on
pseudo-terminals for any serial client). Angles are in degrees, f_r in 1/sr.
Long calls release the interpreter's lock, and Ctrl-C interrupts them (an
acquisition stops its stages first). Errors are ``GonioError`` and its
subclasses, with the command's message and ``exit_code``.
"""

from __future__ import annotations

from gonio import micro
from gonio._frame import read_csv
from gonio._instrument import Simulator, acquire, resume
from gonio._model import Model, load_model
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
from gonio._run import Run, open_run

__all__ = [
    "ConfigError",
    "DataError",
    "FitResult",
    "GonioError",
    "InputError",
    "InstrumentError",
    "Model",
    "Run",
    "RunFileError",
    "Simulator",
    "__version__",
    "acquire",
    "check",
    "correct",
    "fit",
    "harmonics",
    "init_logging",
    "load_model",
    "micro",
    "open_run",
    "read_csv",
    "resume",
]


def __getattr__(name: str) -> object:
    # matplotlib is an optional extra: gonio.plot is imported when first used.
    if name == "plot":
        import importlib

        return importlib.import_module("gonio.plot")
    raise AttributeError(f"module 'gonio' has no attribute {name!r}")
