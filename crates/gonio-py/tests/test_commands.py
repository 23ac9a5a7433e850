"""colour, export, verify, report, plan.check, plan.compare and instrument.check:
the package's results held against the command's on the same inputs — the same
JSON, the same bytes — and bad inputs refused with the command's message."""

from __future__ import annotations

import json
import sqlite3

import pandas as pd
import pytest

import gonio
from conftest import CONFIG, ROOT

SPECTRA = ROOT / "crates" / "gonio-core" / "src" / "colour" / "testdata"
COLORCHECKER = SPECTRA / "colorchecker_babelcolor_avg.csv"
INSTRUMENT = CONFIG / "instrument-sim.toml"


def without(d, *keys):
    return {k: v for k, v in d.items() if k not in keys}


def damage(path):
    """Alters one reading behind the file's back (its checksum no longer holds)."""
    con = sqlite3.connect(path)
    con.execute(
        "UPDATE readings SET r_mean = r_mean * 1.01 WHERE step_id = "
        "(SELECT min(step_id) FROM readings WHERE r_mean > 0)"
    )
    con.commit()
    con.close()


# colour


def test_colour_is_gonio_colour(cli):
    for args in ((), ("--illuminant", "A", "--observer", "1964", "--adaptation", "none")):
        want = cli.json("colour", COLORCHECKER, *args)
        opts = dict(zip(("illuminant", "observer", "adaptation"), args[1::2]))
        df = gonio.colour(COLORCHECKER, **opts)
        assert df.attrs["colour"] == want
        assert list(df.index) == [s["name"] for s in want["spectra"]]
        for s in want["spectra"]:
            row = df.loc[s["name"]]
            assert [row["X"], row["Y"], row["Z"], row["x"], row["y"]] == [
                s["X"],
                s["Y"],
                s["Z"],
                s["x"],
                s["y"],
            ]
            assert [row["R_linear"], row["G_linear"], row["B_linear"]] == s["srgb_linear"]
            assert [row["R"], row["G"], row["B"]] == s["srgb"]
            assert row["hex"] == "#{:02x}{:02x}{:02x}".format(*s["srgb8"])
    # The white patch is nearly the illuminant's white, far from the black one.
    assert df.loc["white 9.5 (.05 D)", "Y"] > 0.8 > 0.05 > df.loc["black 2 (1.5 D)", "Y"]


def test_colour_of_a_dataframe_is_that_of_its_file(cli):
    spectra = pd.read_csv(COLORCHECKER, comment="#")
    want = cli.json("colour", COLORCHECKER, "--observer", "1964")
    got = gonio.colour(spectra, observer=1964)
    assert got.attrs["colour"] == {**want, "input": "DataFrame"}
    # The wavelengths may be the index.
    again = gonio.colour(spectra.set_index("wavelength_nm"), observer=1964)
    pd.testing.assert_frame_equal(got, again, check_exact=True)


def test_bad_spectra_are_refused_as_the_command_does(cli, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("wavelength_nm,a\n400,0.5\n410,oops\n")
    with pytest.raises(gonio.DataError) as e:
        gonio.colour(bad)
    code, line = cli.error("colour", bad)
    assert (str(e.value), e.value.exit_code) == (line, code)
    assert str(bad) in line and ":3:" in line
    with pytest.raises(gonio.InputError) as e:
        gonio.colour(COLORCHECKER, illuminant="D99")
    assert (str(e.value), e.value.exit_code) == cli.error(
        "colour", COLORCHECKER, "--illuminant", "D99"
    )[::-1]
    df = pd.DataFrame({"wavelength_nm": [400.0, 410.0], "a": [0.5, float("nan")]})
    with pytest.raises(gonio.DataError, match=r"^DataFrame:3: field `a`"):
        gonio.colour(df)
    with pytest.raises(TypeError):
        gonio.colour(42)


# export


@pytest.mark.parametrize("fmt", ["merl", "astm", "csv"])
def test_export_of_a_run_is_gonio_export(runs, cli, tmp_path, fmt):
    theirs, ours = tmp_path / f"cli.{fmt}", tmp_path / f"py.{fmt}"
    want = cli.json("export", runs["py"], "--format", fmt, "--out", theirs)
    got = gonio.export(gonio.open_run(runs["py"]), fmt, ours)
    assert without(got, "out") == without(want, "out") and got["out"] == str(ours)
    assert ours.read_bytes() == theirs.read_bytes()
    assert got["bytes"] == len(ours.read_bytes())
    # Without a file, the same bytes, and nothing written.
    assert gonio.export(runs["py"], fmt) == theirs.read_bytes()
    if fmt == "csv":
        side = ours.with_name(ours.name + ".json")
        assert side.read_bytes() == theirs.with_name(theirs.name + ".json").read_bytes()
    if fmt == "merl":
        # A half turn of an isotropic material, unfolded into the MERL table.
        assert got["symmetry"] == "isotropic-bilateral"


@pytest.fixture(scope="module")
def spectral(tmp_path_factory, cli):
    """A simulated spectral run (a band per step: wavelength channels)."""
    out = tmp_path_factory.mktemp("spectral") / "s.gonio"
    cli.json(
        "acquire",
        "--instrument",
        CONFIG / "instrument-spectral.toml",
        "--plan",
        CONFIG / "plan-spectral.toml",
        "--sim",
        CONFIG / "sim-spectral.toml",
        "--out",
        out,
    )
    return out


def test_export_of_wavelength_channels(spectral, cli, tmp_path):
    theirs, ours = tmp_path / "cli.csv", tmp_path / "py.csv"
    want = cli.json("export", spectral, "--format", "csv-long", "--out", theirs)
    got = gonio.export(spectral, "csv-long", ours)
    assert without(got, "out") == without(want, "out")
    assert ours.read_bytes() == theirs.read_bytes()
    side = ours.with_name(ours.name + ".json")
    assert side.read_bytes() == theirs.with_name(theirs.name + ".json").read_bytes()
    assert ours.read_text().startswith("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,")
    # MERL holds R, G, B: the wavelengths go through the colour conversion.
    merl = tmp_path / "cli.binary"
    want = cli.json("export", spectral, "--format", "merl", "--out", merl, "--observer", "1964")
    assert want["colour"] == "illuminant D65, CIE 1964 10° observer"
    assert gonio.export(spectral, "merl", observer=1964) == merl.read_bytes()


def test_export_of_a_dataframe_is_that_of_its_csv(runs, cli, tmp_path):
    csv = tmp_path / "r.csv"
    cli.run("reduce", runs["py"], "--out", csv)
    want = tmp_path / "cli.astm"
    cli.run("export", csv, "--format", "astm", "--out", want)
    df = gonio.open_run(runs["py"]).reduce()
    assert gonio.export(df, "astm") == want.read_bytes()


def test_export_refuses_as_the_command_does(runs, cli, tmp_path, copy_run):
    out = tmp_path / "x.astm"
    out.write_text("mine\n")
    with pytest.raises(gonio.InputError) as e:
        gonio.export(runs["py"], "astm", out)
    code, line = cli.error("export", runs["py"], "--format", "astm", "--out", out)
    assert (str(e.value), e.value.exit_code) == (line, code)
    assert type(e.value) is gonio.InputError and str(out) in line
    assert out.read_text() == "mine\n"
    gonio.export(runs["py"], "astm", out, force=True)
    assert out.read_bytes() == gonio.export(runs["py"], "astm")

    with pytest.raises(gonio.InputError) as e:
        gonio.export(runs["py"], "obj", tmp_path / "y")
    code, line = cli.error("export", runs["py"], "--format", "obj", "--out", tmp_path / "y")
    assert (str(e.value), e.value.exit_code) == (line, code)

    damaged = copy_run()
    damage(damaged)
    with pytest.raises(gonio.RunFileError) as e:
        gonio.export(damaged, "csv", tmp_path / "d.csv")
    code, line = cli.error("export", damaged, "--format", "csv", "--out", tmp_path / "d.csv")
    assert (str(e.value), e.value.exit_code) == (line, code)
    assert str(damaged) in line and not (tmp_path / "d.csv").exists()


# verify


def test_verify_is_gonio_verify(runs, cli, copy_run):
    want = cli.json("verify", runs["py"])
    assert gonio.verify(runs["py"]) == want == gonio.open_run(runs["py"]).verify()
    assert want["intact"] and want["faults"] == [] and want["readings"] > 0
    assert gonio.verify(runs["py"], check=True) == want

    damaged = copy_run()
    damage(damaged)
    p = cli.run("verify", damaged, "--json", check=False)
    assert p.returncode == 1
    want = json.loads(p.stdout)
    got = gonio.verify(damaged)
    assert got == want and not got["intact"] and got["faults"]
    with pytest.raises(gonio.RunFileError) as e:
        gonio.verify(damaged, check=True)
    code, line = cli.error("verify", damaged)
    assert (str(e.value), e.value.exit_code) == (line, code) and code == 1


def test_verify_refuses_what_is_not_a_run_file(cli, tmp_path):
    for path in (tmp_path / "none.gonio", tmp_path / "text.gonio"):
        if path.name == "text.gonio":
            path.write_text("not a run\n")
        with pytest.raises(gonio.RunFileError) as e:
            gonio.verify(path)
        code, line = cli.error("verify", path)
        assert (str(e.value), e.value.exit_code) == (line, code)
        assert str(path) in line


# report


def test_report_is_gonio_report(runs, cli, tmp_path):
    want = cli.json("report", runs["inplane"], "--out", tmp_path / "cli")
    page = (tmp_path / "cli" / "report.html").read_bytes()
    got = gonio.report(gonio.open_run(runs["inplane"]), tmp_path / "py")
    written = tmp_path / "py" / "report.html"
    assert got == {**want, "out": str(written)}
    assert written.read_bytes() == page
    # Without a directory: the same page, nothing written.
    html = gonio.open_run(runs["inplane"]).report()
    assert html.encode() == page and html.startswith("<!DOCTYPE html>")


def test_report_refuses_as_the_command_does(runs, cli, tmp_path, copy_run):
    out = tmp_path / "rep"
    gonio.report(runs["inplane"], out)
    with pytest.raises(gonio.InputError) as e:
        gonio.report(runs["inplane"], out)
    code, line = cli.error("report", runs["inplane"], "--out", out)
    assert (str(e.value), e.value.exit_code) == (line, code) and str(out) in line
    assert gonio.report(runs["inplane"], out, force=True)["out"] == str(out / "report.html")

    missing = tmp_path / "none.gonio"
    with pytest.raises(gonio.RunFileError) as e:
        gonio.report(missing, tmp_path / "r2")
    code, line = cli.error("report", missing, "--out", tmp_path / "r2")
    assert (str(e.value), e.value.exit_code) == (line, code)
    with pytest.raises(gonio.InputError) as e:
        gonio.report(runs["inplane"], calibration="moon")
    code, line = cli.error(
        "report", runs["inplane"], "--out", tmp_path / "r3", "--calibration", "moon"
    )
    assert (str(e.value), e.value.exit_code) == (line, code)


# plan check


@pytest.mark.parametrize(
    "plan", ["plan-in-plane.toml", "plan-hemisphere-targeted.toml", "plan-adaptive.toml"]
)
def test_plan_check_is_gonio_plan_check(cli, plan):
    want = cli.json("plan", "check", CONFIG / plan, "--instrument", INSTRUMENT)
    assert gonio.plan.check(CONFIG / plan, INSTRUMENT) == want
    assert want["pairs"] == want["accepted"] + len(want["rejected"])


def test_plan_check_like_a_run(runs, cli):
    plan = CONFIG / "plan-hemisphere-targeted.toml"
    want = cli.json("plan", "check", plan, "--instrument", INSTRUMENT, "--like", runs["py"])
    got = gonio.plan.check(plan, INSTRUMENT, like=gonio.open_run(runs["py"]))
    assert got == want and want["reading"] is not None


def test_plan_check_refuses_as_the_command_does(cli, tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text((CONFIG / "plan-in-plane.toml").read_text() + "\nbogus = 1\n")
    with pytest.raises(gonio.ConfigError) as e:
        gonio.plan.check(plan, INSTRUMENT)
    code, line = cli.error("plan", "check", plan, "--instrument", INSTRUMENT)
    assert (str(e.value), e.value.exit_code) == (line, code) and str(plan) in line
    missing = tmp_path / "none.gonio"
    target = CONFIG / "plan-hemisphere-targeted.toml"
    with pytest.raises(gonio.RunFileError) as e:
        gonio.plan.check(target, INSTRUMENT, like=missing)
    code, line = cli.error("plan", "check", target, "--instrument", INSTRUMENT, "--like", missing)
    assert (str(e.value), e.value.exit_code) == (line, code)


# plan compare

ADAPTIVE = """
[points]
kind = "adaptive"
theta_i = [30, 60]
budget = { points = 60 }
batch = 0.25
candidates = 512
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"""


def test_plan_compare_is_gonio_plan_compare(cli, tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(ADAPTIVE)
    sample = CONFIG / "samples" / "ggx-0.2.toml"
    args = ("--instrument", INSTRUMENT, "--seed", "2", "--sample", sample, "--grid", "5,10")
    want = cli.json("plan", "compare", plan, *args)
    seen = []
    got = gonio.plan.compare(
        plan, INSTRUMENT, seed=2, sample=sample, grid=(5, 10), progress=seen.append
    )
    # The runs are the command's, step for step, their errors to the bit (summed in
    # node order, whatever the threads).
    assert got.to_dict("records") == want["runs"]
    assert without(got.attrs["compare"], "runs") == without(want, "runs")
    assert list(got["plan"]) == ["adaptive", "lattice", "grid"]
    assert got.loc[0, "error_over_adaptive"] == 1.0
    assert got.loc[0, "error"] < got.loc[1, "error"]
    # A bar a run, each ending at its total.
    stages = [p.stage for p in seen]
    assert [s for i, s in enumerate(stages) if i == 0 or stages[i - 1] != s] == [
        "adaptive",
        "lattice",
        "grid",
    ]
    for name, steps in zip(got["plan"], got["steps"]):
        last = [p for p in seen if p.stage == name][-1]
        assert last.done == last.total == steps and last.unit == "steps"


def test_plan_compare_refuses_as_the_command_does(cli, tmp_path):
    plan = CONFIG / "plan-in-plane.toml"
    with pytest.raises(gonio.ConfigError) as e:
        gonio.plan.compare(plan, INSTRUMENT, progress=False)
    code, line = cli.error("plan", "compare", plan, "--instrument", INSTRUMENT)
    assert (str(e.value), e.value.exit_code) == (line, code) and str(plan) in line
    adaptive = tmp_path / "plan.toml"
    adaptive.write_text(ADAPTIVE)
    with pytest.raises(gonio.InputError) as e:
        gonio.plan.compare(adaptive, INSTRUMENT, keep=tmp_path / "none", progress=False)
    code, line = cli.error(
        "plan", "compare", adaptive, "--instrument", INSTRUMENT, "--keep", tmp_path / "none"
    )
    assert (str(e.value), e.value.exit_code) == (line, code)


# instrument check


@pytest.mark.parametrize("config", ["instrument-sim.toml", "instrument-mixed.toml"])
def test_instrument_check_is_gonio_instrument_check(cli, config):
    want = cli.json("instrument", "check", CONFIG / config)
    assert gonio.instrument.check(CONFIG / config) == want
    assert "connected" not in want


def test_instrument_check_connect_on_the_simulator(cli):
    want = cli.json("instrument", "check", INSTRUMENT, "--connect")
    got = gonio.instrument.check(INSTRUMENT, connect=True)
    assert got == want
    controllers = got["connected"]["controllers"]
    assert controllers and all(c["version"] for c in controllers)
    mixed = cli.json(
        "instrument",
        "check",
        CONFIG / "instrument-mixed.toml",
        "--connect",
        "--sim",
        CONFIG / "sim-mixed.toml",
    )
    got = gonio.instrument.check(
        CONFIG / "instrument-mixed.toml", connect=True, sim=CONFIG / "sim-mixed.toml"
    )
    assert got == mixed
    assert {c["family"] for c in got["connected"]["controllers"]} > {"smc100"}


def test_instrument_check_refuses_as_the_command_does(cli, tmp_path):
    bad = tmp_path / "inst.toml"
    bad.write_text(INSTRUMENT.read_text() + "\nbogus = 1\n")
    with pytest.raises(gonio.ConfigError) as e:
        gonio.instrument.check(bad)
    code, line = cli.error("instrument", "check", bad)
    assert (str(e.value), e.value.exit_code) == (line, code) and str(bad) in line
