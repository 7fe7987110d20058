"""npf.Model from Python: the CLI's values, the sampler's pdf and weights,
factors, files and tables."""

import math

import numpy as np
import pytest

import npf
from _helpers import known_factor_model, random_directions, run_npf, spherical


@pytest.fixture(scope="module")
def model():
    return known_factor_model((0.1, 0.3, 0.6))


@pytest.fixture(scope="module")
def model_file(model, tmp_path_factory):
    path = tmp_path_factory.mktemp("model") / "known.json"
    model.save(path)
    return path


def test_eval_equals_the_cli_to_1e_9(model_file):
    m = npf.load(model_file)
    rng = np.random.default_rng(1)
    n = 40
    deg = np.column_stack(
        [rng.uniform(0, 88, n), rng.uniform(-180, 180, n), rng.uniform(0, 88, n), rng.uniform(-180, 180, n)]
    )
    deg[0] = [0, 0, 0, 0]  # normal incidence, the specular peak
    deg[1] = [30, 0, 30, 180]  # mirror configuration
    out = run_npf("eval", model_file, *deg.ravel().tolist())
    cli = np.array([[float(x) for x in line.split(",")[4:]] for line in out.strip().splitlines()[1:]])
    wi = spherical(np.radians(deg[:, 0]), np.radians(deg[:, 1]))
    wo = spherical(np.radians(deg[:, 2]), np.radians(deg[:, 3]))
    py = m.eval(wi, wo)
    assert py.shape == (n, 3) and cli.shape == (n, 3)
    assert np.all(cli > 0)
    # The CLI prints 10 significant digits (relative rounding <= 5e-10).
    np.testing.assert_allclose(py, cli, rtol=1e-9, atol=0)


def test_eval_is_zero_below_the_horizon_and_reciprocal(model):
    rng = np.random.default_rng(2)
    wi, wo = random_directions(rng, 1000), random_directions(rng, 1000)
    np.testing.assert_allclose(model.eval(wi, wo), model.eval(wo, wi), rtol=1e-12)
    below = wi * [1, 1, -1]
    assert np.all(model.eval(below, wo) == 0)
    one = model.eval(wi[0], wo[0])
    assert one.shape == (3,)
    np.testing.assert_array_equal(one, model.eval(wi[:1], wo[:1])[0])


def test_sample_pdf_equals_pdf_of_the_returned_directions(model):
    rng = np.random.default_rng(3)
    n = 20000
    wo = random_directions(rng, n)
    for u in (rng.random((n, 3)), rng.random((n, 2))):
        wi, pdf, weight = model.sample(wo, u)
        assert wi.shape == (n, 3) and pdf.shape == (n,) and weight.shape == (n, 3)
        kept = pdf > 0
        assert kept.mean() > 0.9
        np.testing.assert_allclose(np.linalg.norm(wi[kept], axis=1), 1, atol=1e-12)
        np.testing.assert_allclose(pdf[kept], model.pdf(wo[kept], wi[kept]), rtol=1e-12)
        f = model.eval(wi[kept], wo[kept])
        np.testing.assert_allclose(weight[kept], f * wi[kept, 2:3] / pdf[kept, None], rtol=1e-12)
        assert np.all(weight[~kept] == 0)


@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 75.0])
def test_mean_sample_weight_equals_the_quadrature_albedo(model, theta_deg):
    n = 400_000
    rng = np.random.default_rng(int(theta_deg) + 10)
    wo = np.tile(spherical(math.radians(theta_deg), 0.7), (n, 1))
    _, _, weight = model.sample(wo, rng.random((n, 3)))
    mean = weight.mean(axis=0)
    err = weight.std(axis=0) / math.sqrt(n)
    albedo = model.albedo(wo[:1])[0]
    assert np.all(albedo > 0.05)
    # Within 4 standard errors (plus the quadrature's own 1e-3 relative).
    assert np.all(np.abs(mean - albedo) < 4 * err + 1e-3 * albedo), (mean, albedo, err)


def test_factors_are_read_only_arrays_with_axes(model):
    assert model.num_parameters == 3 + 3 * 3 + 3 * (90 + 90) + 3 * 90 == 822
    assert model.d.shape == (3,) and model.s.shape == (3, 3)
    assert model.F.shape == (3, 90) and model.D.shape == (3, 90) and model.G.shape == (3, 90)
    for name in ("d", "s", "F", "D", "G"):
        a = getattr(model, name)
        assert a.dtype == np.float64
        with pytest.raises(ValueError):
            a[...] = 0
    axes = model.axes
    assert axes["D"]["name"] == "theta_h" and axes["D"]["kind"] == "sqrt_angle"
    np.testing.assert_allclose(axes["D"]["theta"], (np.arange(90) / 90) ** 2 * math.pi / 2)
    np.testing.assert_allclose(axes["F"]["theta"], np.arange(90) / 90 * math.pi / 2)
    np.testing.assert_allclose(axes["G"]["theta"], np.arange(90) / 89 * math.pi / 2)
    # The constructor stores float32, as model files do.
    again = npf.Model(model.d, model.s, model.F, model.D, model.G)
    np.testing.assert_array_equal(again.D, model.D)


def test_save_load_and_export_round_trip(model, tmp_path):
    rng = np.random.default_rng(4)
    wi, wo = random_directions(rng, 500), random_directions(rng, 500)
    ref = model.eval(wi, wo)
    for ext in (".json", ".npfb"):
        model.save(tmp_path / f"m{ext}")
        np.testing.assert_array_equal(npf.load(tmp_path / f"m{ext}").eval(wi, wo), ref)
        model.export(tmp_path / f"e{ext}")
        np.testing.assert_array_equal(npf.load(tmp_path / f"e{ext}").eval(wi, wo), ref)
    with pytest.raises(FileExistsError, match="refusing to overwrite"):
        model.save(tmp_path / "m.json")
    model.save(tmp_path / "m.json", overwrite=True)
    model.export(tmp_path / "m.binary")
    table = npf.read_merl(tmp_path / "m.binary")
    np.testing.assert_allclose(table, model.reconstruct(), rtol=1e-15)
    assert ".binary" in npf.EXPORT_FORMATS
    with pytest.raises(ValueError, match="unknown export format"):
        model.export(tmp_path / "m.xyz")


def test_renderer_exports_write_what_npf_export_writes(model, tmp_path):
    # Model.export and `npf export` share the library's export module: the
    # same model gives the same bytes.
    model.save(tmp_path / "m.json")
    for ext in (".bsdf", ".brdf", ".glsl", ".h"):
        assert ext in npf.EXPORT_FORMATS
        model.export(tmp_path / f"py{ext}")
        out = tmp_path / f"cli{ext}"
        run_npf("export", tmp_path / "m.json", "-o", out, "--quiet")
        assert (tmp_path / f"py{ext}").read_bytes() == out.read_bytes()
        with pytest.raises(FileExistsError):
            model.export(tmp_path / f"py{ext}")
    assert (tmp_path / "py.bsdf").read_bytes().startswith(b"tensor_file")


def test_merl_tables_round_trip_and_match_the_model(model, tmp_path):
    table = model.reconstruct()
    assert table.shape == (3, 90, 90, 180)
    # Cell (theta_h, theta_d, phi_d) = (0, 0, 0) is normal incidence.
    z = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(table[:, 0, 0, 0], model.eval(z, z), rtol=1e-12)
    npf.write_merl(tmp_path / "t.binary", table)
    back = npf.read_merl(tmp_path / "t.binary")
    np.testing.assert_allclose(back, table, rtol=1e-15)
    raw = npf.read_merl(tmp_path / "t.binary", raw=True)
    npf.write_merl(tmp_path / "raw.binary", raw, raw=True)
    assert (tmp_path / "raw.binary").read_bytes() == (tmp_path / "t.binary").read_bytes()
