"""Third-party clients against the simulated instruments, unmodified.

The simulator speaks the instruments' own bytes on pseudo-terminals, so public Python
drivers written for the real hardware drive its twins as they would the devices:

- ``thorlabs-apt-device`` (PyPI) drives the simulated KDC101 + PRM1-Z8 as it would
  the K-Cube on a USB port: it opens the port, homes, moves absolute and relative,
  follows the status it polls, reads the velocity parameters, moves at velocity and
  stops.
- ``hvl_ccb``'s ``NewportSMC100PP`` (ETH Zurich's High Voltage Lab, PyPI 0.19.6)
  drives the simulated SMC100PP: at start it reads ``TS`` and the ``ZT`` dump line by
  line against the exact lines an SMC100PP lists (``PW1 ID AC BA BH FRM FRS HT JR OH
  OT QIL SA SL SR VA VB ZX PW0``) and compares every value with its own
  configuration, writes its configuration in CONFIGURATION (``PW1`` … ``PW0``) where
  they differ, homes (``OR``) and polls ``TS`` until READY from HOMING; then it moves
  with ``PA``/``PR``, reads ``TP`` and stops with a broadcast ``ST``, every command
  followed by ``TE``.
"""

from __future__ import annotations

import json
import pathlib
import subprocess
import time

import pytest

from conftest import gonio_bin

thorlabs = pytest.importorskip("thorlabs_apt_device.devices")
newport = pytest.importorskip("hvl_ccb.dev.newport")

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


# Wall seconds per simulated second.
TIME_SCALE = 0.1


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
            str(TIME_SCALE),
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


# The SMC100 twin's step (ControllerConfig::counts_per_unit): TP reports multiples of
# 1/2000 of a unit.
SMC_STEP = 1 / 2000


def hvl_config(velocity: float) -> dict:
    """hvl_ccb's configuration of controller 1: the twin's factory configuration
    (config/sim-mixed.toml leaves controller 1 at the defaults), with `velocity`."""
    return {
        "address": 1,
        "user_position_offset": 0,  # positions are the controller's own
        "screw_scaling": 1,
        # PW0 keeps the controller silent while it saves (the twin: the manual's
        # "up to 10 seconds", p. 44); hvl_ccb asks TE after this wait.
        "exit_configuration_wait_sec": 10 * TIME_SCALE + 1.0,
        "move_wait_sec": 0.1,
        "home_search_polling_interval": 0.1,
        "acceleration": 160,
        "backlash_compensation": 0,
        "hysteresis_compensation": 0,
        "micro_step_per_full_step_factor": 100,
        "motion_distance_per_full_step": 0.05,
        "home_search_type": 2,  # MZ switch only
        "jerk_time": 0.04,
        "home_search_velocity": 10,
        "home_search_timeout": 60,
        "peak_output_current_limit": 1.0,
        "rs485_address": 2,
        "negative_software_limit": -170,
        "positive_software_limit": 170,
        "velocity": velocity,
        "base_velocity": 0,
        "stage_configuration": 3,  # ESP stage check enabled
    }


@pytest.mark.parametrize(
    "velocity",
    [
        40,  # the twin's factory value: hvl_ccb finds its configuration and homes
        30,  # a different one: hvl_ccb writes it (PW1, each set and TE, PW0) first
    ],
)
def test_hvl_ccb_drives_the_simulated_smc100pp(simulator, velocity):
    ready = newport.NewportStates.READY
    dev = newport.NewportSMC100PP({"port": simulator["motion"], "timeout": 5}, hvl_config(velocity))
    try:
        dev.start()
        assert dev.get_state() is dev.StateMessages.READY_FROM_HOMING
        # The dump matches hvl_ccb's configuration exactly, line for line.
        assert dev.get_motor_configuration() == dev.config.motor_config
        assert dev.get_motor_configuration()["velocity"] == velocity
        assert dev.get_position() == pytest.approx(0, abs=SMC_STEP)

        # PA: a profiled move, then READY from MOVING where it was sent.
        dev.move_to_absolute_position(30.0)
        wait_for(lambda: dev.get_state().state == ready)
        assert dev.get_state() is dev.StateMessages.READY_FROM_MOVING
        assert dev.get_position() == pytest.approx(30.0, abs=SMC_STEP)

        # PR: from the current target.
        dev.move_to_relative_position(-12.5)
        wait_for(lambda: dev.get_state().state == ready)
        assert dev.get_position() == pytest.approx(17.5, abs=SMC_STEP)

        # A long move stopped on the way with the broadcast ST: the stage ends
        # between where it started and its target, and stays there.
        dev.move_to_absolute_position(-150.0)
        wait_for(lambda: dev.get_position() < -20)
        dev.stop_motion()
        wait_for(lambda: dev.get_state().state == ready)
        stopped = dev.get_position()
        assert -150.0 < stopped < -20
        time.sleep(0.3)
        assert dev.get_position() == stopped

        # ST and TE in READY, then the port closes.
        dev.stop()
        assert not dev.com.is_open
    finally:
        if dev.com.is_open:
            dev.com.close()
