"""Every CSV the command writes names its units in its header, and pandas reads it
with no arguments: one header row, numbers in every column."""

from __future__ import annotations

import pathlib

import pandas as pd
import pytest

from conftest import CONFIG, Cli

# A column's unit, by the end of its name; `flags` is a bit set, no unit.
UNITS = ("_deg", "_per_sr", "_nm")


def assert_units(path: pathlib.Path, rows: int | None = None) -> pd.DataFrame:
    df = pd.read_csv(path)
    for c in df.columns:
        assert c == "flags" or c.endswith(UNITS), f"{path.name}: column {c!r} has no unit"
        assert pd.api.types.is_numeric_dtype(df[c]), f"{path.name}: column {c!r} is not numbers"
    assert list(df.columns[:4]) == ["theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"]
    if rows is not None:
        assert len(df) == rows
    return df


def test_model_eval_mirrors_the_directions_with_units(cli: Cli, tmp_path: pathlib.Path) -> None:
    dirs = tmp_path / "dirs.csv"
    dirs.write_text("theta_i,phi_i,theta_o,phi_o\n0,0,30,180\n30,0,30,180\n65,0,80,180\n")
    out = tmp_path / "eval.csv"
    paint = CONFIG / "models" / "blue-paint-550nm.toml"
    cli.run("model", "eval", paint, dirs, "--out", out)
    df = assert_units(out, 3)
    assert list(df.columns) == [
        "theta_i_deg",
        "phi_i_deg",
        "theta_o_deg",
        "phi_o_deg",
        "f_r_550nm_per_sr",
    ]
    # The same numbers as the JSON, and the result reads back as directions.
    rows = cli.json("model", "eval", paint, dirs)["rows"]
    assert df["f_r_550nm_per_sr"].tolist() == [r["values"][0] for r in rows]
    again = tmp_path / "again.csv"
    cli.run("model", "eval", paint, out, "--out", again)
    assert again.read_bytes() == out.read_bytes()
    # It reads as samples too: a wavelength channel, so the long form exports.
    long = tmp_path / "long.csv"
    cli.run("export", out, "--format", "csv-long", "--out", long)
    df_long = assert_units(long, 3)
    assert df_long["wavelength_nm"].tolist() == [550.0] * 3
    assert df_long["f_r_per_sr"].tolist() == df["f_r_550nm_per_sr"].tolist()
    rgb = tmp_path / "rgb.csv"
    cli.run("model", "eval", CONFIG / "models" / "cook-torrance-gold.toml", dirs, "--out", rgb)
    assert [c for c in assert_units(rgb, 3).columns[4:]] == [
        "f_r_R_per_sr",
        "f_r_G_per_sr",
        "f_r_B_per_sr",
    ]


@pytest.mark.parametrize("name", ["cli", "inplane"])
def test_reduce_and_export_write_units(
    cli: Cli, runs: dict[str, pathlib.Path], tmp_path: pathlib.Path, name: str
) -> None:
    reduced = tmp_path / "reduced.csv"
    n = cli.json("reduce", runs[name], "--out", reduced)["samples"]
    df = assert_units(reduced)
    assert len(df) <= n
    exported = tmp_path / "export.csv"
    cli.run("export", runs[name], "--format", "csv", "--out", exported)
    assert_units(exported, len(df))


def test_correct_and_micro_write_units(
    cli: Cli, runs: dict[str, pathlib.Path], tmp_path: pathlib.Path
) -> None:
    corrected = tmp_path / "corrected.csv"
    cli.run("correct", runs["cli"], "--reciprocity", "1", "--out", corrected)
    assert_units(corrected)
    traced = tmp_path / "micro.csv"
    surface = CONFIG / "micro-gaussian-gold.toml"
    cli.run("micro", surface, "--grid", "30,90", "--rays", "2000", "--out", traced)
    df = assert_units(traced)
    assert any(c.startswith("sigma_") for c in df.columns)
