"""DeYoung's measures and transforms, spherical harmonics and the lobe fit: the
command line's own computations on a run, a table, samples, a model or a
DataFrame."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from typing import Any

import pandas as pd

from gonio import _native
from gonio._frame import grid_words, reduce_words, to_frame, to_input, write_new
from gonio._model import Model
from gonio._progress import ProgressArg, Reporter

#: The transforms of ``correct``, by keyword (DeYoung Ch. 5).
STEPS = ("reciprocity", "energy", "isotropy", "separable")


def check(
    data: Any,
    k: int | Iterable[int] = (1, 5, 10),
    *,
    grid: tuple[float, float] | None = None,
    calibration: str = "auto",
    drift: str = "auto",
) -> dict[str, Any]:
    """DeYoung's measures (Ch. 4) of ``data`` — a path, a ``Run``, a ``Model`` or a
    DataFrame of samples: reciprocity P_r (Eq. 4.1), energy conservation P_ec
    (Eq. 4.5) with the directional albedos, isotropy P_i (Eq. 4.10) and
    k-separability P_s^(k) (Eq. 4.20) for each ``k``. The same dict, and the same
    numbers, as ``gonio check --json``."""
    ks = [int(k)] if isinstance(k, int) else [int(x) for x in k]
    words = ["check", "--k", ",".join(str(x) for x in ks)]
    words += grid_words(grid) + reduce_words(calibration, drift)
    return json.loads(_native.check(to_input(data), words))


def correct(
    data: Any,
    *,
    grid: tuple[float, float] | None = None,
    calibration: str = "auto",
    drift: str = "auto",
    **steps: Any,
) -> pd.DataFrame:
    """DeYoung's δ-transforms (Ch. 5) applied to ``data``'s table in the order the
    keywords are given: ``reciprocity=δ``, ``energy=δ`` (or ``"δ,max"``),
    ``isotropy=δ``, ``separable="k,δ"`` — each a value or a list of values, as the
    flags of ``gonio correct``. Returns the corrected table (the columns of the CSV
    ``gonio correct`` writes; its sidecar in ``df.attrs["gonio"]``) with the
    measures before and after in ``df.attrs["correct"]``."""
    words = ["correct"]
    for name, values in steps.items():
        if name not in STEPS:
            raise TypeError(f"correct() got an unexpected keyword {name!r}; steps are {STEPS}")
        seq = values if isinstance(values, (list, tuple)) else [values]
        for v in seq:
            words += [f"--{name}", str(v)]
    words += ["--out", os.devnull] + grid_words(grid) + reduce_words(calibration, drift)
    cols, sidecar, report = _native.correct(to_input(data), words)
    df = to_frame(cols, sidecar)
    df.attrs["correct"] = json.loads(report)
    return df


def harmonics(
    data: Any,
    order: int,
    *,
    filter: int | None = None,
    out: str | os.PathLike[str] | None = None,
    force: bool = False,
    grid: tuple[float, float] | None = None,
    calibration: str = "auto",
    drift: str = "auto",
) -> dict[str, Any]:
    """Real spherical harmonics with a symmetric coefficient matrix (Westin et al.
    1992) up to ``order``: exactly reciprocal. Returns ``gonio harmonics
    --json``'s dict (truncation error per channel, storage ratio) with the
    harmonics file's text under ``"file"``; ``out`` also writes it."""
    words = ["harmonics", "--order", str(int(order))]
    if filter is not None:
        words += ["--filter", str(int(filter))]
    words += ["--out", os.devnull] + grid_words(grid) + reduce_words(calibration, drift)
    text, report = _native.harmonics(to_input(data), words)
    result = json.loads(report)
    result["file"] = text
    if out is not None:
        write_new(out, text, force)
        result["out"] = os.fspath(out)
    return result


class FitResult:
    """A lobe fit (Lafortune et al. 1997) as ``gonio fit`` makes it."""

    def __init__(self, model_file: str, report_json: str, report: str) -> None:
        #: The fitted model.
        self.model: Model = Model.from_toml(model_file)
        #: The model file's text (what ``gonio fit --out`` writes).
        self.model_file: str = model_file
        #: ``gonio fit --json``'s object.
        self.json: dict[str, Any] = json.loads(report_json)
        #: The text ``gonio fit`` prints.
        self.report: str = report

    def __repr__(self) -> str:
        return f"<gonio.FitResult {len(self.json['fit']['channels'])} channel(s) chi2={self.chi2}>"

    @property
    def chi2(self) -> dict[str, float]:
        """Reduced χ² per channel (the objective's residual sum of squares over the
        degrees of freedom)."""
        return {c["channel"]: c["reduced_chi2"] for c in self.json["fit"]["channels"]}

    @property
    def params(self) -> pd.DataFrame:
        """Every parameter with its standard error: one row each, columns
        ``channel``, ``term`` (``diffuse`` or ``lobe 1`` …), ``parameter``
        (``rho_d``, ``m``, ``Cx``, ``Cy``, ``Cz``, ``n``), ``value``, ``std_err``."""
        rows = []
        for c in self.json["fit"]["channels"]:
            p, s = c["params"], c["std_err"]
            rows.append((c["channel"], "diffuse", "rho_d", p["rho_d"], s["rho_d"]))
            if self.json["fit"]["shape"]["diffuse"] == "Minnaert":
                rows.append((c["channel"], "diffuse", "m", p["m"], s["m"]))
            for j, (lobe, err) in enumerate(zip(p["lobes"], s["lobes"])):
                for name, v, e in zip(("Cx", "Cy", "Cz", "n"), lobe, err):
                    rows.append((c["channel"], f"lobe {j + 1}", name, v, e))
        return pd.DataFrame(rows, columns=["channel", "term", "parameter", "value", "std_err"])

    def save(self, path: str | os.PathLike[str], *, force: bool = False) -> None:
        """Writes the model file, as ``gonio fit --out`` does."""
        write_new(path, self.model_file, force)


def fit(
    samples: Any,
    model: str = "lafortune",
    lobes: int = 3,
    objective: str | None = None,
    *,
    diffuse: str = "lambert",
    anisotropic: bool = False,
    metric: str = "lafortune",
    cutoff: float = 90.0,
    share_exponents: bool = False,
    conserve_energy: bool = False,
    unweighted: bool = False,
    compare: bool = False,
    calibration: str = "auto",
    drift: str = "auto",
    threads: int | None = None,
    progress: ProgressArg = True,
) -> FitResult:
    """Sums of generalized cosine lobes (Lafortune et al. 1997, Eq. 8) fitted by
    Levenberg–Marquardt to ``samples``: a DataFrame like ``Run.reduce()`` returns,
    a ``Run``, a ``Model`` or a path. The options are ``gonio fit``'s flags;
    ``threads`` bounds the threads the fit uses (default: one a core). The
    interpreter's lock is released while it runs. ``progress``: in a notebook, a
    tqdm bar showing the time it has taken (the fit does not say how far it is),
    or a callable given a ``gonio.Progress``."""
    words = ["fit", "--model", model, "--lobes", str(int(lobes))]
    if objective is not None:
        words += ["--objective", objective]
    words += ["--diffuse", diffuse, "--metric", metric, "--cutoff", repr(float(cutoff))]
    for flag, on in (
        ("--anisotropic", anisotropic),
        ("--share-exponents", share_exponents),
        ("--conserve-energy", conserve_energy),
        ("--unweighted", unweighted),
        ("--compare", compare),
    ):
        if on:
            words.append(flag)
    words += reduce_words(calibration, drift)
    with Reporter(progress) as reporter:
        report = reporter if reporter.active else None
        return FitResult(*_native.fit(to_input(samples), words, threads=threads, report=report))
