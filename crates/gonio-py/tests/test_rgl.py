"""RGL materials (``.bsdf``) held against Mitsuba 3's own ``measured`` plugin (PyPI
``mitsuba``, its CPU ``scalar_rgb`` and ``scalar_spectral`` variants): Gonio's
exports of materials drawn at random (not the ones the format was tuned on) load
in the plugin and give the model's f_r cos θo at the file's nodes and between
them, the model's albedo through the plugin's own sampling, and a rendered sphere
under a white sky; Gonio reads any valid file (one written here, byte by byte,
by an independent writer) as the plugin evaluates it."""

from __future__ import annotations

import json
import pathlib
import struct
import subprocess

import numpy as np
import pytest

import gonio
from conftest import gonio_bin

mi = pytest.importorskip("mitsuba")

SEED = 20261129


def materials() -> list[tuple[str, dict]]:
    """Materials with parameters drawn from a seed: lobes, microfacets,
    retro-reflection and anisotropy, in RGB and one channel."""
    rng = np.random.default_rng(SEED)
    u = lambda a, b, n=3: [float(x) for x in rng.uniform(a, b, n)]  # noqa: E731
    lob = u(-1.0, -0.7, 1)[0]
    return [
        (
            "lafortune",
            {
                "kind": "lafortune",
                "channels": ["R", "G", "B"],
                "diffuse": {"rho": u(0.05, 0.4)},
                "lobes": [{"cx": [lob] * 3, "cy": [lob] * 3, "cz": u(0.6, 0.95), "n": u(8, 40)}],
            },
        ),
        (
            "cook-torrance",
            {
                "kind": "cook-torrance",
                "channels": ["R", "G", "B"],
                "distribution": "beckmann",
                "f0": u(0.3, 0.95),
                "alpha": [u(0.2, 0.45, 1)[0]] * 3,
            },
        ),
        (
            "oren-nayar",
            {
                "kind": "oren-nayar",
                "channels": ["value"],
                "rho": u(0.3, 0.9, 1),
                "sigma_deg": u(10, 35, 1),
                "variant": "full",
            },
        ),
        (
            "ward",
            {
                "kind": "ward",
                "channels": ["value"],
                "rho_s": u(0.05, 0.2, 1),
                "alpha_x": u(0.12, 0.3, 1),
                "alpha_y": u(0.12, 0.3, 1),
                "diffuse": {"rho": u(0.1, 0.4, 1)},
            },
        ),
    ]


def directions(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors of angles in degrees."""
    t, p = np.radians(theta), np.radians(phi)
    return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)


def plugin_eval(
    bsdf: object, pairs: np.ndarray, wavelengths: list[float] | None = None
) -> np.ndarray:
    """The plugin's eval (f_r cos θo) at pairs of (θi, φi, θo, φo) in degrees."""
    wi, wo = directions(pairs[:, 0], pairs[:, 1]), directions(pairs[:, 2], pairs[:, 3])
    ctx = mi.BSDFContext()
    out = []
    for a, b in zip(wi, wo):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*a)
        if wavelengths is not None:
            si.wavelengths = mi.Spectrum(wavelengths)
        v = bsdf.eval(ctx, si, mi.Vector3f(*b))
        out.append([v[k] for k in range(len(wavelengths) if wavelengths else 3)])
    return np.asarray(out)


def rel_rms(a: np.ndarray, b: np.ndarray) -> float:
    """√(Σ(a − b)² / Σ b²)."""
    return float(np.sqrt(((a - b) ** 2).sum() / (b**2).sum()))


def as_rgb(values: np.ndarray) -> np.ndarray:
    """A single channel as grey R = G = B, as the export writes it."""
    return np.repeat(values, 3, axis=-1) if values.shape[-1] == 1 else values


def between_pairs(n: int, theta_max: float, isotropic: bool, seed: int) -> np.ndarray:
    """Pairs with θi uniform and ωo distributed as cos θo, both up to theta_max."""
    rng = np.random.default_rng(seed)
    ti = rng.uniform(0, theta_max, n)
    to = np.degrees(np.arcsin(np.sqrt(rng.random(n)) * np.sin(np.radians(theta_max))))
    pi = np.zeros(n) if isotropic else rng.uniform(-180, 180, n)
    po = rng.uniform(-180, 180, n)
    return np.stack([ti, pi, to, po], axis=1)


@pytest.fixture(scope="module")
def exported(
    tmp_path_factory: pytest.TempPathFactory,
) -> list[tuple[str, gonio.Model, pathlib.Path, dict]]:
    d = tmp_path_factory.mktemp("rgl")
    out = []
    for name, spec in materials():
        model = gonio.Model.from_dict(spec)
        path = d / f"{name}.bsdf"
        report = gonio.export(model, "rgl", path)
        out.append((name, model, path, report))
    return out


def test_the_plugin_gives_the_model_at_the_nodes_and_between_them(exported: list) -> None:
    mi.set_variant("scalar_rgb")
    for name, model, path, report in exported:
        b = gonio.open_bsdf(path)
        plugin = mi.load_dict({"type": "measured", "filename": str(path)})
        rng = np.random.default_rng(1)
        nodes = b.node_pairs()
        nodes = nodes[rng.choice(len(nodes), 1500, replace=False)]
        truth = as_rgb(model.eval(*nodes.T)) * np.cos(np.radians(nodes[:, 2]))[:, None]
        at_nodes = rel_rms(plugin_eval(plugin, nodes), truth)
        assert at_nodes <= 0.02, (name, at_nodes)
        pairs = between_pairs(1500, 75.0, b.isotropic, 2)
        truth = as_rgb(model.eval(*pairs.T)) * np.cos(np.radians(pairs[:, 2]))[:, None]
        got = plugin_eval(plugin, pairs)
        between = rel_rms(got, truth)
        assert between <= 0.15, (name, between)
        # What the export said of itself agrees with what the plugin shows.
        assert report["interpolation"]["at_nodes"] <= 0.02, report
        assert abs(report["interpolation"]["between"] - between) <= 0.5 * between + 0.005, (
            name,
            report,
            between,
        )
        # Gonio reads the file as the plugin evaluates it.
        mine = b.eval(*pairs.T) * np.cos(np.radians(pairs[:, 2]))[:, None]
        assert rel_rms(mine, got) <= 1e-3, name


def test_the_plugins_sampling_gives_the_models_albedo(exported: list) -> None:
    mi.set_variant("scalar_rgb")
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(3)
    for name, model, path, _ in exported:
        plugin = mi.load_dict({"type": "measured", "filename": str(path)})
        for theta in (0.0, 35.0, 65.0):
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(*directions(np.array(theta), np.array(0.0)))
            total = np.zeros(3)
            n = 12000
            for u1, u2, u3 in rng.random((n, 3)):
                _, w = plugin.sample(ctx, si, float(u1), mi.Point2f(float(u2), float(u3)))
                total += [w[0], w[1], w[2]]
            est = total / n
            truth = as_rgb(model.albedo([theta]))[0]
            assert np.all(np.abs(est - truth) <= 0.05 * truth), (name, theta, est, truth)


def test_a_rendered_sphere_under_a_white_sky_has_the_albedo(exported: list) -> None:
    mi.set_variant("scalar_rgb")
    res = 40
    for name, model, path, _ in exported[:2]:
        scene = mi.load_dict(
            {
                "type": "scene",
                "integrator": {"type": "path", "max_depth": 2},
                "sensor": {
                    "type": "orthographic",
                    "to_world": mi.ScalarTransform4f().look_at(
                        origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]
                    ),
                    "film": {
                        "type": "hdrfilm",
                        "width": res,
                        "height": res,
                        "rfilter": {"type": "box"},
                        "pixel_format": "rgb",
                    },
                    "sampler": {"type": "independent", "sample_count": 64, "seed": 7},
                },
                "sphere": {"type": "sphere", "bsdf": {"type": "measured", "filename": str(path)}},
                "sky": {"type": "constant", "radiance": {"type": "rgb", "value": 1.0}},
            }
        )
        img = np.asarray(mi.render(scene))
        c = (np.arange(res) + 0.5) / res * 2 - 1
        r = np.hypot(*np.meshgrid(c, c))
        inside = r < 0.9
        # A pixel at radius r sees the surface at θ = asin r from its normal.
        theta = np.degrees(np.arcsin(r[inside]))
        grid = np.linspace(0, 65, 27)
        rho = as_rgb(model.albedo(grid))
        truth = np.stack([np.interp(theta, grid, rho[:, k]) for k in range(3)], axis=1).mean(axis=0)
        got = img[inside].mean(axis=0)
        assert np.all(np.abs(got - truth) <= 0.04 * truth), (name, got, truth)


def test_spectral_materials_load_in_the_spectral_variant(tmp_path: pathlib.Path) -> None:
    mi.set_variant("scalar_spectral")
    model = gonio.load_model(
        pathlib.Path(__file__).resolve().parents[3] / "config/models/spectral-blue-paint.toml"
    )
    path = tmp_path / "paint.bsdf"
    gonio.export(model, "rgl", path)
    plugin = mi.load_dict({"type": "measured", "filename": str(path)})
    waves = [float(c.removesuffix("nm")) for c in model.channels]
    pairs = between_pairs(300, 75.0, True, 4)
    pick = [2, 7, 12, 17]  # 420, 520, 620 and 720 nm
    got = plugin_eval(plugin, pairs, [waves[k] for k in pick])
    truth = model.eval(*pairs.T)[:, pick] * np.cos(np.radians(pairs[:, 2]))[:, None]
    assert rel_rms(got, truth) <= 0.15
    mine = gonio.open_bsdf(path).eval(*pairs.T)[:, pick] * np.cos(np.radians(pairs[:, 2]))[:, None]
    assert rel_rms(mine, got) <= 1e-3


def write_tensor_file(path: pathlib.Path, fields: dict[str, np.ndarray]) -> None:
    """A tensor file as Mitsuba's format defines it, written here independently of
    Gonio: magic, version 1.0, field count, the field headers, 8-byte aligned data."""
    head = b"tensor_file\0" + struct.pack("<BBI", 1, 0, len(fields))
    size = len(head) + sum(2 + len(k) + 2 + 1 + 8 + 8 * v.ndim for k, v in fields.items())
    offsets, at = [], (size + 7) // 8 * 8
    for v in fields.values():
        offsets.append(at)
        at = (at + v.nbytes + 7) // 8 * 8
    for (k, v), o in zip(fields.items(), offsets):
        code = {np.dtype(np.uint8): 1, np.dtype(np.float32): 10}[v.dtype]
        head += struct.pack("<H", len(k)) + k.encode() + struct.pack("<HBQ", v.ndim, code, o)
        head += struct.pack("<" + "Q" * v.ndim, *v.shape)
    out = bytearray(head)
    for v, o in zip(fields.values(), offsets):
        out += b"\0" * (o - len(out)) + np.ascontiguousarray(v).tobytes()
    path.write_bytes(bytes(out))


def random_material(seed: int) -> dict[str, np.ndarray]:
    """An isotropic RGB material of random values with the structure the plugin
    reads (at other resolutions than Gonio writes): periodic in the half vector's
    azimuth and single-valued at θm = 0, as any isotropic material is."""
    rng = np.random.default_rng(seed)
    nt, ns, nv = 6, 16, 24
    f = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    fields = {
        "description": np.frombuffer(b"random test material", dtype=np.uint8),
        "phi_i": f([0.0]),
        "theta_i": f(np.linspace(0, np.radians(80), nt)),
        "ndf": f(np.repeat(rng.random((1, 20)) + 0.1, 2, axis=0)),
        "sigma": f(np.repeat(rng.random((1, 20)) + 0.5, 2, axis=0)),
        "vndf": f(rng.random((1, nt, nv, nv)) + 0.05),
        "luminance": f(rng.random((1, nt, ns, ns)) + 0.05),
        "rgb": f(rng.random((1, nt, 3, ns, ns))),
        "jacobian": np.array([1], dtype=np.uint8),
    }
    for k in ("vndf", "luminance", "rgb"):
        fields[k][..., -1, :] = fields[k][..., 0, :]
        fields[k][..., :, 0] = fields[k][..., :1, 0]
    return fields


def test_a_file_another_tool_wrote_reads_as_the_plugin_evaluates_it(tmp_path: pathlib.Path) -> None:
    mi.set_variant("scalar_rgb")
    for seed in (5, 6):
        path = tmp_path / f"random{seed}.bsdf"
        write_tensor_file(path, random_material(seed))
        table = tmp_path / f"random{seed}.csv"
        subprocess.run(
            [gonio_bin(), "export", str(path), "--format", "csv", "--out", str(table)],
            check=True,
            capture_output=True,
        )
        rows = np.loadtxt(table, delimiter=",", skiprows=1, comments="#")
        rows = rows[np.random.default_rng(seed).choice(len(rows), 3000, replace=False)]
        plugin = mi.load_dict({"type": "measured", "filename": str(path)})
        got = plugin_eval(plugin, rows[:, :4])
        mine = rows[:, 4:7] * np.cos(np.radians(rows[:, 2]))[:, None]
        # Cos-weighted RMS over the rows: the plugin's own f32 arithmetic is the rest.
        assert rel_rms(mine, got) <= 1e-3, seed


def test_an_rgl_input_exports_to_rgl_unchanged_and_to_merl_as_its_source(
    exported: list, tmp_path: pathlib.Path
) -> None:
    _, model, path, _ = exported[1]
    again = tmp_path / "again.bsdf"
    gonio.export(path, "rgl", again)
    assert again.read_bytes() == path.read_bytes()
    via = gonio.export(path, "merl")
    direct = gonio.export(model, "merl")

    def merl(b: bytes) -> np.ndarray:
        assert struct.unpack("<3i", b[:12]) == (90, 90, 180)
        return np.frombuffer(b[12:], dtype="<f8").reshape(3, 90, 90, 180)

    a, d = merl(via), merl(direct)
    # θh and θd up to 75° (the bins the plugin holds between its nodes).
    th = (((np.arange(90) + 0.5) / 90) ** 2) * 90
    td = np.arange(90) + 0.5
    keep = (th[:, None] <= 75) & (td[None, :] <= 75)
    a, d = a[:, keep], d[:, keep]
    ok = (a >= 0) & (d >= 0)
    assert rel_rms(a[ok], d[ok]) <= 0.15


def test_export_json_reports_the_interpolation_error(tmp_path: pathlib.Path) -> None:
    root = pathlib.Path(__file__).resolve().parents[3]
    out = tmp_path / "gold.bsdf"
    done = subprocess.run(
        [
            gonio_bin(),
            "export",
            str(root / "config/models/cook-torrance-gold.toml"),
            "--format",
            "rgl",
            "--out",
            str(out),
            "--json",
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    report = json.loads(done.stdout)
    assert report["format"] == "rgl"
    assert report["interpolation"]["at_nodes"] < 1e-5
    assert 0 < report["interpolation"]["between"] < 0.15
    assert out.read_bytes()[:12] == b"tensor_file\0"


def test_lobes_fit_to_an_rgl_material(exported: list) -> None:
    # The Cook–Torrance material read back and fitted by Lafortune lobes: the fit
    # reproduces the material's albedo at normal incidence (the lobes' own integral).
    _, model, path, _ = exported[1]
    fitted = gonio.fit(gonio.open_bsdf(path))
    rho = np.asarray(fitted.model.albedo([10.0]))[0]
    truth = np.asarray(model.albedo([10.0]))[0]
    assert np.all(np.abs(rho - truth) <= 0.1 * truth), (rho, truth)


def test_the_example_renders_an_export(exported: list, tmp_path: pathlib.Path) -> None:
    import importlib.util

    root = pathlib.Path(__file__).resolve().parents[3]
    spec = importlib.util.spec_from_file_location("render_rgl", root / "examples/render_rgl.py")
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = tmp_path / "sphere.png"
    example.render(str(exported[0][2]), str(out), size=24, spp=4)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
