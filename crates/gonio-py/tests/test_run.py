"""Run files: opened, read and reduced by the package, held against the command
line's output on the same file and against SQLite read directly."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pandas as pd
import pytest

import gonio


def test_meta_and_summary_are_gonio_show(runs, cli):
    run = gonio.open_run(runs["py"])
    assert run.summary == cli.json("show", runs["py"])
    m = run.meta
    assert (m["name"], m["status"], m["seed"]) == ("isotropic hemisphere", "complete", 3)
    assert m["software"].startswith("gonio ")
    # The configs are parsed: the plan's own fields, the instrument's ports.
    assert m["plan"]["name"] == m["name"]
    assert m["instrument"]["motion"]["port"] == "sim"
    assert m["sim"]["seed"] == 1 and m["keys"]["status"] == "complete"
    assert run.status == "complete"


def test_the_package_and_the_command_acquire_the_same_readings(runs):
    """Same seed, same engine: identical readings but for the clocks."""
    a = gonio.open_run(runs["py"]).readings()
    b = gonio.open_run(runs["cli"]).readings()
    clocks = ["wall_s", "session"]
    pd.testing.assert_frame_equal(a.drop(columns=clocks), b.drop(columns=clocks), check_exact=True)


def test_readings_are_every_column_of_the_file(runs):
    run = gonio.open_run(runs["py"])
    df = run.readings()
    con = sqlite3.connect(f"file:{runs['py']}?mode=ro", uri=True)
    cols = [r[1] for r in con.execute("PRAGMA table_info(readings)") if r[1] != "crc"]
    assert list(df.columns[: len(cols)]) == cols
    rows = con.execute(f"SELECT {', '.join(cols)} FROM readings ORDER BY step_id").fetchall()
    assert len(df) == len(rows) == run.summary["states"]["done"]
    for j, name in enumerate(cols):
        want = np.array([np.nan if r[j] is None else r[j] for r in rows], dtype=float)
        np.testing.assert_array_equal(df[name].to_numpy(dtype=float), want, err_msg=name)
    steps = con.execute(
        "SELECT kind, channel, repeat, plan_index, theta_o FROM steps s "
        "WHERE id IN (SELECT step_id FROM readings) ORDER BY id"
    ).fetchall()
    assert list(df["kind"]) == [s[0] for s in steps]
    assert list(df["channel"]) == [s[1] for s in steps]
    assert [None if pd.isna(x) else int(x) for x in df["plan_index"]] == [s[3] for s in steps]
    np.testing.assert_array_equal(
        df["planned_theta_o"].to_numpy(),
        np.array([np.nan if s[4] is None else s[4] for s in steps]),
    )
    # Dark and calibration readings carry no plan index; samples do.
    assert df.loc[df["kind"] == "sample", "plan_index"].notna().all()
    assert df.loc[df["kind"] == "dark", "plan_index"].isna().all()


def test_events_are_the_files(runs):
    ev = gonio.open_run(runs["py"]).events()
    con = sqlite3.connect(f"file:{runs['py']}?mode=ro", uri=True)
    rows = con.execute("SELECT wall_s, kind, step_id, message FROM events ORDER BY id").fetchall()
    assert list(ev["kind"]) == [r[1] for r in rows]
    assert list(ev["message"]) == [r[3] for r in rows]
    np.testing.assert_array_equal(ev["wall_s"].to_numpy(), [r[0] for r in rows])
    assert ev["kind"].iloc[0] == "start" and ev["time"].dt.tz is not None


@pytest.mark.parametrize("name", ["py", "inplane"])
def test_reduce_is_gonio_reduce(runs, cli, tmp_path, name):
    """The same columns, units and values as the CSV `gonio reduce` writes, read by
    pandas; the same sidecar; the same account of the reduction."""
    out = tmp_path / "r.csv"
    report = cli.json("reduce", runs[name], "--out", out)
    want = pd.read_csv(out)
    got = gonio.open_run(runs[name]).reduce()
    # pandas reads whole degrees written as `30` as integers; the values are equal.
    pd.testing.assert_frame_equal(got, want, check_exact=True, check_dtype=False)
    assert (got.dtypes == "float64").all()
    assert got.attrs["gonio"] == json.loads((tmp_path / "r.csv.json").read_text())
    assert got.attrs["reduction"] == report["reduction"]
    assert got["sigma_per_sr"].gt(0).all()


def test_reduce_options_are_the_commands(runs, cli, tmp_path):
    out = tmp_path / "r.csv"
    cli.run("reduce", runs["py"], "--out", out, "--drift", "none")
    got = gonio.open_run(runs["py"]).reduce(drift="none")
    pd.testing.assert_frame_equal(got, pd.read_csv(out), check_exact=True, check_dtype=False)
    assert not got.equals(gonio.open_run(runs["py"]).reduce())
    # A grid the samples do not cover is refused with the command's message.
    with pytest.raises(gonio.DataError) as e:
        gonio.open_run(runs["py"]).reduce(grid=(15, 30))
    code, line = cli.error("reduce", runs["py"], "--out", out, "--grid", "15,30", "--force")
    assert (str(e.value), e.value.exit_code) == (line, code)
    with pytest.raises(gonio.InputError) as e:
        gonio.open_run(runs["py"]).reduce(calibration="moon")
    code, line = cli.error(
        "reduce", runs["py"], "--out", tmp_path / "x.csv", "--calibration", "moon"
    )
    assert str(e.value) == line and e.value.exit_code == code == 2


def test_missing_foreign_and_damaged_files_are_refused_as_the_command_does(
    runs, cli, tmp_path, copy_run
):
    missing = tmp_path / "none.gonio"
    with pytest.raises(gonio.RunFileError) as e:
        gonio.open_run(missing)
    code, line = cli.error("show", missing)
    assert (str(e.value), e.value.exit_code) == (line, code)

    text = tmp_path / "text.gonio"
    text.write_text("not a run\n")
    with pytest.raises(gonio.RunFileError) as e:
        gonio.open_run(text)
    assert str(e.value) == cli.error("show", text)[1]

    damaged = copy_run()
    con = sqlite3.connect(damaged)
    con.execute(
        "UPDATE readings SET r_mean = r_mean * 1.01 WHERE step_id = "
        "(SELECT min(step_id) FROM readings WHERE r_mean > 0)"
    )
    con.commit()
    con.close()
    with pytest.raises(gonio.RunFileError) as e:
        gonio.open_run(damaged)
    assert str(e.value) == cli.error("show", damaged)[1]
    assert "checksum" in str(e.value) or "integrity" in str(e.value)
    assert isinstance(e.value, gonio.GonioError)


@pytest.mark.parametrize("name", ["py", "inplane"])
def test_reduce_carries_the_covariance(runs, name):
    """Each row of the reduction's covariance (in the sidecar, ``df.attrs["gonio"]``)
    names a sample's directions; its independent σ and its coefficients on the shared
    errors add in quadrature to that sample's σ, so a user can form the full χ²."""
    df = gonio.open_run(runs[name]).reduce()
    cov = df.attrs["gonio"]["covariance"]
    assert cov == df.attrs["reduction"]["covariance"]
    sources = cov["sources"]
    assert {s["term"] for s in sources} >= {"dark", "calibration"}
    ind = np.array([row[0] for row in cov["independent"]])
    coef = np.array(cov["coefficients"])
    total = np.sqrt(ind**2 + (coef**2).sum(axis=1))
    key = lambda ti, pi, to, po: (round(ti, 6), round(to, 6), round((po - pi) % 360.0, 6))  # noqa: E731
    by_dir = {key(*d): s for d, s in zip(cov["directions"], total)}
    phi_i = df["phi_i_deg"] if "phi_i_deg" in df else 0.0 * df["theta_i_deg"]
    rows = zip(df["theta_i_deg"], phi_i, df["theta_o_deg"], df["phi_o_deg"], df["sigma_per_sr"])
    matched = 0
    for ti, pi, to, po, sigma in rows:
        k = key(ti, pi, to, po)
        if k in by_dir:
            assert by_dir[k] == pytest.approx(sigma, rel=1e-9)
            matched += 1
    assert matched == len(cov["directions"])
