"""npf.fit from Python: known factors come back, progress is reported, the
result is the CLI's model."""

import threading

import numpy as np
import pytest

import npf
from _helpers import known_factor_model, run_npf


def test_fit_of_a_known_factor_table_recovers_it():
    truth = known_factor_model((0.2,))
    table = truth.reconstruct()
    reports = []
    fitted = npf.fit(table, lobes=1, max_sweeps=40, tol=1e-9, progress=reports.append)
    assert fitted.num_parameters == truth.num_parameters == 3 + 3 + 180 + 270
    # As the Rust test (tests/fit.rs): npf's cosine-weighted relative RMSE
    # against the table (theta <= 85 deg) below 1e-3.
    metrics = fitted.fit_info["metrics"]
    assert metrics["max_theta_deg"] == 85 and metrics["samples"] > 1_000_000
    assert metrics["rel_cos_rmse"] < 1e-3, metrics
    # The fit's own values agree: at normal incidence (the specular peak).
    z = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(fitted.eval(z, z), truth.eval(z, z), rtol=1e-2)
    assert np.array_equal(fitted.reconstruct() >= 0, table >= 0)
    # The progress callback saw every sweep, objective never rising.
    assert len(reports) == fitted.fit_info["sweeps"] > 1
    assert [r["sweep"] for r in reports] == list(range(1, len(reports) + 1))
    objective = [r["objective"] for r in reports]
    assert all(b <= a * (1 + 1e-12) for a, b in zip(objective, objective[1:]))
    assert fitted.fit_info["objective"] == objective[-1]


def test_fit_from_a_path_is_the_cli_fit(tmp_path):
    truth = known_factor_model((0.2,))
    npf.write_merl(tmp_path / "t.binary", truth.reconstruct())
    opts = dict(lobes=1, max_sweeps=5)
    py = npf.fit(tmp_path / "t.binary", **opts)
    run_npf("fit", tmp_path / "t.binary", "-o", tmp_path / "cli.npfb", "--lobes", "1", "--max-sweeps", "5", "--quiet")
    cli = npf.load(tmp_path / "cli.npfb")
    for name in ("d", "s", "F", "D", "G"):
        np.testing.assert_array_equal(getattr(py, name), getattr(cli, name))
    assert py.fit_info["source"].endswith("t.binary")


def test_progress_errors_are_raised_after_the_fit_and_the_gil_is_free():
    table = known_factor_model((0.3,)).reconstruct()
    table[..., np.arange(180) % 6 != 0] = -1  # a sparse table: a quick fit

    def boom(report):
        raise KeyError("stop")

    with pytest.raises(KeyError, match="stop"):
        npf.fit(table, lobes=1, max_sweeps=2, progress=boom)

    # While a fit runs in another thread, this one keeps running Python
    # (a fit holding the GIL would freeze it for seconds).
    result = {}
    worker = threading.Thread(target=lambda: result.update(model=npf.fit(table, lobes=1, max_sweeps=2)))
    worker.start()
    spins = 0
    while worker.is_alive():
        spins += 1
    worker.join()
    assert result["model"].lobes == 1
    assert spins > 10_000, spins


def test_separable_diffuse_fit_is_the_cli_fit_and_samples_consistently(tmp_path):
    truth = known_factor_model((0.2,))
    npf.write_merl(tmp_path / "t.binary", truth.reconstruct())
    py = npf.fit(tmp_path / "t.binary", lobes=1, max_sweeps=5, diffuse="separable")
    run_npf("fit", tmp_path / "t.binary", "-o", tmp_path / "cli.json", "--lobes", "1",
            "--max-sweeps", "5", "--diffuse", "separable", "--quiet")
    cli = npf.load(tmp_path / "cli.json")
    rng = np.random.default_rng(7)
    wo = rng.normal(size=(500, 3))
    wo[:, 2] = np.abs(wo[:, 2]) + 0.05
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi = wo * np.array([-1.0, -1.0, 1.0])
    # The same model (P included: eval reads it) from both front doors.
    np.testing.assert_array_equal(py.eval(wi, wo), cli.eval(wi, wo))
    # Its sampler's weight is f cos / pdf of the model's own eval and pdf.
    wi_s, pdf, weight = py.sample(wo, rng.random((500, 3)))
    ok = pdf > 0
    f = py.eval(wi_s[ok], wo[ok])
    np.testing.assert_allclose(weight[ok], f * wi_s[ok, 2:3] / pdf[ok][:, None], rtol=1e-6)
    np.testing.assert_allclose(py.pdf(wo[ok], wi_s[ok]), pdf[ok], rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(diffuse="velvet"), "unknown diffuse"),
        (dict(model="auto"), "npf fit --model auto"),
        (dict(lobes=0), "lob"),
        (dict(lobes=9), "lob"),
        (dict(weighting="loud"), "unknown weighting"),
        (dict(model="neural"), "unknown model"),
        (dict(g_method="magic"), "unknown g_method"),
        (dict(nodes=2), "values per factor table"),
        (dict(tol=float("nan")), "finite"),
        (dict(threads=100_000), "threads"),
    ],
)
def test_bad_fit_options_raise_value_error(kwargs, message):
    table = np.full((3, 90, 90, 180), 0.1)
    with pytest.raises(ValueError, match=message):
        npf.fit(table, **kwargs)


def test_a_progress_that_is_not_callable_is_refused_before_fitting():
    with pytest.raises(TypeError, match="callable"):
        npf.fit(np.full((3, 90, 90, 180), 0.1), progress="yes")


def test_energy_scale_is_read_from_the_table_as_in_the_cli():
    # A table npf made itself is trusted: no scale by default; forced on,
    # the record holds the per-channel ratio (applied only past 5 %).
    table = known_factor_model((0.2,)).reconstruct()
    opts = dict(lobes=1, max_sweeps=2)
    plain = npf.fit(table, **opts)
    assert "energy_scale" not in plain.fit_info["selection"]
    forced = npf.fit(table, energy_scale=True, **opts)
    record = forced.fit_info["selection"]["energy_scale"]
    assert len(record["k"]) == 3 and all(k > 0 for k in record["k"])
    assert record["applied"] == any(abs(k - 1) > record["dead_zone"] for k in record["k"])
    if not record["applied"]:
        assert forced.fit_info["objective"] == plain.fit_info["objective"]
        z = np.array([0.0, 0.0, 1.0])
        np.testing.assert_array_equal(forced.eval(z, z), plain.eval(z, z))
    assert "energy_scale" not in npf.fit(table, energy_scale=False, **opts).fit_info["selection"]
