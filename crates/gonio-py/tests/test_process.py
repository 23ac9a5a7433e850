"""check, correct, harmonics, fit and micro: the package's results held against
the command's on the same inputs — files, runs, models and DataFrames."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

import gonio
from conftest import CONFIG

PAINT = CONFIG / "models" / "blue-paint-550nm.toml"


def without_out(d):
    return {k: v for k, v in d.items() if k != "out"}


def test_check_of_a_run_is_gonio_check(runs, cli):
    want = cli.json("check", runs["py"], "--k", "1,5,10")
    assert gonio.check(gonio.open_run(runs["py"]), k=(1, 5, 10)) == want
    assert gonio.check(runs["py"], k=[1, 5, 10]) == want
    # A half turn of an isotropic material, unfolded by mirror symmetry.
    assert want["symmetry"] == "isotropic-bilateral"


def test_check_of_a_model_is_gonio_check(cli):
    want = cli.json("check", PAINT, "--grid", "10,30", "--k", "1,2")
    assert gonio.check(gonio.load_model(PAINT), k=(1, 2), grid=(10, 30)) == want
    assert gonio.check(PAINT, k=(1, 2), grid=(10, 30)) == want
    # The paint conserves energy: its largest directional albedo is below one.
    assert want["energy"]["p_ec"] == [0.0]
    assert 0.3 < max(a[0] for _, _, a in want["energy"]["worst"]) < 1.0


def test_check_of_a_dataframe_is_gonio_check_of_its_csv(runs, cli, tmp_path):
    out = tmp_path / "r.csv"
    cli.run("reduce", runs["py"], "--out", out)
    df = gonio.open_run(runs["py"]).reduce()
    assert gonio.check(df, k=(1, 5)) == cli.json("check", out, "--k", "1,5")
    # The same frame read back from the CSV and its sidecar.
    assert gonio.check(gonio.read_csv(out), k=(1, 5)) == gonio.check(df, k=(1, 5))


def test_correct_is_gonio_correct(runs, cli, tmp_path):
    out = tmp_path / "c.csv"
    want = cli.json("correct", runs["py"], "--energy", "1", "--reciprocity", "0.5", "--out", out)
    got = gonio.correct(runs["py"], energy=1, reciprocity=0.5)
    pd.testing.assert_frame_equal(got, pd.read_csv(out), check_exact=True, check_dtype=False)
    assert got.attrs["correct"] == without_out(want)
    assert got.attrs["gonio"] == json.loads((tmp_path / "c.csv.json").read_text())
    # The steps run in the order the keywords are given.
    assert [s for s in want["steps"]] == got.attrs["correct"]["steps"]
    other = gonio.correct(runs["py"], reciprocity=0.5, energy=1)
    assert other.attrs["correct"]["steps"] == list(reversed(want["steps"]))
    with pytest.raises(TypeError, match="steps are"):
        gonio.correct(runs["py"], reciprocty=1)


def test_harmonics_is_gonio_harmonics(runs, cli, tmp_path):
    out = tmp_path / "h.toml"
    want = cli.json("harmonics", PAINT, "--order", "4", "--grid", "10,30", "--out", out)
    got = gonio.harmonics(gonio.load_model(PAINT), 4, grid=(10, 30), out=tmp_path / "p.toml")
    assert got["file"] == out.read_text() == (tmp_path / "p.toml").read_text()
    assert without_out(got) == {**without_out(want), "file": got["file"]}
    with pytest.raises(gonio.InputError, match="exists"):
        gonio.harmonics(PAINT, 4, grid=(10, 30), out=out)


def test_fit_is_gonio_fit(runs, cli, tmp_path):
    csv = tmp_path / "r.csv"
    cli.run("reduce", runs["py"], "--out", csv)
    model = tmp_path / "fit.toml"
    want = cli.json("fit", csv, "--lobes", "2", "--out", model)
    text = cli.run("fit", csv, "--lobes", "2", "--out", tmp_path / "fit2.toml").stdout
    df = gonio.open_run(runs["py"]).reduce()
    r = gonio.fit(df, lobes=2)
    # The numbers are the command's; only the seconds the fit took differ.
    for d in (want, r.json):
        d["fit"].pop("seconds")
        d.pop("out")
    assert r.json == want

    def lines(report):
        # All but the time taken and the model file written.
        return [x for x in report.splitlines() if " s; " not in x and not x.startswith("model:")]

    assert lines(r.report.replace("DataFrame", str(csv))) == lines(text)
    assert len(lines(text)) >= 6
    body = lambda s: s.split("\n", 1)[1]  # noqa: E731 - after the comment line naming the input
    assert body(r.model_file) == body(model.read_text())
    assert r.model.kind == "lafortune" and r.chi2.keys() == {"value"}
    p = r.params
    assert list(p.columns) == ["channel", "term", "parameter", "value", "std_err"]
    assert len(p) == 1 + 2 * 4 and (p["std_err"] > 0).all()
    rho = p.query("parameter == 'rho_d'")["value"].item()
    assert rho == want["fit"]["channels"][0]["params"]["rho_d"]
    # The fit from a run, and from the CSV's path, are the same fit.
    assert gonio.fit(runs["py"], lobes=2).model_file.split("\n", 1)[1] == body(r.model_file)


def test_fit_refuses_as_the_command_does(runs, cli, tmp_path):
    with pytest.raises(gonio.InputError) as e:
        gonio.fit(runs["py"], lobes=99)
    code, line = cli.error("fit", runs["py"], "--lobes", "99", "--out", tmp_path / "x.toml")
    assert (str(e.value), e.value.exit_code) == (line, code)
    with pytest.raises(gonio.InputError, match="objective"):
        gonio.fit(runs["py"], objective="median")


def test_dataframes_are_checked_as_files_are():
    df = pd.DataFrame(
        {
            "theta_i_deg": [0.0, 10.0],
            "phi_i_deg": [0.0, 0.0],
            "theta_o_deg": [5.0, np.nan],
            "phi_o_deg": [0.0, 0.0],
            "f_r_per_sr": [0.1, 0.2],
        }
    )
    with pytest.raises(gonio.DataError) as e:
        gonio.check(df)
    assert str(e.value) == "DataFrame:2: field `theta_o_deg`: NaN is not a finite number"
    with pytest.raises(gonio.DataError, match="columns"):
        gonio.check(df.rename(columns={"f_r_per_sr": "brightness"}))
    with pytest.raises(TypeError):
        gonio.check(42)


def test_micro_is_gonio_micro(cli, tmp_path):
    surface = CONFIG / "micro-gaussian-gold.toml"
    out = tmp_path / "m.csv"
    want = cli.json(
        "micro", surface, "--grid", "15,45", "--rays", "2000", "--seed", "7", "--out", out
    )
    got = gonio.micro.simulate(surface, grid=(15, 45), rays=2000, seed=7)
    pd.testing.assert_frame_equal(got, pd.read_csv(out), check_exact=True, check_dtype=False)
    got.attrs["micro"].pop("seconds")
    want.pop("seconds")
    assert got.attrs["micro"] == without_out(want)
    # The same seed on one thread gives the same bytes.
    again = gonio.micro.simulate(surface, grid=(15, 45), rays=2000, seed=7, threads=1)
    pd.testing.assert_frame_equal(got, again, check_exact=True)


def test_micro_at_chosen_incidences(cli):
    surface = CONFIG / "micro-gaussian-gold.toml"
    df = gonio.micro.simulate(surface, theta_i=[20, 40, 60], grid=(15, 45), rays=500, seed=2)
    assert sorted(df["theta_i_deg"].unique()) == [20.0, 40.0, 60.0]
    assert df.attrs["gonio"]["grid"]["theta_i"] == {"start_deg": 20.0, "step_deg": 20.0, "n": 3}
    with pytest.raises(ValueError, match="evenly"):
        gonio.micro.simulate(surface, theta_i=[10, 20, 40])
    with pytest.raises(gonio.ConfigError) as e:
        gonio.micro.simulate(CONFIG / "plan-list.toml", rays=100)
    assert str(CONFIG / "plan-list.toml") in str(e.value)
