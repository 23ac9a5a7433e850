"""What reprocessing and sweeps share: the Dask client, content hashes, options as
command-line words, and outputs published whole or not at all."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import uuid
from collections.abc import Iterator, Mapping
from typing import Any

from gonio import _native
from gonio._frame import write_atomic

#: Hidden working names in an output directory: a task's files before they are
#: published, and the chunks of a sweep kept for a rerun.
TMP_PREFIX = ".tmp-"


def cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


@contextlib.contextmanager
def client_for(
    client: Any = None, scheduler: str | None = None, workers: int | None = None
) -> Iterator[Any]:
    """The Dask client to submit to: ``client`` as given; else a client of the
    scheduler at ``scheduler`` (``tcp://host:8786``); else the embedded default, a
    ``LocalCluster`` of worker processes on the loopback interface, one a core
    (``workers`` overrides), one thread each, closed at the end."""
    if client is not None:
        yield client
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ImportError(
            "gonio.batch needs Dask distributed: pip install 'gonio[batch]' "
            "(dask[distributed] and bokeh)"
        ) from None

    if scheduler:
        c = Client(scheduler)
        try:
            yield c
        finally:
            c.close()
        return
    cluster = LocalCluster(
        host="127.0.0.1",
        n_workers=workers or cores(),
        threads_per_worker=1,
        processes=True,
        dashboard_address="127.0.0.1:0",
    )
    c = Client(cluster)
    try:
        yield c
    finally:
        c.close()
        cluster.close()


def sha256_file(*paths: str) -> str:
    """SHA-256 of the bytes of ``paths`` that exist, in order."""
    h = hashlib.sha256()
    for p in paths:
        if os.path.exists(p):
            with open(p, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    h.update(block)
    return h.hexdigest()


def run_digest(path: str) -> str:
    """The content hash of a run file: its bytes, and those of its write-ahead log
    when one is beside it (a live run, or one whose writer was killed: what a
    reader sees includes it)."""
    return sha256_file(path, path + "-wal")


def canonical(value: Any) -> str:
    """``value`` as canonical JSON (sorted keys, no spaces): the same options give
    the same text, and so the same output names, on any machine."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=True)


def short_hash(*parts: str) -> str:
    """16 hex digits of SHA-256 over ``parts``."""
    h = hashlib.sha256()
    for p in parts:
        h.update(p.encode())
        h.update(b"\0")
    return h.hexdigest()[:16]


def flag_words(name: str, value: Any) -> list[str]:
    """The command-line words of one option, by its keyword: ``lobes=2`` →
    ``--lobes 2``, ``anisotropic=True`` → ``--anisotropic`` (``False``: none),
    ``k=[1, 5]`` → ``--k 1,5``, ``grid=(10, 15)`` → ``--grid 10,15``."""
    flag = "--" + name.replace("_", "-")
    if isinstance(value, bool):
        return [flag] if value else []
    if isinstance(value, (list, tuple)):
        return [flag, ",".join(_word(v) for v in value)]
    return [flag, _word(value)]


def _word(v: Any) -> str:
    if isinstance(v, float):
        return repr(v)
    return str(v)


def takes(words: list[str], flag: list[str]) -> bool:
    """Whether the command of ``words`` takes the option ``flag`` (its parser is
    asked); an option it takes with a bad value raises its message."""
    try:
        _native.validate(words + flag)
    except _native.InputError as e:
        # Only the option itself unknown: a value it refuses is the value's error.
        if f"unexpected argument '{flag[0]}'" in str(e):
            return False
        raise
    return True


def strip(value: Any, keys: frozenset[str] = frozenset({"seconds"})) -> Any:
    """``value`` without the keys in ``keys`` at any depth: wall times, which would
    make two runs of the same work differ."""
    if isinstance(value, dict):
        return {k: strip(v, keys) for k, v in value.items() if k not in keys}
    if isinstance(value, list):
        return [strip(v, keys) for v in value]
    return value


def write_json(path: str, value: Any) -> None:
    """Writes ``value`` as indented JSON, durably (synced before it is published)."""
    with open(path, "w", encoding="utf-8") as f:
        json.dump(value, f, indent=1, ensure_ascii=False)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())


def new_token() -> str:
    """A call's own mark on its hidden working names, so that it cleans up only
    after itself (another batch may be writing to the same directory)."""
    return uuid.uuid4().hex[:12]


def work_dir(out_dir: str, token: str, name: str) -> str:
    """A fresh hidden directory in ``out_dir`` for one attempt at ``name``: a
    retried task (its worker killed) never meets the files of the first attempt."""
    d = os.path.join(out_dir, f"{TMP_PREFIX}{token}-{name}-{uuid.uuid4().hex[:12]}")
    os.mkdir(d)
    return d


def _fsync_dir(path: str) -> None:
    """Makes a directory's entries durable (best effort: not every platform can)."""
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def publish(tmp: str, final: str, complete: str, replace: bool = False) -> bool:
    """Renames the finished directory ``tmp`` to ``final``: atomic, a reader sees all
    of it or none. ``complete`` names the file that marks a directory whole.

    False when a whole ``final`` is there already (another attempt at the same
    work finished first; its files are the same): ``tmp`` is then removed. A
    ``final`` without its ``complete`` file (left by a crash before its files
    were durable), or any ``final`` when ``replace``, is moved aside first and
    removed after the new one is in place."""
    _fsync_dir(tmp)
    parent = os.path.dirname(final) or "."
    old = None
    if os.path.isdir(final) and (replace or not os.path.exists(os.path.join(final, complete))):
        old = f"{tmp}-old"
        with contextlib.suppress(FileNotFoundError):
            os.rename(final, old)
    try:
        os.rename(tmp, final)
    except OSError:
        if os.path.exists(os.path.join(final, complete)):
            shutil.rmtree(tmp, ignore_errors=True)
            return False
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    _fsync_dir(parent)
    return True


def clean_work(out_dir: str, token: str) -> None:
    """Removes what this call's attempts left behind in ``out_dir`` (a worker
    killed mid-task)."""
    for entry in os.scandir(out_dir):
        if entry.name.startswith(f"{TMP_PREFIX}{token}-"):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                with contextlib.suppress(FileNotFoundError):
                    os.remove(entry.path)


def safe_stem(path: str) -> str:
    """The file's name without its extension, as the start of an output's name:
    never hidden (so never taken for a working name)."""
    stem = os.path.splitext(os.path.basename(path))[0].lstrip(".")
    return stem or "run"


def show_progress(futures: list[Any]) -> None:
    """Dask's progress bar of ``futures`` on the terminal, drawn by a thread of its
    own while the caller collects the results as they come."""
    import threading

    from distributed import progress

    if futures:
        threading.Thread(
            target=progress, args=(futures,), kwargs={"notebook": False}, daemon=True
        ).start()


def gather(client: Any, futures: Mapping[Any, Any], progress: bool) -> dict[Any, Any]:
    """Waits for ``futures`` (label → future) and returns label → result, or the
    exception of one that failed (a worker lost more often than Dask retries):
    a failure never stops the others. ``progress`` shows Dask's progress bar."""
    from distributed import as_completed

    if progress:
        show_progress(list(futures.values()))
    by_future = {f: label for label, f in futures.items()}
    out: dict[Any, Any] = {}
    for f in as_completed(list(futures.values())):
        label = by_future[f]
        try:
            out[label] = f.result()
        except Exception as e:  # a KilledWorker, or the task's own failure
            out[label] = e
    return out


__all__ = ["write_atomic"]
