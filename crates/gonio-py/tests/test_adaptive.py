"""Adaptive plans through the package: the run spends its budget, records each
batch as an event and a decision, and makes the command's choices exactly."""

from __future__ import annotations

import json
import sqlite3

import gonio
from conftest import CONFIG

INSTRUMENT = CONFIG / "instrument-sim.toml"
PLAN = """
[points]
kind = "adaptive"
theta_i = [30, 60]
budget = { points = 80 }
batch = 0.25
candidates = 1024
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"""


def decisions(path) -> list[tuple]:
    con = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    try:
        return con.execute(
            "SELECT id, first_step, steps, points, method, readings, detail "
            "FROM decisions ORDER BY id"
        ).fetchall()
    finally:
        con.close()


def test_an_adaptive_run_through_the_package_makes_the_commands_choices(cli, tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN)
    py = gonio.acquire(INSTRUMENT, plan, tmp_path / "py.gonio", seed=4, progress=False)
    assert py.status == "complete"
    cli.json(
        "acquire",
        "--instrument",
        INSTRUMENT,
        "--plan",
        plan,
        "--out",
        tmp_path / "cli.gonio",
        "--seed",
        4,
    )
    ours, theirs = decisions(tmp_path / "py.gonio"), decisions(tmp_path / "cli.gonio")
    assert ours == theirs and len(ours) >= 2
    # The budget, exactly: the coarse pass's points and every batch's.
    df = py.readings()
    points = df.loc[df["kind"] == "sample", "plan_index"].nunique()
    assert points == 80
    assert sum(d[3] for d in ours) == 80 - json.loads(ours[0][6])["points_before"]
    # Each batch is an event at its first step.
    ev = py.events()
    batches = ev[ev["kind"] == "batch"]
    assert list(batches["step_id"]) == [d[1] for d in ours]
    assert batches["message"].iloc[0].startswith(f"batch 1: {ours[0][3]} points")
