"""Analytic BRDF models and RGL materials (``.bsdf``): files in, f_r and albedos
out as numpy arrays."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np
import numpy.typing as npt

from gonio import _native
from gonio._frame import write_new

ArrayLike = npt.ArrayLike


class _Evaluable:
    """A BRDF evaluated in the native module: ``eval`` and ``albedo``."""

    def __init__(self, native: Any) -> None:
        self._native = native

    def _gonio_input(self) -> Any:
        """What the native module takes for this BRDF (``_frame.to_input``)."""
        return self._native

    @property
    def channels(self) -> list[str]:
        """The channel names (``["R", "G", "B"]``, ``["value"]``, …)."""
        return list(self._native.channels())

    def eval(
        self,
        theta_i: ArrayLike,
        phi_i: ArrayLike,
        theta_o: ArrayLike,
        phi_o: ArrayLike,
        *,
        threads: int | None = None,
    ) -> np.ndarray:
        """f_r (1/sr) at the direction pairs the four angle arrays (degrees) give,
        broadcast together: an array of shape ``broadcast_shape + (channels,)``.
        An ideal mirror term, if the model has one, is not in f_r (it is in
        ``albedo``). The work is shared among ``threads`` threads (default: one a
        core), without the interpreter's lock."""
        arrays = np.broadcast_arrays(
            *(np.asarray(a, dtype=np.float64) for a in (theta_i, phi_i, theta_o, phi_o))
        )
        shape = arrays[0].shape
        flat = [np.ascontiguousarray(a.reshape(-1)) for a in arrays]
        out = self._native.eval(*flat, threads=threads)
        return out.reshape(shape + (out.shape[1],))

    def albedo(self, theta_i: ArrayLike, phi_i: float = 0.0) -> np.ndarray:
        """Directional–hemispherical reflectance at incident polar angle(s)
        ``theta_i`` (degrees) and azimuth ``phi_i``: shape ``theta_i.shape +
        (channels,)``."""
        t = np.asarray(theta_i, dtype=np.float64)
        out = self._native.albedo([float(x) for x in t.reshape(-1)], float(phi_i))
        return out.reshape(t.shape + (out.shape[1],))


class Model(_Evaluable):
    """An analytic BRDF model (Lafortune lobes, Ward, Blinn-Phong, Cook–Torrance,
    Lambert, …) as a model file describes it. Angles are in degrees, f_r in 1/sr."""

    def __repr__(self) -> str:
        return f"<gonio.Model {self.kind} channels={self.channels}>"

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Model:
        """A model from the dict a model file's TOML parses into (``to_dict``'s
        form), checked as the file would be."""
        return cls(_native.NativeModel.from_toml(_native.json_to_toml(json.dumps(d)), "<dict>"))

    @classmethod
    def from_toml(cls, text: str) -> Model:
        """A model from a model file's text."""
        return cls(_native.NativeModel.from_toml(text, "<text>"))

    def to_dict(self) -> dict[str, Any]:
        """The model file as a dict."""
        return json.loads(_native.toml_to_json(self.to_toml()))

    def to_toml(self) -> str:
        """The model file's text."""
        return str(self._native.to_toml())

    @property
    def kind(self) -> str:
        """The model's kind: ``lafortune``, ``ward``, …"""
        return str(self._native.kind())

    def save(self, path: str | os.PathLike[str], *, force: bool = False) -> None:
        """Writes the model file (whole or not at all; an existing file only with
        ``force``)."""
        write_new(path, self.to_toml(), force)


def load_model(path: str | os.PathLike[str]) -> Model:
    """Reads a model file; errors name the file, line and field (``ConfigError``)."""
    return Model(_native.NativeModel.load(os.fspath(path)))


class Bsdf(_Evaluable):
    """An RGL material (``.bsdf``, Dupuy & Jakob 2018), evaluated exactly as
    Mitsuba 3's ``measured`` plugin evaluates it: ``eval`` gives f_r (the plugin's
    f_r cos θo divided by cos θo). Any command takes it as its input (``check``,
    ``fit``, ``export``, …)."""

    def __repr__(self) -> str:
        return f"<gonio.Bsdf channels={self.channels} isotropic={self.isotropic}>"

    @property
    def description(self) -> str:
        """The file's ``description`` field."""
        return str(self._native.description())

    @property
    def isotropic(self) -> bool:
        """True when the file holds one incidence azimuth."""
        return bool(self._native.isotropic())

    def node_pairs(self) -> np.ndarray:
        """The file's nodes as direction pairs: an ``(n, 4)`` array of θi, φi, θo,
        φo (degrees), each incidence with each node of its sample square whose
        outgoing direction is above the surface."""
        return np.asarray(self._native.node_pairs())


def open_bsdf(path: str | os.PathLike[str]) -> Bsdf:
    """Reads an RGL material (``.bsdf``); errors name the file and the field or
    byte (``InputError``)."""
    return Bsdf(_native.NativeBsdf.load(os.fspath(path)))
