"""Plot helpers: what they draw is the model's values and the data's samples."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest

import gonio
from conftest import CONFIG

matplotlib.use("Agg")
PAINT = CONFIG / "models" / "blue-paint-550nm.toml"


def test_polar_of_a_model_draws_its_values():
    m = gonio.load_model(PAINT)
    fig = gonio.plot.polar(m, theta_i=(0, 45))
    ax = fig.axes[0]
    lines = ax.get_lines()
    assert [ln.get_label() for ln in lines] == ["θi = 0° (model)", "θi = 45° (model)"]
    x, y = lines[1].get_data()
    # Specular side positive: φo = 180° when φi = 0.
    want = m.eval(45.0, 0.0, np.abs(x), np.where(x >= 0, 180.0, 0.0))[:, 0]
    np.testing.assert_array_equal(y, want)
    assert "550nm" in ax.get_ylabel()


def test_polar_of_a_run_draws_its_in_plane_samples(runs):
    run = gonio.open_run(runs["inplane"])
    df = run.reduce()
    fig = gonio.plot.polar(df, theta_i=(35,))
    ax = fig.axes[0]
    dphi = np.mod(df["phi_o_deg"] - df["phi_i_deg"], 360.0)
    plane = (np.abs(df["theta_i_deg"] - 35) < 1) & ((dphi < 1) | (np.abs(dphi - 180) < 1))
    points = ax.get_lines()[0].get_xydata()
    assert len(points) == plane.sum() > 5
    assert sorted(points[:, 1]) == sorted(df.loc[plane, "f_r_per_sr"])
    assert "(value)" in ax.get_ylabel()
    # The same θi has the same colour drawn from the model and from the data.
    gonio.plot.polar(gonio.load_model(PAINT), theta_i=(35,), ax=ax)
    assert ax.get_lines()[0].get_color() == ax.get_lines()[-1].get_color()


def test_hemisphere_of_a_model_is_its_values_in_the_projected_disk():
    m = gonio.load_model(PAINT)
    fig = gonio.plot.hemisphere(m, theta_i=30, resolution=41)
    img = fig.axes[0].get_images()[0].get_array()
    # The centre pixel is the normal direction; corners lie outside the disk.
    assert img[20, 20] == pytest.approx(m.eval(30.0, 0.0, 0.0, 0.0)[0], rel=1e-12)
    assert np.ma.is_masked(img[0, 0]) or np.isnan(img[0, 0])
