"""Third-party clients against the simulated instruments, unmodified.

The simulator speaks the instruments' own bytes on pseudo-terminals, so a public
Python driver of the Thorlabs APT protocol (``thorlabs-apt-device``, from PyPI)
drives the simulated KDC101 + PRM1-Z8 exactly as it would drive the K-Cube on a USB
port: it opens the port, homes, moves absolute and relative, follows the status it
polls, reads the velocity parameters, moves at velocity and stops.
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import time

import pytest

from conftest import gonio_bin

thorlabs = pytest.importorskip("thorlabs_apt_device.devices")

ROOT = pathlib.Path(__file__).resolve().parents[3]
# PRM1-Z8 on a KDC101: encoder counts per degree, and the APT velocity unit per
# deg/s (counts x T x 65536 with T = 2048 / 6e6 s), as the APT protocol manual's
# KDC101 scaling section gives them.
COUNTS_PER_DEG = 1919.6418
VELOCITY_PER_DEG_S = COUNTS_PER_DEG * 2048 / 6e6 * 65536


def wait_for(what, timeout_s: float = 30.0) -> None:
    """Polls `what()` until true; fails after `timeout_s`."""
    end = time.monotonic() + timeout_s
    while not what():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


@pytest.fixture
def simulator():
    """`gonio sim` on config/sim-mixed.toml, ten times faster than real time; yields
    its announcement (the pty paths)."""
    proc = subprocess.Popen(
        [
            gonio_bin(),
            "sim",
            "--config",
            str(ROOT / "config" / "sim-mixed.toml"),
            "--time-scale",
            "0.1",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert line, proc.stderr.read()
        yield json.loads(line)
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def settled(dev) -> bool:
    s = dev.status
    return not (s["moving_forward"] or s["moving_reverse"] or s["homing"])


def test_a_public_apt_client_drives_the_simulated_kdc101(simulator):
    # The APT lines in the layout's role order: sample_rot (the KDC101), sample_tilt.
    port = simulator["apt"][0]
    dev = thorlabs.KDC101(serial_port=port, home=True)
    try:
        # Homing: the counter is zero at home.
        wait_for(lambda: dev.status["homed"] and settled(dev))
        assert dev.status["position"] == 0
        # The velocity parameters it asked for at open: the twin's 20 deg/s, 20 deg/s².
        wait_for(lambda: dev.velparams["max_velocity"] > 0)
        assert dev.velparams["max_velocity"] == pytest.approx(20 * VELOCITY_PER_DEG_S, rel=1e-4)

        target = round(30 * COUNTS_PER_DEG)
        dev.move_absolute(target)
        wait_for(lambda: dev.status["position"] != 0)
        wait_for(lambda: settled(dev) and abs(dev.status["position"] - target) <= 1)

        dev.move_relative(round(-10 * COUNTS_PER_DEG))
        back = target + round(-10 * COUNTS_PER_DEG)
        wait_for(lambda: settled(dev) and abs(dev.status["position"] - back) <= 1)

        # At velocity, then a profiled stop: the stage ends beyond where it started and
        # stays there.
        dev.move_velocity("forward")
        wait_for(lambda: abs(dev.status["position"] - back) > 5 * COUNTS_PER_DEG)
        dev.stop()
        wait_for(lambda: settled(dev))
        stopped = dev.status["position"]
        time.sleep(0.3)
        assert dev.status["position"] == stopped
        assert abs(stopped - back) > 5 * COUNTS_PER_DEG
    finally:
        dev.close()
        # The client's event loop ends on its own thread; let it, before the
        # simulator's ptys go away under its last poll.
        time.sleep(0.5)
