"""Reprocessing an archive of run files: one Dask task a run, each running the
command line's own ``reduce``, ``check``, ``fit`` and ``report`` in its worker."""

from __future__ import annotations

import contextlib
import glob
import json
import os
import shutil
import time
import uuid
from collections.abc import Iterable, Sequence
from typing import Any

import pandas as pd

from gonio import _native
from gonio.batch import _common as c

#: The steps, in the order they run.
STEPS = ("reduce", "check", "fit", "report")

#: The file each step writes in a run's output directory (``report`` writes
#: ``report.html``; ``reduce`` also the table's sidecar ``reduced.csv.json``).
FILES = {
    "reduce": ("reduced.csv", "reduction.json"),
    "check": ("check.json",),
    "fit": ("model.toml", "fit.json"),
    "report": ("report.html",),
}

#: The file that marks a run's outputs complete: the row, written last.
ROW = "row.json"


def find_runs(runs: str | os.PathLike[str] | Iterable[str | os.PathLike[str]]) -> list[str]:
    """The run files ``runs`` names: paths, directories (every ``*.gonio`` below
    them, sorted) and glob patterns; each once, in the order given. A name that
    exists is taken as it is, even with ``[`` or ``*`` in it."""
    items = [runs] if isinstance(runs, (str, os.PathLike)) else list(runs)
    out: list[str] = []
    for item in items:
        p = os.fspath(item)
        if os.path.isdir(p):
            pattern = os.path.join(glob.escape(p), "**", "*.gonio")
            found = sorted(glob.glob(pattern, recursive=True))
        elif not os.path.exists(p) and any(ch in p for ch in "*?["):
            found = sorted(glob.glob(p, recursive=True))
        else:
            found = [p]
        out.extend(os.path.abspath(f) for f in found)
    return list(dict.fromkeys(out))


def step_words(steps: Sequence[str], options: dict[str, Any]) -> dict[str, list[str]]:
    """The flags each step gets from ``options`` (keywords of the commands' flags:
    ``lobes=2``, ``drift="none"``): each option goes to every step whose
    command takes it, as its parser says. An option no step takes is a
    ``TypeError``, a bad value the command's ``InputError``: both before any work."""
    unknown = [s for s in steps if s not in STEPS]
    if unknown or not steps:
        raise ValueError(f"steps: {unknown or 'none'}; choose from {STEPS}")
    base = {s: [s, "run.gonio"] + (["--out", "out"] if s != "check" else []) for s in steps}
    words: dict[str, list[str]] = {s: [] for s in steps}
    for name, value in options.items():
        flag = c.flag_words(name, value)
        probe = c.flag_words(name, True) if isinstance(value, bool) else flag
        takers = [s for s in steps if c.takes(base[s], probe)]
        if not takers:
            raise TypeError(f"reprocess: no step of {tuple(steps)} takes the option {name!r}")
        for s in takers:
            words[s] += flag
    for s in steps:
        _native.validate(base[s] + words[s])
    return words


def _worst(per_channel: Any) -> float | None:
    """The largest of a per-channel list of measures (the worst channel)."""
    values = [v for v in per_channel or [] if isinstance(v, (int, float))]
    return max(values) if values else None


def _summary(outputs: dict[str, Any]) -> dict[str, Any]:
    """The row's numbers from the steps' JSON objects."""
    row: dict[str, Any] = {}
    red = outputs.get("reduce")
    if red is not None:
        row["samples"] = red.get("samples")
    chk = outputs.get("check")
    if chk is not None:
        row["P_r"] = _worst(chk.get("reciprocity"))
        row["P_ec"] = _worst((chk.get("energy") or {}).get("p_ec"))
        row["P_i"] = _worst(chk.get("isotropy"))
        for ch in chk.get("separability") or []:
            for k, p in ch.get("p_s", []):
                if isinstance(p, (int, float)):
                    key = f"P_s{k}"
                    row[key] = max(row.get(key, p), p)
    fit = outputs.get("fit")
    if fit is not None:
        f = fit["fit"]
        row.setdefault("samples", f.get("samples"))
        row["fit"] = {ch["channel"]: ch["params"] for ch in f["channels"]}
        row["chi2"] = {ch["channel"]: ch["reduced_chi2"] for ch in f["channels"]}
    return row


def reprocess_one(
    path: str,
    out_dir: str,
    steps: Sequence[str],
    words: dict[str, list[str]],
    options_key: str,
    token: str,
    force: bool = False,
) -> dict[str, Any]:
    """One run: the task a worker runs. Its outputs go to ``out_dir/NAME-KEY/``
    (``KEY`` from the run's content hash and the options), built in a hidden
    directory and renamed into place when all are written; a run already done is
    read back, not redone. The run file is only read. Never raises: a failure is
    the row's ``error``."""
    started = time.perf_counter()
    stem = c.safe_stem(path)
    row: dict[str, Any] = {"run": path, "status": "failed", "key": None, "dir": None}
    try:
        if not os.path.isfile(path):
            # The command's own words for it.
            raise _native.RunFileError(f"{path}: No such file or directory (os error 2)")
        key = f"{stem}-{c.short_hash(c.run_digest(path), options_key)}"
        final = os.path.join(out_dir, key)
        row["key"] = key
        if os.path.exists(os.path.join(final, ROW)) and not force:
            row.update(_read_row(final), status="skipped")
        else:
            outputs = _compute(path, out_dir, token, key, final, steps, words, force)
            row.update(outputs, status="done")
        row["dir"] = final
    except _native.GonioError as e:
        row.update(error=str(e), exit_code=e.exit_code)
    except Exception as e:  # a failure of this run is reported, never the batch's
        row.update(error=f"{type(e).__name__}: {e}", exit_code=None)
    row["seconds"] = time.perf_counter() - started
    return row


def _read_row(final: str) -> dict[str, Any]:
    with open(os.path.join(final, ROW), encoding="utf-8") as f:
        return json.load(f)


def _compute(
    path: str,
    out_dir: str,
    token: str,
    key: str,
    final: str,
    steps: Sequence[str],
    words: dict[str, list[str]],
    force: bool,
) -> dict[str, Any]:
    tmp = c.work_dir(out_dir, token, key)
    try:
        outputs: dict[str, Any] = {}
        for step in STEPS:
            if step not in steps:
                continue
            argv = [step, path]
            if step == "reduce":
                argv += ["--out", os.path.join(tmp, "reduced.csv")]
            elif step == "fit":
                argv += ["--out", os.path.join(tmp, "model.toml")]
            elif step == "report":
                argv += ["--out", tmp]
            text = _native.run_command([*argv, "--json", *words[step]], threads=1)
            # Paths of the hidden directory and wall times are left out: a retried
            # task writes the same bytes.
            outputs[step] = c.strip(json.loads(text), frozenset({"out", "seconds"}))
            if step in ("reduce", "check", "fit"):
                name = FILES[step][-1]
                c.write_json(os.path.join(tmp, name), outputs[step])
        row = _summary(outputs)
        files = [f for s in steps for f in FILES[s]]
        if "reduce" in steps:
            files.append("reduced.csv.json")
        row["files"] = sorted(files)
        c.write_json(os.path.join(tmp, ROW), row)
        if not c.publish(tmp, final, ROW, replace=force):
            return _read_row(final)
        return row
    finally:
        if os.path.isdir(tmp):
            shutil.rmtree(tmp, ignore_errors=True)


#: The columns of ``reprocess``'s frame that always exist, in order.
COLUMNS = ["run", "status", "samples", "P_r", "P_ec", "P_i", "chi2", "fit", "dir", "files"]


def reprocess(
    runs: str | os.PathLike[str] | Iterable[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    client: Any = None,
    steps: Sequence[str] = STEPS,
    *,
    force: bool = False,
    progress: bool = False,
    **options: Any,
) -> pd.DataFrame:
    """Reprocesses run files on a Dask cluster: for each run, one task that runs
    ``gonio reduce``, ``check``, ``fit`` and ``report`` (``steps``) in its worker
    and writes their outputs to ``out_dir/NAME-KEY/``: ``reduced.csv`` (+ sidecar)
    and ``reduction.json``, ``check.json``, ``model.toml`` and ``fit.json``,
    ``report.html``, and ``row.json``. ``NAME`` is the run's file name and ``KEY``
    hashes its content and the options, so a rerun skips every run already done
    (``force`` redoes them), and a run changed since is done again.

    ``runs``: paths, directories (their ``*.gonio``, recursively) or glob patterns.
    ``client``: a ``distributed.Client`` (of a ``LocalCluster``, of a scheduler's
    address, of a dask-jobqueue cluster); ``None`` starts a ``LocalCluster`` on the
    loopback interface, one worker process a core, for this call. ``options``:
    the commands' flags by keyword, each given to the steps that take it
    (``drift="none"``, ``lobes=2``, ``k=[1, 5]``, ``grid=(10, 15)``).
    Workers must see ``runs`` and ``out_dir`` at the same paths (a shared file
    system, as on any cluster); run files are opened read-only.

    Returns one row a run: ``run``, ``status`` (``done``, ``skipped``: done
    before, ``failed``), ``samples``, the worst channel's DeYoung measures
    ``P_r``, ``P_ec``, ``P_i``, ``P_s{k}``, per-channel ``chi2`` (reduced χ²) and
    ``fit`` parameters, ``dir`` and its ``files``, ``error`` and ``exit_code`` of
    a run that failed (which never stops the others), and the task's ``seconds``.
    """
    paths = find_runs(runs)
    if not paths:
        raise ValueError(f"reprocess: no run files in {runs!r}")
    out = os.path.abspath(os.fspath(out_dir))
    steps = tuple(steps)
    words = step_words(steps, options)
    token = c.new_token()
    if not os.path.isdir(out):
        os.makedirs(out)
    options_key = c.canonical(
        {"steps": sorted(steps), "words": words, "version": _native.__version__}
    )
    rows: list[dict[str, Any]] = []
    with c.client_for(client) as cl:
        futures = {
            i: cl.submit(
                reprocess_one,
                p,
                out,
                steps,
                words,
                options_key,
                token,
                force,
                key=f"gonio-run-{os.path.basename(p)}-{uuid.uuid4().hex[:12]}",
            )
            for i, p in enumerate(paths)
        }
        results = c.gather(cl, futures, progress)
    for i, p in enumerate(paths):
        r = results.get(i)
        if isinstance(r, BaseException):
            r = {"run": p, "status": "failed", "error": f"{type(r).__name__}: {r}"}
        rows.append(r)
    with contextlib.suppress(OSError):
        c.clean_work(out, token)
    df = pd.DataFrame(rows)
    for col in COLUMNS + ["error", "exit_code", "seconds"]:
        if col not in df.columns:
            df[col] = None
    # A failed run has no count: a nullable integer, not a float.
    df["samples"] = df["samples"].astype("Int64")
    extra = sorted(col for col in df.columns if col.startswith("P_s"))
    rest = [col for col in df.columns if col not in COLUMNS + extra]
    return df[COLUMNS[:6] + extra + COLUMNS[6:] + rest]


__all__ = ["STEPS", "find_runs", "reprocess", "reprocess_one", "step_words"]
