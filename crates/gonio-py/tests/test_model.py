"""Models: evaluated and integrated by the package, held against `gonio model eval`
and `gonio model albedo`, closed forms, and round trips through files and dicts."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gonio
from conftest import CONFIG

PAINT = CONFIG / "models" / "blue-paint-550nm.toml"


def test_eval_is_gonio_model_eval(cli):
    dirs = CONFIG / "dirs-example.csv"
    want = cli.json("model", "eval", PAINT, dirs)
    m = gonio.load_model(PAINT)
    rows = want["rows"]
    got = m.eval(
        [r["theta_i"] for r in rows],
        [r["phi_i"] for r in rows],
        [r["theta_o"] for r in rows],
        [r["phi_o"] for r in rows],
    )
    assert got.shape == (len(rows), 1)
    np.testing.assert_array_equal(got, [r["values"] for r in rows])
    assert m.channels == want["channels"] == ["550nm"] and m.kind == want["kind"]


def test_eval_broadcasts_and_is_the_same_on_any_number_of_threads():
    m = gonio.load_model(CONFIG / "models" / "cook-torrance-gold.toml")
    theta_o = np.linspace(0, 89, 90)[:, None]
    phi_o = np.linspace(0, 350, 36)[None, :]
    f = m.eval(30.0, 0.0, theta_o, phi_o)
    assert f.shape == (90, 36, len(m.channels))
    one = m.eval(30.0, 0.0, theta_o, phi_o, threads=1)
    np.testing.assert_array_equal(f, one)
    # Each element is the model at its own pair.
    np.testing.assert_array_equal(f[40, 7], m.eval(30.0, 0.0, 40.0, 70.0))
    # Reciprocity holds pair by pair (the model is reciprocal by construction).
    g = m.eval(theta_o, phi_o, 30.0, 0.0)
    np.testing.assert_allclose(f, g, rtol=1e-12, atol=0)


def test_lambert_closed_forms():
    rho = 0.8
    m = gonio.Model.from_dict(
        {"kind": "lafortune", "channels": ["value"], "diffuse": {"rho": [rho]}, "lobes": []}
    )
    f = m.eval(np.array([0.0, 45.0, 80.0]), 10.0, 33.0, 200.0)
    np.testing.assert_allclose(f[:, 0], rho / math.pi, rtol=1e-15)
    np.testing.assert_allclose(m.albedo([0.0, 60.0]), [[rho], [rho]], rtol=1e-9)


def test_albedo_is_gonio_model_albedo(cli):
    want = cli.json("model", "albedo", PAINT, "--theta-i", "0,30,60,85")
    got = gonio.load_model(PAINT).albedo([0.0, 30.0, 60.0, 85.0])
    np.testing.assert_array_equal(got, [r["values"] for r in want["albedo"]])
    assert gonio.load_model(PAINT).albedo(30.0).shape == (1,)


def test_round_trips(tmp_path):
    m = gonio.load_model(PAINT)
    d = m.to_dict()
    assert d["kind"] == "lafortune" and d["lobes"][2]["n"] == [63.8]
    again = gonio.Model.from_dict(d)
    args = (np.array([10.0, 50.0]), 0.0, np.array([20.0, 70.0]), 180.0)
    np.testing.assert_array_equal(again.eval(*args), m.eval(*args))
    path = tmp_path / "paint.toml"
    m.save(path)
    np.testing.assert_array_equal(gonio.load_model(path).eval(*args), m.eval(*args))
    with pytest.raises(gonio.InputError, match="exists"):
        m.save(path)
    m.save(path, force=True)
    assert not list(tmp_path.glob(".*tmp"))


def test_bad_model_files_are_refused_as_the_command_does(cli, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(PAINT.read_text().replace("n = [18.6]", "n = [-18.6]"))
    with pytest.raises(gonio.ConfigError) as e:
        gonio.load_model(bad)
    code, line = cli.error("model", "albedo", bad)
    assert (str(e.value), e.value.exit_code) == (line, code) == (line, 2)
    assert str(e.value).startswith(f"{bad}:18:5: field `lobes[0].n`: -18.6")
    with pytest.raises(gonio.ConfigError, match="kind"):
        gonio.Model.from_dict({"kind": "teapot", "channels": ["value"]})
    with pytest.raises(gonio.InputError):
        gonio.load_model(PAINT).albedo([95.0])
