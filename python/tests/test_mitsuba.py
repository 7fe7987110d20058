"""The Mitsuba 3 plugin (scalar_rgb): npf's values and sampler inside
Mitsuba, and a sphere that renders without NaN."""

import math

import numpy as np
import pytest

import npf
from _helpers import known_factor_model, random_directions

mi = pytest.importorskip("mitsuba")


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    mi.set_variant("scalar_rgb")
    import npf.mitsuba

    npf.mitsuba.register()
    path = tmp_path_factory.mktemp("mi") / "known.json"
    model = known_factor_model((0.1, 0.4))
    model.save(path)
    bsdf = mi.load_dict({"type": "npf", "filename": str(path)})
    return model, bsdf, path


def interaction(wi):
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*wi)
    return si


def test_plugin_eval_is_model_eval_times_cos(plugin):
    model, bsdf, _ = plugin
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(7)
    view, light = random_directions(rng, 200), random_directions(rng, 200)
    expect = model.eval(light, view) * light[:, 2:3]
    for v, l, e in zip(view, light, expect):
        si = interaction(v)
        got = np.array(bsdf.eval(ctx, si, mi.Vector3f(*l)))
        np.testing.assert_allclose(got, e, rtol=1e-6, atol=1e-12)  # Mitsuba's float32
        value, pdf = bsdf.eval_pdf(ctx, si, mi.Vector3f(*l))
        np.testing.assert_allclose(np.array(value), e, rtol=1e-6, atol=1e-12)
        np.testing.assert_allclose(pdf, model.pdf(v, l), rtol=1e-6)
        np.testing.assert_allclose(bsdf.pdf(ctx, si, mi.Vector3f(*l)), model.pdf(v, l), rtol=1e-6)
    # Below the surface: nothing.
    assert np.all(np.array(bsdf.eval(ctx, interaction([0, 0, -1]), mi.Vector3f(0, 0, 1))) == 0)


def test_plugin_sample_is_npf_sampler(plugin):
    model, bsdf, _ = plugin
    ctx = mi.BSDFContext()
    rng = np.random.default_rng(8)
    for v, u in zip(random_directions(rng, 100), rng.random((100, 3))):
        bs, weight = bsdf.sample(ctx, interaction(v), float(u[0]), mi.Point2f(u[1], u[2]))
        wi, pdf, w = model.sample(v, u)
        np.testing.assert_allclose(np.array(bs.wo), wi, atol=1e-6)
        np.testing.assert_allclose(bs.pdf, pdf, rtol=1e-5)
        np.testing.assert_allclose(np.array(weight), w, rtol=1e-5, atol=1e-9)


def test_a_sphere_renders_without_nan(plugin):
    _, _, path = plugin
    scene = mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 3},
            "sensor": {
                "type": "perspective",
                "fov": 30,
                "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4], target=[0, 0, 0], up=[0, 1, 0]),
                "film": {"type": "hdrfilm", "width": 24, "height": 24, "rfilter": {"type": "box"}},
                "sampler": {"type": "independent", "sample_count": 4},
            },
            "sphere": {"type": "sphere", "bsdf": {"type": "npf", "filename": str(path)}},
            "light": {"type": "point", "position": [2, 2, 4], "intensity": {"type": "rgb", "value": 20.0}},
            "env": {"type": "constant", "radiance": {"type": "rgb", "value": 0.2}},
        }
    )
    image = np.array(mi.render(scene))
    assert image.shape == (24, 24, 3)
    assert np.all(np.isfinite(image))
    centre = image[12, 12]
    assert np.all(centre > 0)
    # The point light is above the camera: the upper half is brighter.
    assert image[:12].sum() > 1.2 * image[12:].sum()


LLVM_CHECK = r"""
import sys
import numpy as np
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
import npf.mitsuba
npf.mitsuba.register()
model = npf.load(sys.argv[1])
bsdf = mi.load_dict({"type": "npf", "filename": sys.argv[1]})
rng = np.random.default_rng(9)
def dirs(n):
    z = 1 - rng.random(n) * 0.9
    p = rng.random(n) * 2 * np.pi
    r = np.sqrt(1 - z * z)
    # float32 values, as Mitsuba holds them, so both sides see the same input.
    return np.stack([r * np.cos(p), r * np.sin(p), z], axis=1).astype(np.float32).astype(np.float64)
v, l = dirs(2000), dirs(2000)
si = mi.SurfaceInteraction3f()
si.wi = mi.Vector3f(v[:, 0], v[:, 1], v[:, 2])
ctx = mi.BSDFContext()
wo = mi.Vector3f(l[:, 0], l[:, 1], l[:, 2])
value, pdf = bsdf.eval_pdf(ctx, si, wo)
np.testing.assert_allclose(np.array(value).T, model.eval(l, v) * l[:, 2:3], rtol=1e-5)
np.testing.assert_allclose(np.array(pdf), model.pdf(v, l), rtol=1e-5)
u = rng.random((2000, 3)).astype(np.float32).astype(np.float64)
bs, weight = bsdf.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(u[:, 1], u[:, 2]))
wi, p, w = model.sample(v, u)
np.testing.assert_allclose(np.array(bs.wo).T, wi, atol=1e-6)
np.testing.assert_allclose(np.array(weight).T, w, rtol=1e-4, atol=1e-7)
print("ok")
"""


def test_llvm_variant_batched_calls_are_npf(plugin):
    """The vectorised path (whole arrays through numpy), in a fresh process
    (Mitsuba's variant is global). Rendering with llvm variants is not
    tested: this machine's libLLVM rejects Dr.Jit's kernels for any BSDF."""
    import subprocess
    import sys

    if "llvm_ad_rgb" not in mi.variants():
        pytest.skip("this Mitsuba build has no llvm_ad_rgb variant")
    _, _, path = plugin
    r = subprocess.run([sys.executable, "-c", LLVM_CHECK, str(path)], capture_output=True, text=True)
    if "LLVM" in r.stderr and "could not" in r.stderr.lower() and r.returncode != 0:
        pytest.skip(f"no usable LLVM for Dr.Jit: {r.stderr.strip().splitlines()[-1]}")
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]
