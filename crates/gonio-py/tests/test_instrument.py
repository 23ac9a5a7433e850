"""The simulator on pseudo-terminals, and acquisitions: the instruments' bytes,
the safe stop on Ctrl-C, resuming with nothing lost or measured twice, and faults
and bad inputs refused as the command refuses them."""

from __future__ import annotations

import _thread
import os
import select
import sqlite3
import threading
import time
import tty

import pytest

import gonio
from conftest import CONFIG

INSTRUMENT = CONFIG / "instrument-sim.toml"
PLAN = CONFIG / "plan-hemisphere.toml"


def exchange(path: str, data: bytes, end: bytes) -> bytes:
    """Writes `data` to a serial port and reads until `end` (3 s at most)."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    try:
        tty.setraw(fd)
        os.write(fd, data)
        buf, t0 = b"", time.monotonic()
        while not buf.endswith(end) and time.monotonic() - t0 < 3.0:
            if select.select([fd], [], [], 0.1)[0]:
                buf += os.read(fd, 256)
        return buf
    finally:
        os.close(fd)


def test_the_simulator_speaks_the_instruments_bytes():
    with gonio.Simulator(seed=4) as sim:
        assert sim.serving and sim.seed == 4 and set(sim.ports) == {"motion", "detector"}
        # SMC100: not referenced after power-up (state 0A), no positioner error.
        assert exchange(sim.ports["motion"], b"1TS\r\n", b"\r\n") == b"1TS00000A\r\n"
        assert exchange(sim.ports["motion"], b"2VE\r\n", b"\r\n").startswith(b"2VESMC_PP")
        # SR830: silent on RS-232 until OUTX 0 sends the replies there.
        idn = exchange(sim.ports["detector"], b"OUTX 0\r*IDN?\r", b"\r")
        assert idn.startswith(b"Stanford_Research_Systems,SR830,")
        ports = dict(sim.ports)
    assert not sim.serving
    assert not any(os.path.exists(p) for p in ports.values())
    sim.close()  # idempotent


def test_a_bad_simulator_config_is_the_commands_error(cli, tmp_path):
    bad = tmp_path / "sim.toml"
    bad.write_text((CONFIG / "sim-example.toml").read_text().replace("seed = 1", "seed = -1"))
    with pytest.raises(gonio.ConfigError) as e:
        gonio.Simulator(bad)
    code, line = cli.error("sim", "--config", bad)
    assert (str(e.value), e.value.exit_code) == (line, code)


def slow_sim(tmp_path, scale: float):
    """The example simulator config, running at `scale` wall seconds per physical
    second (the hemisphere plan is about 2700 physical seconds)."""
    p = tmp_path / "slow.toml"
    text = (CONFIG / "sim-example.toml").read_text()
    p.write_text(text.replace("time_scale = 0.0", f"time_scale = {scale}"))
    return p


def test_ctrl_c_stops_safely_and_resume_loses_nothing(tmp_path, ctrl_c_raises):
    out = tmp_path / "run.gonio"
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        gonio.acquire(INSTRUMENT, PLAN, out, seed=3, progress=False, sim=slow_sim(tmp_path, 0.001))
    # Stopped within a poll or two of the interrupt, with the stages stopped.
    assert time.monotonic() - t0 < 3.0
    run = gonio.open_run(out)
    taken = len(run.readings())
    assert run.status == "interrupted" and 0 < taken < run.summary["steps"]
    assert run.summary["sessions"][0]["outcome"] == "interrupted"
    assert run.events()["kind"].iloc[-1] == "stop"
    run = gonio.resume(out, progress=False)
    assert run.status == "complete" and run.session["status"] == "complete"
    df = run.readings()
    con = sqlite3.connect(f"file:{out}?mode=ro", uri=True)
    steps = [r[0] for r in con.execute("SELECT id FROM steps ORDER BY id")]
    # Every step measured exactly once; the readings of the first session kept.
    assert list(df["step_id"]) == steps
    assert run.session["measured"] == len(steps) - taken
    assert sorted(set(df["session"])) == [1, 2]


def test_acquisition_faults_and_bad_inputs(cli, tmp_path, runs):
    # An existing run file is never written onto.
    with pytest.raises(gonio.RunFileError) as e:
        gonio.acquire(INSTRUMENT, PLAN, runs["py"], progress=False)
    code, line = cli.error(
        "acquire", "--instrument", INSTRUMENT, "--plan", PLAN, "--out", runs["py"]
    )
    assert (str(e.value), e.value.exit_code) == (line, code)
    # A bad plan is refused before anything is created.
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.read_text() + "\nbogus = 1\n")
    out = tmp_path / "x.gonio"
    with pytest.raises(gonio.ConfigError) as e:
        gonio.acquire(INSTRUMENT, plan, out, progress=False)
    assert (
        str(e.value)
        == cli.error("acquire", "--instrument", INSTRUMENT, "--plan", plan, "--out", out)[1]
    )
    assert not out.exists()
    # A controller that never answers a position query: a fault, the run resumable.
    sim = tmp_path / "deaf.toml"
    sim.write_text((CONFIG / "sim-example.toml").read_text() + '\n[faults]\nsilent = ["1TP"]\n')
    with pytest.raises(gonio.InstrumentError, match="fault") as e:
        gonio.acquire(INSTRUMENT, PLAN, out, progress=False, sim=sim)
    assert e.value.exit_code == 1
    assert gonio.open_run(out).status == "faulted"
