"""Fixtures of the package's tests: the repository, the ``gonio`` command (the
reference every result is held against: it runs the same crates in a process of
its own) and runs acquired once a session."""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import signal
import subprocess
from typing import Any

import pytest

import gonio

ROOT = pathlib.Path(__file__).resolve().parents[3]
CONFIG = ROOT / "config"


def gonio_bin() -> str:
    """The command: ``$GONIO_BIN``, else the test profile's build (``cargo test
    --profile ci`` makes it), else one built now."""
    env = os.environ.get("GONIO_BIN")
    if env:
        return env
    for profile in ("ci", "release"):
        p = ROOT / "target" / profile / "gonio"
        if p.exists():
            return str(p)
    subprocess.run(
        ["cargo", "build", "--profile", "ci", "-p", "gonio-cli", "--bin", "gonio"],
        cwd=ROOT,
        check=True,
    )
    return str(ROOT / "target" / "ci" / "gonio")


class Cli:
    """Runs ``gonio`` and returns what it printed."""

    def __init__(self) -> None:
        self.bin = gonio_bin()

    def run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        p = subprocess.run([self.bin, *map(str, args)], capture_output=True, text=True, cwd=ROOT)
        if check and p.returncode != 0:
            raise AssertionError(f"gonio {' '.join(map(str, args))}: {p.returncode}\n{p.stderr}")
        return p

    def acquire(self, plan: str, out: Any, seed: int) -> Any:
        """``gonio acquire`` of the simulated instrument with ``plan`` (a name in
        ``config/``) into ``out``: its ``--json`` object."""
        inst = CONFIG / "instrument-sim.toml"
        args = ("--instrument", inst, "--plan", CONFIG / plan, "--out", out, "--seed", seed)
        return self.json("acquire", *args)

    def json(self, *args: str) -> Any:
        return json.loads(self.run(*args, "--json").stdout)

    def error(self, *args: str) -> tuple[int, str]:
        """The exit status and the one-line reason of a failing command."""
        p = self.run(*args, check=False)
        assert p.returncode != 0, f"gonio {args} succeeded"
        line = p.stderr.strip().splitlines()[-1]
        return p.returncode, line.removeprefix("gonio: ")


@pytest.fixture(scope="session")
def cli() -> Cli:
    return Cli()


@pytest.fixture(scope="session")
def runs(tmp_path_factory: pytest.TempPathFactory, cli: Cli) -> dict[str, pathlib.Path]:
    """Simulated runs of the shipped configs, seed 3: ``py`` acquired through the
    package, ``cli`` by the command; ``inplane`` is a run of the in-plane plan."""
    d = tmp_path_factory.mktemp("runs")
    inst, plan = CONFIG / "instrument-sim.toml", CONFIG / "plan-hemisphere.toml"
    gonio.acquire(inst, plan, d / "py.gonio", seed=3, progress=False)
    cli.acquire("plan-hemisphere.toml", d / "cli.gonio", 3)
    gonio.acquire(inst, CONFIG / "plan-in-plane.toml", d / "inplane.gonio", seed=5, progress=False)
    return {"py": d / "py.gonio", "cli": d / "cli.gonio", "inplane": d / "inplane.gonio", "dir": d}


@pytest.fixture
def copy_run(runs: dict[str, pathlib.Path], tmp_path: pathlib.Path):
    """A copy of a run, to damage or extend."""

    def make(name: str = "py") -> pathlib.Path:
        dst = tmp_path / f"{name}-copy.gonio"
        shutil.copy(runs[name], dst)
        return dst

    return make


@pytest.fixture
def ctrl_c_raises():
    """Python's own SIGINT handler for the test, as a terminal or a notebook has it.
    A Python started with SIGINT ignored (a shell's `&` job, some CI runners) keeps it
    ignored, and `_thread.interrupt_main` then does nothing: the cause of the Ctrl-C tests'
    failures in background runs (issue 37)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
