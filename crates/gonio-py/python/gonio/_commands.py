"""Colour, export, report and verify: the command line's own computations, the
files written as the command writes them."""

from __future__ import annotations

import json
import os
from typing import Any

import pandas as pd

from gonio import _native
from gonio._frame import reduce_words, to_input

#: The formats of ``export``, as ``gonio export --format`` names them.
FORMATS = ("merl", "astm", "csv", "csv-long")


def _conditions(illuminant: str, observer: str | int, adaptation: str) -> list[str]:
    """The colour conversion's flags."""
    return [
        "--illuminant",
        str(illuminant),
        "--observer",
        str(observer),
        "--adaptation",
        str(adaptation),
    ]


def colour(
    spectra: str | os.PathLike[str] | pd.DataFrame,
    *,
    illuminant: str = "D65",
    observer: str | int = "1931",
    adaptation: str = "bradford",
) -> pd.DataFrame:
    """CIE XYZ, chromaticity and sRGB of spectra under a CIE illuminant, for the
    1931 or 1964 observer (CIE 015:2018), as ``gonio colour`` computes them.

    ``spectra`` is a CSV file or a DataFrame: a ``wavelength_nm`` column (or
    index; uniform 1, 5 or 10 nm covering 400–700 nm) and one column per spectrum
    (reflectance factor, or BRDF in 1/sr). Returns one row a spectrum, indexed by
    its name: ``X``, ``Y``, ``Z``, ``x``, ``y`` (NaN for black), the linear sRGB
    ``R_linear``, ``G_linear``, ``B_linear`` (unclipped), the encoded ``R``,
    ``G``, ``B`` in [0, 1] and ``hex`` (``#rrggbb``). ``df.attrs["colour"]`` holds
    ``gonio colour --json``'s object (conditions, white point)."""
    text = None
    if isinstance(spectra, pd.DataFrame):
        df = spectra
        if "wavelength_nm" not in df.columns and df.index.name == "wavelength_nm":
            df = df.reset_index()
        # Floats written as the shortest text that reads back to the same value.
        text = df.to_csv(index=False)
        name = "DataFrame"
    elif isinstance(spectra, (str, os.PathLike)):
        name = os.fspath(spectra)
    else:
        raise TypeError(
            f"colour(): spectra: a CSV path or a DataFrame, got {type(spectra).__name__}"
        )
    words = ["colour", name, *_conditions(illuminant, observer, adaptation)]
    result = json.loads(_native.colour(words, text))
    rows = []
    for s in result["spectra"]:
        r, g, b = s["srgb8"]
        rows.append(
            {
                "name": s["name"],
                "X": s["X"],
                "Y": s["Y"],
                "Z": s["Z"],
                "x": float("nan") if s["x"] is None else s["x"],
                "y": float("nan") if s["y"] is None else s["y"],
                "R_linear": s["srgb_linear"][0],
                "G_linear": s["srgb_linear"][1],
                "B_linear": s["srgb_linear"][2],
                "R": s["srgb"][0],
                "G": s["srgb"][1],
                "B": s["srgb"][2],
                "hex": f"#{r:02x}{g:02x}{b:02x}",
            }
        )
    out = pd.DataFrame(rows).set_index("name")
    out.attrs["colour"] = result
    return out


def export(
    data: Any,
    format: str,
    out: str | os.PathLike[str] | None = None,
    *,
    force: bool = False,
    calibration: str = "auto",
    drift: str = "auto",
    illuminant: str = "D65",
    observer: str | int = "1931",
    adaptation: str = "bradford",
) -> Any:
    """``data`` (a path, a ``Run``, a ``Model``, a ``Bsdf`` or a DataFrame of samples) in a
    format other tools read, as ``gonio export`` writes it: ``"merl"`` (MERL
    binary; wavelength channels go to R, G, B through the colour conversion, a half
    turn of an isotropic material is unfolded), ``"astm"`` (ASTM E1392 text),
    ``"csv"``, ``"csv-long"`` (a row per pair per wavelength) or ``"rgl"`` (the
    RGL material ``.bsdf`` Mitsuba 3's ``measured`` plugin renders; its json holds
    the interpolation error).

    With ``out``, writes the file (a CSV with its sidecar ``out.json``), refusing
    an existing one unless ``force``, and returns ``gonio export --json``'s dict;
    without, writes nothing and returns the file's bytes."""
    words = ["export", "--format", str(format)]
    if out is not None:
        words += ["--out", os.fspath(out)]
        if force:
            words.append("--force")
    else:
        words += ["--out", os.devnull]
    words += reduce_words(calibration, drift) + _conditions(illuminant, observer, adaptation)
    data, _sidecar, report = _native.export(to_input(data), words, out is not None)
    if out is None:
        return data
    return json.loads(report)


def report(
    run: Any,
    out: str | os.PathLike[str] | None = None,
    *,
    force: bool = False,
    calibration: str = "auto",
    drift: str = "auto",
) -> Any:
    """The run report, as ``gonio report`` makes it: one self-contained HTML page
    with the run's metadata, calibration, measures, fit and plots (and, for an
    adaptive run, where its points went). ``run`` is a ``Run`` or a run file.

    With ``out`` (a directory, made if missing), writes ``out/report.html``,
    refusing an existing one unless ``force``, and returns ``gonio report
    --json``'s dict (``out``, ``figures``, ``notes``); without, writes nothing and
    returns the page's HTML (``IPython.display.HTML`` shows it)."""
    path = run.path if hasattr(run, "path") else os.fspath(run)
    words = ["report", path, "--out", os.fspath(out) if out is not None else os.devnull]
    if force:
        words.append("--force")
    words += reduce_words(calibration, drift)
    result, html = _native.report(words, out is not None)
    return json.loads(result) if out is not None else html


def verify(run: Any, *, check: bool = False) -> dict[str, Any]:
    """Checks a run file whole, as ``gonio verify`` does: SQLite's integrity check,
    every row checksum, and the integrity record (readings deleted, replaced or
    altered, configs edited). Returns ``gonio verify --json``'s dict: ``intact``,
    ``recorded``, ``readings``, ``missing`` (steps whose readings are gone) and
    ``faults`` (one sentence each). ``check=True`` raises ``RunFileError`` (exit
    status 1, the command's message) when the file is damaged. A file that is
    missing or not a run file always raises ``RunFileError``."""
    path = run.path if hasattr(run, "path") else os.fspath(run)
    result, failure = _native.verify(["verify", path])
    if check and failure is not None:
        raise failure
    return json.loads(result)


__all__ = ["FORMATS", "colour", "export", "report", "verify"]
