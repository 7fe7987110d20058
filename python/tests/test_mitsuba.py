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
