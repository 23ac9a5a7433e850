"""Render an RGL material (``.bsdf``, as ``gonio export --format rgl`` writes it)
on a sphere with Mitsuba 3's ``measured`` plugin: a white sky and a sun from the
upper left, 256 × 256 pixels, written as an sRGB PNG.

    python examples/render_rgl.py paint.bsdf paint.png

Needs ``pip install mitsuba`` (its CPU ``scalar_rgb`` variant)."""

from __future__ import annotations

import sys

import mitsuba as mi


def render(bsdf: str, out: str, size: int = 256, spp: int = 512) -> None:
    """Renders the material ``bsdf`` on a unit sphere into ``out``."""
    mi.set_variant("scalar_rgb")
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 3},
            "sensor": {
                "type": "perspective",
                "fov": 30,
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=[0, -1.5, 4.2], target=[0, 0, 0], up=[0, 1, 0]
                ),
                "film": {"type": "hdrfilm", "width": size, "height": size},
                "sampler": {"type": "independent", "sample_count": spp, "seed": 1},
            },
            "sphere": {
                "type": "sphere",
                "bsdf": {"type": "measured", "filename": bsdf},
            },
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 0.25}},
            "sun": {
                "type": "directional",
                "direction": [1.0, -0.6, -1.0],
                "irradiance": {"type": "rgb", "value": 3.0},
            },
        }
    )
    mi.util.write_bitmap(out, mi.render(scene), write_async=False)


if __name__ == "__main__":
    render(sys.argv[1], sys.argv[2])
