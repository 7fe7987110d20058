"""Bad input from Python raises clear exceptions (never crashes the
interpreter): wrong shapes, NaN, wrong dtypes, missing and broken files."""

import numpy as np
import pytest

import npf
from _helpers import known_factor_model


@pytest.fixture(scope="module")
def model():
    return known_factor_model((0.2,))


GOOD = np.array([[0.0, 0.0, 1.0]])


@pytest.mark.parametrize(
    "bad, exc, message",
    [
        (np.zeros((4, 2)), ValueError, r"shape \(N, 3\)"),
        (np.zeros((2, 3, 1)), ValueError, r"shape \(N, 3\)"),
        (np.array([[np.nan, 0, 1]]), ValueError, "not finite"),
        (np.array([[0, 0, np.inf]]), ValueError, "not finite"),
        (np.array([[0.0, 0.0, 0.0]]), ValueError, "zero length"),
        (np.array([[0, 0, 1]], dtype=np.int64), TypeError, "floats"),
        (np.array([[0, 0, 1]], dtype=np.complex128), TypeError, "floats"),
        (np.array([["a", "b", "c"]]), TypeError, "floats"),
        ("not an array", TypeError, "floats"),
        ([[0, "x", 1]], TypeError, "floats"),
    ],
)
def test_bad_directions(model, bad, exc, message):
    with pytest.raises(exc, match=message):
        model.eval(bad, GOOD)
    with pytest.raises(exc, match=message):
        model.pdf(GOOD, bad)
    with pytest.raises(exc, match=message):
        model.albedo(bad)


def test_mismatched_lengths_and_bad_random_numbers(model):
    with pytest.raises(ValueError, match="different lengths"):
        model.eval(np.tile(GOOD, (3, 1)), np.tile(GOOD, (2, 1)))
    with pytest.raises(ValueError, match=r"\(N, 2\) or \(N, 3\)"):
        model.sample(GOOD, np.zeros((1, 4)))
    with pytest.raises(ValueError, match=r"\(N, 2\) or \(N, 3\)"):
        model.sample(GOOD, np.array([[np.nan, 0.5]]))
    with pytest.raises(ValueError, match="different lengths"):
        model.sample(np.tile(GOOD, (2, 1)), np.zeros((3, 2)))


def test_float32_and_lists_are_accepted(model):
    ref = model.eval(GOOD, GOOD)
    np.testing.assert_allclose(model.eval(GOOD.astype(np.float32), [[0.0, 0.0, 1.0]]), ref)
    np.testing.assert_array_equal(model.eval([[0, 0, 1]], (0, 0, 1)), ref[0] * np.ones((1, 3)))
    # Non-contiguous views read the right values.
    wide = np.zeros((1, 6))
    wide[0, 2] = wide[0, 5] = 1
    np.testing.assert_array_equal(model.eval(wide[:, :3], wide[:, 3:]), ref)


def test_empty_batches(model):
    empty = np.zeros((0, 3))
    assert model.eval(empty, empty).shape == (0, 3)
    wi, pdf, w = model.sample(empty, np.zeros((0, 3)))
    assert wi.shape == (0, 3) and pdf.shape == (0,) and w.shape == (0, 3)


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.json"):
        npf.load(tmp_path / "missing.json")
    with pytest.raises(FileNotFoundError, match="missing.binary"):
        npf.read_merl(tmp_path / "missing.binary")
    with pytest.raises(FileNotFoundError, match="missing.binary"):
        npf.fit(tmp_path / "missing.binary")
    (tmp_path / "junk.json").write_text("{not json")
    with pytest.raises(ValueError, match="junk.json"):
        npf.load(tmp_path / "junk.json")
    (tmp_path / "short.npfb").write_bytes(b"NPFB\x01\x00")
    with pytest.raises(ValueError, match="short.npfb"):
        npf.load(tmp_path / "short.npfb")
    (tmp_path / "short.binary").write_bytes(b"\x00" * 100)
    with pytest.raises(ValueError, match="truncated"):
        npf.read_merl(tmp_path / "short.binary")
    with pytest.raises(ValueError, match="unknown model file extension"):
        npf.load(tmp_path / "model.txt")
    with pytest.raises(ValueError, match="unknown table format"):
        npf.fit(tmp_path / "table.csv")
    (tmp_path / "dir.json").mkdir()
    with pytest.raises(OSError, match="dir.json"):
        npf.load(tmp_path / "dir.json")  # a directory, not a file


def test_bad_tables(tmp_path):
    with pytest.raises(ValueError, match=r"\(3, 90, 90, 180\)"):
        npf.write_merl(tmp_path / "t.binary", np.zeros((3, 90, 90)))
    table = np.zeros((3, 90, 90, 180))
    table[1, 2, 3, 4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        npf.write_merl(tmp_path / "t.binary", table)
    with pytest.raises(ValueError, match="NaN"):
        npf.fit(table)
    assert not (tmp_path / "t.binary").exists()
    with pytest.raises(ValueError, match="no valid samples"):
        npf.fit(np.full((3, 90, 90, 180), -1.0))
    with pytest.raises(TypeError, match="floats"):
        npf.fit(np.zeros((3, 90, 90, 180), dtype=np.int32))


def test_bad_factors():
    m = known_factor_model((0.2,))
    with pytest.raises(ValueError, match="negative"):
        npf.Model(m.d, m.s, -m.F, m.D, m.G)
    with pytest.raises(ValueError, match="not finite"):
        npf.Model(m.d, m.s, m.F, m.D * np.nan, m.G)
    with pytest.raises(ValueError, match="one row per lobe"):
        npf.Model(m.d, np.vstack([m.s, m.s]), m.F, m.D, m.G)
    with pytest.raises(ValueError, match="same number of values"):
        npf.Model(m.d, m.s, m.F, m.D[:, :45], m.G)
