#!/usr/bin/env python3
"""Run the workspace's test binaries side by side, as `cargo test` would one by one.

`cargo test` runs its 36 test binaries in sequence. The command line's integration
tests take two minutes, mostly waiting on simulated instruments and a browser, while a
core sits idle; the other binaries take another minute and a half. This runs up to
`--jobs` of them at once (each still runs its own tests on as many threads as cargo
would), the longest first, plus the doc tests and any further commands given with `--job NAME=COMMAND`
(scripts/test passes pytest, in two halves). Each job's output is kept and printed whole when it
ends, so nothing interleaves; the exit status is 1 if any job failed.

The binaries are the ones `cargo test --no-run` lists for the same arguments, so what
runs is what `cargo test --workspace --profile ci` runs. Durations are remembered in
target/ci/test-durations.json to order the next run.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CARGO = os.environ.get("CARGO", "cargo")
DURATIONS = ROOT / "target" / "ci" / "test-durations.json"
#: Test threads for binaries whose tests mostly wait in real time: the command line's
#: drive simulated instruments, signals and a browser (its 16 s SIGTERM test uses half
#: a second of CPU), so more of them at once than there are cores finish sooner.
THREADS = {"gonio-cli test it": 6}
#: Seconds, on 2 cores, for a run with no durations file yet.
FIRST_RUN = {"gonio-cli test it": 110.0, "pytest-1": 100.0, "pytest-2": 100.0}


@dataclass
class Job:
    """One process to run: a test binary, the doc tests, or an extra command."""

    name: str
    argv: list[str]
    cwd: Path
    env: dict[str, str] = field(default_factory=dict)


def test_binaries(profile: str) -> list[Job]:
    """The test executables `cargo test --workspace --profile PROFILE` would run."""
    out = subprocess.run(
        [CARGO, "test", "--workspace", "--profile", profile, "--no-run"]
        + ["--message-format=json-render-diagnostics"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        check=True,
        text=True,
    ).stdout
    jobs = []
    for line in out.splitlines():
        msg = json.loads(line)
        if msg.get("reason") != "compiler-artifact" or not msg.get("executable"):
            continue
        if not msg["profile"]["test"]:
            continue
        target = msg["target"]
        manifest = Path(msg["manifest_path"])
        name = f"{manifest.parent.name} {target['kind'][0]} {target['name']}"
        jobs.append(
            Job(
                name=name,
                argv=[msg["executable"], *threads(name)],
                cwd=manifest.parent,
                env={"CARGO_MANIFEST_DIR": str(manifest.parent)},
            )
        )
    return jobs


def threads(name: str) -> list[str]:
    """libtest's thread count for the binary `name`, when not the default."""
    n = THREADS.get(name)
    return (
        [f"--test-threads={n}"] if n and "RUST_TEST_THREADS" not in os.environ else []
    )


def run(job: Job, log: Path) -> tuple[Job, int, float]:
    """Runs `job` with its output to `log`; returns its status and wall time."""
    t0 = time.monotonic()
    with log.open("wb") as f:
        status = subprocess.run(
            job.argv,
            check=False,
            cwd=job.cwd,
            env={**os.environ, **job.env},
            stdout=f,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        ).returncode
    return job, status, time.monotonic() - t0


def summary(text: str) -> str:
    """The libtest result lines, or the last line, of a job's output."""
    lines = [ln for ln in text.splitlines() if ln.startswith("test result:")]
    if lines:
        return "; ".join(ln.removeprefix("test result: ") for ln in lines)
    tail = [ln for ln in text.splitlines() if ln.strip()]
    return tail[-1] if tail else ""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--profile", default="ci")
    parser.add_argument("--jobs", type=int, default=3, help="processes at once (3)")
    parser.add_argument(
        "--job",
        action="append",
        default=[],
        metavar="NAME=COMMAND",
        help="a further command to run with the tests (shell words), repeatable",
    )
    args = parser.parse_args()

    jobs = test_binaries(args.profile)
    jobs.append(
        Job(
            "doc tests",
            [CARGO, "test", "--workspace", "--profile", args.profile, "--doc"],
            ROOT,
        )
    )
    for spec in args.job:
        name, sep, command = spec.partition("=")
        if not sep or not command.strip():
            parser.error(f"--job {spec!r}: expected NAME=COMMAND")
        jobs.append(Job(name, shlex.split(command), ROOT))
    try:
        known = json.loads(DURATIONS.read_text())
    except (OSError, ValueError):
        known = {}
    # The longest first, so that the last to finish started early: by the last run's
    # times, or on a first run by what they were when this was written.
    jobs.sort(key=lambda j: -known.get(j.name, FIRST_RUN.get(j.name, 0.0)))

    failed = []
    times = {}
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="gonio-tests-") as tmp:
        logs = {j.name: Path(tmp) / f"{i}.log" for i, j in enumerate(jobs)}
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            futures = [pool.submit(run, j, logs[j.name]) for j in jobs]
            for fut in as_completed(futures):
                job, status, secs = fut.result()
                times[job.name] = round(secs, 1)
                text = logs[job.name].read_text(errors="replace")
                if status != 0:
                    failed.append(job.name)
                    print(f"---- {job.name}: FAILED (exit {status}, {secs:.1f} s)")
                    print(text, flush=True)
                else:
                    print(f"ok {job.name} ({secs:.1f} s): {summary(text)}", flush=True)
    DURATIONS.parent.mkdir(parents=True, exist_ok=True)
    DURATIONS.write_text(json.dumps({**known, **times}, indent=1, sort_keys=True))
    total = time.monotonic() - t0
    if failed:
        print(
            f"{len(failed)} of {len(jobs)} failed in {total:.0f} s: {', '.join(failed)}"
        )
        return 1
    print(f"all {len(jobs)} test jobs passed in {total:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
