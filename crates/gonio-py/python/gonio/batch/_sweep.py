"""Microgeometry sweeps: surfaces × parameter sets × incident directions, each
table traced in chunks of rays on Dask workers and merged exactly."""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from gonio import _native
from gonio._frame import read_csv, to_frame
from gonio.batch import _common as c
from gonio.micro import _axis

#: Rays a segment: a chunk is whole segments, which is what makes a table merged
#: from chunks bit for bit the table ``gonio micro`` traces at once.
SEGMENT_RAYS: int = _native.SEGMENT_RAYS

#: The default chunk: four segments (1 048 576 rays), seconds of one core's work.
CHUNK_RAYS = 4 * SEGMENT_RAYS

#: Flags of ``gonio micro`` a sweep does not set: it writes its own outputs, and
#: spherical harmonics are not split into chunks.
NOT_IN_SWEEP = frozenset(
    {"out", "force", "per_order", "sh", "sh_filter", "sh_out", "sh_rays", "json", "surface"}
)


@dataclass
class Table:
    """One table of a sweep: a surface under one parameter set."""

    surface: str
    set: int
    params: dict[str, Any]
    text: str
    words: list[str]
    axis: tuple[float, float, int] | None
    seed: int
    name: str
    incidents: int
    segments: int


def _set(doc: dict[str, Any], dotted: str, value: Any) -> None:
    """Sets a surface-file value: ``rms_height`` is ``surface.rms_height``; a dotted
    name (``materials.gold.n``) is a path from the top."""
    path = dotted.split(".") if "." in dotted else ["surface", dotted]
    node = doc
    for part in path[:-1]:
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise _native.ConfigError(f"{dotted}: {part!r} is not a table of the surface file")
        node = nxt
    node[path[-1]] = value


def _derived_seed(seed: int, surface_sha: str, params: dict[str, Any]) -> int:
    """A table's seed from the sweep's seed and the task's key (the surface's
    content and the parameter set): the same whatever the order tasks run in."""
    text = f"gonio micro sweep\0{seed}\0{surface_sha}\0{c.canonical(params)}"
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little") >> 1


def _read_toml(path: str) -> tuple[str, dict[str, Any]]:
    """A TOML file's text and contents; a file that cannot be read or parsed is a
    ``ConfigError`` naming it."""
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except OSError as e:
        raise _native.ConfigError(f"{path}: {e.strerror or e}") from None
    try:
        return text, json.loads(_native.toml_to_json(text))
    except _native.GonioError as e:
        raise _native.ConfigError(f"{path}: {e}") from None


def _micro_flag(micro: list[str], j: int, name: str, value: Any) -> bool:
    """Whether ``name`` is a flag of ``gonio micro``; a flag's bad value is refused
    naming the parameter set."""
    try:
        return c.takes(micro, c.flag_words(name, True if isinstance(value, bool) else value))
    except _native.GonioError as e:
        raise type(e)(f"params[{j}]: {e}") from None


def plan(
    surfaces: Sequence[str | os.PathLike[str]], params: Sequence[dict[str, Any]], seed: int = 0
) -> list[Table]:
    """Every table of a sweep, checked — options by ``gonio micro``'s parser, edited
    surfaces by its loader — before anything is traced."""
    if not surfaces or not params:
        raise ValueError("micro_sweep: give at least one surface and one parameter set")
    micro = ["micro", "surface.toml", "--out", os.devnull]
    tables = []
    for s in surfaces:
        path = os.path.abspath(os.fspath(s))
        text0, doc0 = _read_toml(path)
        for j, p in enumerate(params):
            if not isinstance(p, dict):
                raise TypeError(f"params[{j}]: a dict of gonio micro options, got {p!r}")
            flags: list[str] = []
            overrides = {}
            axis = None
            table_seed = None
            for name, value in p.items():
                if name in NOT_IN_SWEEP:
                    raise ValueError(f"params[{j}]: {name!r} is not an option of a sweep")
                if name == "theta_i":
                    axis = _axis(value)
                elif name == "seed":
                    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
                        raise ValueError(f"params[{j}]: seed: a whole number ≥ 0, got {value!r}")
                    table_seed = value
                elif _micro_flag(micro, j, name, value):
                    flags += c.flag_words(name, value)
                else:
                    overrides[name] = value
            if overrides:
                doc = json.loads(json.dumps(doc0))
                for name, value in overrides.items():
                    _set(doc, name, value)
                text = _native.json_to_toml(json.dumps(doc))
            else:
                text = text0
            sha = hashlib.sha256(text.encode()).hexdigest()
            if table_seed is None:
                table_seed = _derived_seed(seed, sha, p)
            flags += ["--seed", str(table_seed)]
            words = ["micro", path, "--out", os.devnull, *flags]
            try:
                n_in, n_seg = _native.micro_plan(words, axis, text)
            except _native.GonioError as e:
                where = f"{path}, params[{j}]" + (f" {overrides}" if overrides else "")
                raise type(e)(f"{where}: {e}") from None
            stem = os.path.splitext(os.path.basename(path))[0]
            key = c.short_hash(sha, c.canonical(flags), c.canonical(axis), _native.__version__)
            tables.append(
                Table(path, j, dict(p), text, words, axis, table_seed, f"{stem}-{key}", n_in, n_seg)
            )
    return tables


def part_task(
    words: list[str],
    axis: tuple[float, float, int] | None,
    text: str,
    incident: int,
    first: int,
    end: int,
    cache: str | None,
) -> bytes:
    """A chunk: segments ``first..end`` of one incident node (the task a worker
    runs), kept in ``cache`` when given so that a rerun does not trace it again."""
    if cache is not None and os.path.exists(cache):
        with open(cache, "rb") as f:
            kept = f.read()
        try:
            if _native.micro_part_info(kept)[2:] == (incident, first, end):
                return kept
        except _native.GonioError:
            pass
        # Damaged, or of another build: traced again.
        os.remove(cache)
    part = _native.micro_part(words, axis, text, incident, first, end, threads=1)
    if cache is not None:
        c.write_atomic(cache, part)
    return part


def _done(out: str | None, t: Table) -> bool:
    return out is not None and all(
        os.path.exists(os.path.join(out, t.name + ext)) for ext in (".csv", ".csv.json", ".json")
    )


def micro_sweep(
    surfaces: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    params: dict[str, Any] | Sequence[dict[str, Any]],
    client: Any = None,
    seed: int = 0,
    *,
    out_dir: str | os.PathLike[str] | None = None,
    chunk_rays: int = CHUNK_RAYS,
    force: bool = False,
    progress: bool = False,
) -> pd.DataFrame:
    """Traces every surface under every parameter set on a Dask cluster: the
    tables ``gonio micro`` makes (f_r with its Monte Carlo standard error in the
    sigma columns), one below the other.

    ``params``: dicts of ``gonio micro`` options by their command-line names
    (``rays``, ``grid=(10, 15)``, ``isotropic``, ``max_bounces``, ``seed``) and
    ``theta_i`` (evenly spaced incident polar angles, degrees); any other key sets
    a value of the surface file (``rms_height=0.2`` is ``[surface] rms_height``,
    ``"materials.gold.n"`` a dotted path). A set without ``seed`` gets one derived
    from ``seed`` and its key (the surface's content, the set), so the tables are
    the same bytes on any number of workers, in any order of completion.

    Each incident direction of each table is traced in chunks of ``chunk_rays``
    (rounded up to whole segments of ``SEGMENT_RAYS``), each chunk a Dask task; a
    table is merged as soon as its last chunk is in. Chunks
    return the estimator's sums, not means, so the merged table and its errors
    are exactly those of one simulation of all the rays: bit for bit the table of
    ``gonio micro SURFACE --seed S`` with the same options.

    ``out_dir`` also writes each table as ``NAME-KEY.csv`` (+ sidecar) and
    ``NAME-KEY.json`` (ray statistics, albedos): named by the surface's content
    and the options, so a rerun reads finished tables back and traces only what
    is missing (chunks already traced are kept under ``.tmp-parts``). A height
    map's data file is not part of the name: a table of an edited height map needs
    ``force``. ``client``: as ``reprocess``. ``df.attrs["tables"]`` describes each
    table. A failed chunk raises ``SweepError`` once the other tables are done.
    """
    surface_list = [surfaces] if isinstance(surfaces, (str, os.PathLike)) else list(surfaces)
    param_list = [params] if isinstance(params, dict) else list(params)
    tables = plan(surface_list, param_list, int(seed))
    if int(chunk_rays) < 1:
        raise ValueError(f"chunk_rays: at least 1, got {chunk_rays}")
    out = None if out_dir is None else os.path.abspath(os.fspath(out_dir))
    if out is not None and not os.path.isdir(out):
        os.makedirs(out)
    per_chunk = max(1, math.ceil(int(chunk_rays) / SEGMENT_RAYS))
    results: dict[int, tuple[pd.DataFrame, dict[str, Any]]] = {}
    todo = []
    for ti, t in enumerate(tables):
        if out is not None and not force and _done(out, t):
            results[ti] = _read_back(t, out)
        else:
            todo.append(ti)
    failed: list[dict[str, Any]] = []
    if todo:
        with c.client_for(client) as cl:
            _trace(cl, tables, todo, out, per_chunk, force, progress, results, failed)
    frames = []
    for ti, t in enumerate(tables):
        if ti in results:
            df, _ = results[ti]
            df = df.copy()
            df.insert(0, "set", t.set)
            df.insert(0, "surface", t.surface)
            frames.append(df)
    result = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    result.attrs["tables"] = [results[ti][1] for ti in range(len(tables)) if ti in results]
    if failed:
        raise SweepError(failed, result)
    return result


class SweepError(RuntimeError):
    """Chunks of some tables failed (their workers died more often than Dask
    retries, or the tracing failed). The other tables are done (and written);
    ``result`` holds them as ``micro_sweep`` would return them, ``failed`` says
    which chunk of which table failed and why. A rerun traces only what is
    missing."""

    def __init__(self, failed: list[dict[str, Any]], result: pd.DataFrame) -> None:
        first = failed[0]
        super().__init__(
            f"micro_sweep: {len(failed)} chunk(s) failed; {first['table']} incident node "
            f"{first['incident']}, segment {first['segment']}: {first['error']}"
        )
        self.failed = failed
        self.result = result


def _trace(
    cl: Any,
    tables: list[Table],
    todo: list[int],
    out: str | None,
    per_chunk: int,
    force: bool,
    progress: bool,
    results: dict[int, tuple[pd.DataFrame, dict[str, Any]]],
    failed: list[dict[str, Any]],
) -> None:
    """Submits every chunk of the tables ``todo`` and merges each table as soon as
    its last chunk is in (its chunks then leave the workers' and this process's
    memory)."""
    from distributed import as_completed

    futures: dict[Any, tuple[int, int, int]] = {}
    missing: dict[int, int] = {}
    for ti in todo:
        t = tables[ti]
        parts_dir = None if out is None else _parts_dir(out, t)
        if parts_dir is not None:
            os.makedirs(parts_dir, exist_ok=True)
        for inc in range(t.incidents):
            for first in range(0, t.segments, per_chunk):
                end = min(first + per_chunk, t.segments)
                cache = (
                    None
                    if parts_dir is None or force
                    else os.path.join(parts_dir, f"{inc}-{first}-{end}.part")
                )
                f = cl.submit(
                    part_task,
                    t.words,
                    t.axis,
                    t.text,
                    inc,
                    first,
                    end,
                    cache,
                    key=f"gonio-micro-{t.name}-{inc}-{first}",
                )
                futures[f] = (ti, inc, first)
                missing[ti] = missing.get(ti, 0) + 1
    if progress:
        c.show_progress(list(futures))
    parts: dict[int, list[bytes]] = {ti: [] for ti in todo}
    broken: set[int] = set()
    for f in as_completed(list(futures)):
        ti, inc, first = futures.pop(f)
        try:
            part = f.result()
        except Exception as e:  # a worker lost too often, or the chunk's own failure
            failed.append(
                {
                    "table": tables[ti].name,
                    "incident": inc,
                    "segment": first,
                    "error": f"{type(e).__name__}: {e}",
                }
            )
            broken.add(ti)
            parts.pop(ti, None)
            continue
        finally:
            f.release()
        if ti in broken:
            continue
        parts[ti].append(part)
        missing[ti] -= 1
        if missing[ti] == 0:
            results[ti] = _merge(tables[ti], parts.pop(ti), out, force)
            if out is not None:
                shutil.rmtree(_parts_dir(out, tables[ti]), ignore_errors=True)
    if out is not None:
        # Gone once empty (another sweep into the same directory may still use it).
        with contextlib.suppress(OSError):
            os.rmdir(os.path.join(out, f"{c.TMP_PREFIX}parts"))


def _parts_dir(out: str, t: Table) -> str:
    """Where the chunks of ``t`` are kept until it is written."""
    return os.path.join(out, f"{c.TMP_PREFIX}parts", t.name)


def _describe(t: Table) -> dict[str, Any]:
    """What names a table in its record: this call's surface path, set and seed."""
    return {"name": t.name, "surface": t.surface, "set": t.set, "params": t.params, "seed": t.seed}


def _read_back(t: Table, out: str) -> tuple[pd.DataFrame, dict[str, Any]]:
    """A table done before, as the merge returned it."""
    # Every column of a table is a float; the CSV's whole-degree angles read as
    # integers otherwise.
    df = read_csv(os.path.join(out, t.name + ".csv")).astype("float64")
    with open(os.path.join(out, t.name + ".json"), encoding="utf-8") as f:
        report = json.load(f)
    # The same table may be asked for under another path or set index.
    return df, {**report, **_describe(t)}


def _merge(
    t: Table, parts: list[bytes], out: str | None, force: bool
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The table ``t`` from its parts (and written, with ``out``)."""
    csv = None if out is None else os.path.join(out, t.name + ".csv")
    # A CSV without its record is this sweep's own, from a run stopped between the
    # two writes: the same name holds the same bytes, so it is replaced.
    cols, sidecar, text = _native.micro_merge(
        t.words, t.axis, t.text, parts, out=csv, force=force or csv is not None
    )
    report = {**_describe(t), **json.loads(text)}
    if csv is not None and out is not None:
        report["file"] = os.path.basename(csv)
        c.write_atomic(
            os.path.join(out, t.name + ".json"),
            (json.dumps(report, indent=1, ensure_ascii=False) + "\n").encode(),
        )
    return to_frame(cols, sidecar), report


def load_sweep(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A sweep file (TOML): ``surfaces`` (paths relative to the file), ``seed``,
    ``chunk_rays`` and ``[[params]]`` tables; every other key is an error naming
    the file."""
    path = os.fspath(path)
    _, doc = _read_toml(path)
    allowed = {"surfaces", "seed", "chunk_rays", "params"}
    for key in doc:
        if key not in allowed:
            raise _native.ConfigError(f"{path}: unknown key {key!r}; keys: {sorted(allowed)}")
    surfaces = doc.get("surfaces")
    if (
        not isinstance(surfaces, list)
        or not surfaces
        or not all(isinstance(s, str) for s in surfaces)
    ):
        raise _native.ConfigError(f"{path}: `surfaces` must be a non-empty list of paths")
    params = doc.get("params")
    if not isinstance(params, list) or not params or not all(isinstance(p, dict) for p in params):
        raise _native.ConfigError(f"{path}: give one or more [[params]] tables")
    seed = doc.get("seed", 0)
    chunk = doc.get("chunk_rays", CHUNK_RAYS)
    for key, v in (("seed", seed), ("chunk_rays", chunk)):
        if not isinstance(v, int) or isinstance(v, bool) or v < (0 if key == "seed" else 1):
            raise _native.ConfigError(f"{path}: `{key}` must be a whole number, got {v!r}")
    base = os.path.dirname(os.path.abspath(path))
    return {
        "surfaces": [os.path.join(base, s) for s in surfaces],
        "params": params,
        "seed": seed,
        "chunk_rays": chunk,
    }


def incidents(df: pd.DataFrame) -> pd.DataFrame:
    """One row a (table, incident direction) of a sweep's ``attrs["tables"]``: the
    surface, set, seed, θi, φi and each channel's albedo with its standard error."""
    rows = []
    for t in df.attrs.get("tables", []):
        for a in t.get("albedo", []):
            row = {
                "surface": t["surface"],
                "set": t["set"],
                "seed": t["seed"],
                "table": t.get("file", t["name"]),
                "theta_i": a["theta_i_deg"],
                "phi_i": a["phi_i_deg"],
            }
            for ch, v, s in zip(t["channels"], a["albedo"], a["sigma"]):
                row[f"albedo_{ch}"] = v
                row[f"albedo_sigma_{ch}"] = s
            rows.append(row)
    return pd.DataFrame(rows)


__all__ = [
    "CHUNK_RAYS",
    "SEGMENT_RAYS",
    "SweepError",
    "incidents",
    "load_sweep",
    "micro_sweep",
    "plan",
]
