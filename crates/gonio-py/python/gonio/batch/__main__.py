"""``python -m gonio.batch``: reprocess run files, or run a microgeometry sweep, on
a Dask cluster (the embedded ``LocalCluster``, or ``--scheduler ADDR``).

Exit status: 0 when everything was done, 1 when some run or chunk failed (the
others are done; the summary says which), 2 for bad input (nothing was started),
130 when stopped by SIGINT, SIGTERM or SIGHUP (finished outputs are kept; the same
command continues from them).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
from typing import Any

from gonio import _native
from gonio.batch import _common as c
from gonio.batch._reprocess import STEPS, find_runs, reprocess, step_words
from gonio.batch._sweep import SweepError, incidents, load_sweep, micro_sweep, plan


def _value(text: str) -> Any:
    """An option's value from ``KEY=VALUE``: JSON when it parses (numbers, true,
    lists), else the text."""
    try:
        return json.loads(text)
    except ValueError:
        return text


def _options(pairs: list[str]) -> dict[str, Any]:
    out = {}
    for p in pairs:
        key, sep, value = p.partition("=")
        if not sep or not key:
            raise ValueError(f"--set {p!r}: give KEY=VALUE (a flag of the command, e.g. lobes=2)")
        out[key.strip().replace("-", "_")] = _value(value)
    return out


def _positive(text: str) -> int:
    n = int(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"at least 1, got {n}")
    return n


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m gonio.batch", description=__doc__)
    ap.add_argument("-v", "--verbose", action="count", default=0, help="log more (-vv: trace)")
    sub = ap.add_subparsers(dest="command", required=True)
    cluster = argparse.ArgumentParser(add_help=False)
    cluster.add_argument("--out", required=True, help="the output directory")
    cluster.add_argument(
        "--scheduler", help="a Dask scheduler's address (tcp://host:8786); default: a local cluster"
    )
    cluster.add_argument(
        "--workers",
        type=_positive,
        help="worker processes of the local cluster (default: one a core)",
    )
    cluster.add_argument("--force", action="store_true", help="redo outputs that exist")
    r = sub.add_parser(
        "reprocess", parents=[cluster], help="reduce, check, fit and report run files"
    )
    r.add_argument("runs", nargs="+", help="run files, directories of them, or glob patterns")
    r.add_argument(
        "--steps", default=",".join(STEPS), help=f"comma-separated, of {','.join(STEPS)}"
    )
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a flag of the steps' commands (lobes=2, drift=none, k=[1,5]); repeatable",
    )
    m = sub.add_parser("micro", parents=[cluster], help="a microgeometry sweep (SWEEP.toml)")
    m.add_argument("sweep", help="the sweep file: surfaces, seed, chunk_rays, [[params]]")
    return ap


def _dashboard(client: Any) -> None:
    link = getattr(client, "dashboard_link", None)
    print(f"gonio.batch: Dask scheduler {client.scheduler.address}", file=sys.stderr)
    if link:
        print(f"gonio.batch: dashboard {link}", file=sys.stderr)


def _stop(signum: int, _frame: Any) -> None:
    # SIGTERM and SIGHUP stop as Ctrl-C does: the cluster is closed, and what was
    # finished stays (every output is whole or absent).
    raise KeyboardInterrupt(signal.Signals(signum).name)


def main(argv: list[str] | None = None) -> int:
    a = _parser().parse_args(argv)
    _native.init_logging(a.verbose)
    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            signal.signal(sig, _stop)
    try:
        out = os.path.abspath(a.out)
        if os.path.exists(out) and not os.path.isdir(out):
            raise _native.InputError(f"{a.out}: exists and is not a directory")
        if a.command == "reprocess":
            steps = tuple(s for s in a.steps.split(",") if s)
            options = _options(a.set)
            runs = find_runs(a.runs)
            missing = [p for p in runs if not os.path.exists(p)]
            if missing:
                raise _native.InputError(f"{missing[0]}: no such run file")
            if not runs:
                raise _native.InputError(f"{' '.join(a.runs)}: no run files (*.gonio)")
            # Checked before any cluster starts (and again by reprocess).
            step_words(steps, options)
            with c.client_for(None, a.scheduler, a.workers) as cl:
                _dashboard(cl)
                df = reprocess(runs, out, cl, steps, force=a.force, progress=True, **options)
            index = os.path.join(out, "reprocess.csv")
            c.write_atomic(index, df.to_csv(index=False).encode())
            failed = df[df["status"] == "failed"]
            done = (df["status"] == "done").sum()
            skipped = (df["status"] == "skipped").sum()
            print(
                f"{len(df)} run(s): {done} done, {skipped} done before, {len(failed)} failed; "
                f"{index}"
            )
            for _, row in failed.iterrows():
                print(f"failed: {row['run']}: {row['error']}", file=sys.stderr)
            return 1 if len(failed) else 0
        sweep = load_sweep(a.sweep)
        try:
            plan(sweep["surfaces"], sweep["params"], sweep["seed"])
        except (_native.GonioError, ValueError, TypeError) as e:
            # The sweep file's tables are what `params[N]` counts.
            raise _native.ConfigError(f"{a.sweep}: {e}") from None
        failed: list[dict[str, Any]] = []
        with c.client_for(None, a.scheduler, a.workers) as cl:
            _dashboard(cl)
            try:
                df = micro_sweep(
                    sweep["surfaces"],
                    sweep["params"],
                    cl,
                    sweep["seed"],
                    out_dir=out,
                    chunk_rays=sweep["chunk_rays"],
                    force=a.force,
                    progress=True,
                )
            except SweepError as e:
                df, failed = e.result, e.failed
        index = os.path.join(out, "sweep.csv")
        c.write_atomic(index, incidents(df).to_csv(index=False).encode())
        print(f"{len(df.attrs['tables'])} table(s) in {out}; albedos by incidence: {index}")
        for f in failed:
            print(
                f"failed: {f['table']} incident node {f['incident']}, segment {f['segment']}: "
                f"{f['error']}",
                file=sys.stderr,
            )
        return 1 if failed else 0
    except (_native.InputError, ValueError, TypeError) as e:
        print(f"gonio.batch: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        # An output directory that cannot be made, a scheduler that cannot be reached.
        print(f"gonio.batch: {e}", file=sys.stderr)
        return 2
    except _native.GonioError as e:
        print(f"gonio.batch: {e}", file=sys.stderr)
        return e.exit_code
    except RuntimeError as e:
        print(f"gonio.batch: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as e:
        why = str(e) or "SIGINT"
        print(
            f"gonio.batch: {why}: stopped; finished outputs are kept, and the same "
            "command continues from them",
            file=sys.stderr,
        )
        return 130


if __name__ == "__main__":
    sys.exit(main())
