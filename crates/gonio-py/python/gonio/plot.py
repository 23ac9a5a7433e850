"""Plots as matplotlib figures (the ``plot`` extra: ``pip install
"./crates/gonio-py[plot]"``): a BRDF in the plane of incidence, and over the
outgoing hemisphere."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gonio._model import Model
from gonio._run import Run


def _pyplot() -> Any:
    try:
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            'gonio.plot needs matplotlib: pip install "./crates/gonio-py[plot]"'
        ) from e
    return plt


def _samples(data: Any) -> Any:
    """A DataFrame of samples of a run (reduced) or a DataFrame."""
    if isinstance(data, Run):
        return data.reduce()
    return data


def _column(df: Any, channel: int | str) -> tuple[str, str]:
    """The value column of ``channel`` (its index, or its name) and the channel's
    name: ``f_r_R_per_sr`` is channel ``R``, ``f_r_per_sr`` channel ``value``."""
    cols = [c for c in df.columns if c.startswith("f_r")]
    names = [
        "value" if c == "f_r_per_sr" else c.removeprefix("f_r_").removesuffix("_per_sr")
        for c in cols
    ]
    k = names.index(channel) if isinstance(channel, str) else int(channel)
    return cols[k], names[k]


def _colour(theta_i: float) -> Any:
    """One colour an incident angle, the same on every plot (model or data)."""
    import matplotlib

    return matplotlib.colormaps["viridis"](min(max(theta_i / 90.0, 0.0), 1.0) * 0.9)


def _figure(plt: Any, ax: Any, size: tuple[float, float]) -> tuple[Any, Any]:
    """The axes to draw on: ``ax``, or those of a new figure."""
    if ax is not None:
        return ax.figure, ax
    fig = plt.figure(figsize=size, layout="constrained")
    return fig, fig.add_subplot(1, 1, 1)


def polar(
    data: Run | Model | Any,
    theta_i: float | Sequence[float] = (0.0, 30.0, 60.0),
    *,
    channel: int | str = 0,
    log: bool = False,
    ax: Any = None,
) -> Any:
    """f_r in the plane of incidence against the signed outgoing angle (degrees;
    positive on the specular side), one curve per incident angle: a model is
    drawn as a line, a run or a DataFrame of samples as points (those within
    1° of the plane and of each ``theta_i``), with error bars where the samples
    have σ. Returns the figure."""
    plt = _pyplot()
    fig, ax = _figure(plt, ax, (6.4, 4.4))
    thetas = np.atleast_1d(np.asarray(theta_i, dtype=np.float64))
    if isinstance(data, Model):
        k = data.channels.index(channel) if isinstance(channel, str) else int(channel)
        t = np.linspace(-89.5, 89.5, 359)
        for ti in thetas:
            f = data.eval(ti, 0.0, np.abs(t), np.where(t >= 0, 180.0, 0.0))[..., k]
            ax.plot(t, f, color=_colour(ti), label=f"θi = {ti:g}° (model)")
        name = data.channels[k]
    else:
        df = _samples(data)
        col, name = _column(df, channel)
        sigma = col.replace("f_r", "sigma", 1)
        dphi = np.mod(df["phi_o_deg"] - df["phi_i_deg"], 360.0)
        for ti in thetas:
            near = np.abs(df["theta_i_deg"] - ti) < 1.0
            spec = near & (np.abs(dphi - 180.0) < 1.0)
            back = near & ((dphi < 1.0) | (dphi > 359.0))
            x = np.concatenate([df["theta_o_deg"][spec], -df["theta_o_deg"][back]])
            y = np.concatenate([df[col][spec], df[col][back]])
            e = np.concatenate([df[sigma][spec], df[sigma][back]]) if sigma in df.columns else None
            order = np.argsort(x)
            ax.errorbar(
                x[order],
                y[order],
                yerr=None if e is None else e[order],
                fmt="o",
                ms=3,
                capsize=2,
                color=_colour(ti),
                label=f"θi = {ti:g}°",
            )
    ax.set_xlabel("θo (°), specular side positive")
    ax.set_ylabel(f"f_r ({name}), 1/sr")
    if log:
        ax.set_yscale("log")
    ax.set_xlim(-90, 90)
    ax.grid(True, alpha=0.3)
    ax.legend()
    return fig


def hemisphere(
    data: Run | Model | Any,
    theta_i: float = 30.0,
    phi_i: float = 0.0,
    *,
    channel: int | str = 0,
    resolution: int = 121,
    ax: Any = None,
) -> Any:
    """f_r over the outgoing hemisphere for one incident direction, in the
    projected disk (x = sin θo cos φo, y = sin θo sin φo: equal areas carry equal
    projected solid angle). A model is drawn as an image; samples as coloured
    points (those within 1° of ``theta_i``). Returns the figure."""
    plt = _pyplot()
    fig, ax = _figure(plt, ax, (5.2, 4.6))
    if isinstance(data, Model):
        k = data.channels.index(channel) if isinstance(channel, str) else int(channel)
        u = np.linspace(-1.0, 1.0, resolution)
        x, y = np.meshgrid(u, u)
        r = np.hypot(x, y)
        inside = r < 1.0
        theta_o = np.degrees(np.arcsin(np.clip(r, 0.0, 1.0)))
        phi_o = np.degrees(np.arctan2(y, x))
        f = data.eval(theta_i, phi_i, theta_o, phi_o)[..., k]
        f = np.where(inside, f, np.nan)
        im = ax.imshow(f, origin="lower", extent=(-1, 1, -1, 1), cmap="magma")
        name = data.channels[k]
    else:
        df = _samples(data)
        col, name = _column(df, channel)
        near = np.abs(df["theta_i_deg"] - theta_i) < 1.0
        s = np.sin(np.radians(df["theta_o_deg"][near]))
        p = np.radians(df["phi_o_deg"][near] - df["phi_i_deg"][near] + phi_i)
        im = ax.scatter(s * np.cos(p), s * np.sin(p), c=df[col][near], cmap="magma", s=12)
    ax.add_patch(plt.Circle((0, 0), 1.0, fill=False, lw=0.8, color="0.4"))
    ax.set_aspect("equal")
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_xlabel("sin θo cos φo")
    ax.set_ylabel("sin θo sin φo")
    ax.set_title(f"θi = {theta_i:g}°, φi = {phi_i:g}°")
    fig.colorbar(im, ax=ax, label=f"f_r ({name}), 1/sr")
    return fig


__all__ = ["hemisphere", "polar"]
