"""Instrument configs, as ``gonio instrument check``."""

from __future__ import annotations

import json
import os
from typing import Any

from gonio import _native


def check(
    config: str | os.PathLike[str],
    *,
    connect: bool = False,
    sim: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """Validates an instrument config (ports, axes, limits, detector settings,
    monochromator or filter wheel), as ``gonio instrument check`` does, and returns
    its ``--json`` dict. ``connect`` also opens the ports, identifies every
    controller and sets the detector up (nothing moves): the answers are under
    ``"connected"``, with the facts of each family not yet confirmed on hardware.
    Ports named ``"sim"`` are the simulator (``sim``: its config). A bad config
    raises ``ConfigError`` naming the file and field; an instrument that does not
    answer ``InstrumentError``."""
    words = ["instrument", "check", os.fspath(config)]
    if connect:
        words.append("--connect")
    if sim is not None:
        words += ["--sim", os.fspath(sim)]
    return json.loads(_native.instrument_check(words))


__all__ = ["check"]
