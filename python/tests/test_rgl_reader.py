"""npf reads RGL `.bsdf` files as Mitsuba 3's `measured` plugin does (issue 45).

`npf eval FILE.bsdf ...` evaluates the file's BRDF with npf's reader
(data-loaders/src/rgl_brdf.rs); Mitsuba 3 (`scalar_rgb`, the `measured`
plugin) loads the same file. At 10,000 random direction pairs (theta up
to 85 degrees) every channel agrees within 1 % relative or 1e-4 absolute.

The files come from three routes:
- written here from scratch, with this file's own tensor-file writer (no
  npf code): an analytic GGX + Lambert BRDF tabulated in the layout of
  ../shared/docs/RGL_FORMAT.md section 8 (identity warp), and files of
  random positive tables (isotropic and anisotropic) that exercise the
  vndf warp's inverse and the blending between parameter nodes;
- npf's own writer (`npf export`) of a model with known factors.

NPF_BIN points at the npf program (tests/run-all.sh sets it).
"""

import os
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba")

NPF = os.environ.get("NPF_BIN", str(Path(__file__).resolve().parents[2] / "target/release/npf"))
PAIRS = 10_000
MAX_THETA = np.radians(85.0)


def npf(*args):
    return subprocess.run([NPF, *map(str, args)], capture_output=True, text=True, check=True)


def write_tensor(path, fields):
    """A tensor file (RGL_FORMAT.md section 1): float32 arrays and uint8
    `jacobian`, each array 8-byte aligned."""
    header = 12 + 2 + 4
    for name, a in fields.items():
        header += 2 + len(name) + 2 + 1 + 8 + 8 * a.ndim
    offset, entries, blobs = header, [], []
    for name, a in fields.items():
        offset = (offset + 7) // 8 * 8
        code = 1 if a.dtype == np.uint8 else 10
        entries.append(struct.pack("<H", len(name)) + name.encode() + struct.pack("<HBQ", a.ndim, code, offset)
                       + b"".join(struct.pack("<Q", n) for n in a.shape))
        blobs.append((offset, np.ascontiguousarray(a).tobytes()))
        offset += a.nbytes
    out = bytearray(b"tensor_file\0" + bytes([1, 0]) + struct.pack("<I", len(fields)) + b"".join(entries))
    for off, blob in blobs:
        out += b"\0" * (off - len(out)) + blob
    path.write_bytes(bytes(out))


def sph(theta, phi):
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)


def ggx_lambert(wi, wo, alpha=0.3, kd=(0.2, 0.3, 0.4), ks=(0.8, 0.7, 0.6)):
    """f of a GGX lobe (Smith G, no Fresnel) plus Lambert, per channel."""
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    c = h[..., 2]
    d = alpha**2 / (np.pi * (c * c * (alpha**2 - 1) + 1) ** 2)
    g1 = lambda w: 2 / (1 + np.sqrt(1 + alpha**2 * (1 - w[..., 2] ** 2) / w[..., 2] ** 2))
    spec = d * g1(wi) * g1(wo) / (4 * wi[..., 2] * wo[..., 2])
    return np.asarray(kd) / np.pi + spec[..., None] * np.asarray(ks)


def analytic_file(path, n=64, thetas=24):
    """RGL_FORMAT.md section 8: constant vndf (the identity warp), ndf = 1
    and sigma = 1/4 so that the jacobian is 1; rgb = f cos(theta_o) at the
    half vectors of the sample nodes."""
    theta_i = np.linspace(0, np.radians(85), thetas).astype(np.float32)
    u = np.arange(n) / (n - 1)
    uy, ux = np.meshgrid(u, u, indexing="ij")
    wm = sph(ux**2 * np.pi / 2, (2 * uy - 1) * np.pi)
    rgb = np.zeros((1, thetas, 3, n, n))
    for t, th in enumerate(theta_i.astype(float)):
        wi = np.broadcast_to(sph(np.array(th), np.array(0.0)), wm.shape)
        wo = 2 * (wi * wm).sum(-1, keepdims=True) * wm - wi
        ok = wo[..., 2] > 1e-6
        f = np.where(ok[..., None], ggx_lambert(wi, np.where(ok[..., None], wo, [0, 0, 1])), 0)
        rgb[0, t] = np.moveaxis(f * np.clip(wo[..., 2:3], 0, None), -1, 0)
    lum = 0.2126 * rgb[:, :, 0] + 0.7152 * rgb[:, :, 1] + 0.0722 * rgb[:, :, 2] + 1e-6
    write_tensor(path, {
        "description": np.frombuffer(b"GGX + Lambert, identity warp (test_rgl_reader.py)", np.uint8),
        "phi_i": np.zeros(1, np.float32),
        "theta_i": theta_i,
        "ndf": np.ones((2, 2), np.float32),
        "sigma": np.full((2, 2), 0.25, np.float32),
        "vndf": np.ones((1, thetas, 2, 2), np.float32),
        "luminance": lum.astype(np.float32),
        "rgb": rgb.astype(np.float32),
        "jacobian": np.ones(1, np.uint8),
    })


def random_file(path, rng, phis, thetas, n=8, wavelengths=None):
    """Random positive tables of unequal sizes: the vndf warp is far from
    the identity, and queries fall between parameter nodes. With
    `wavelengths`, `spectra` (one channel per wavelength) instead of `rgb`."""
    p = len(phis)
    pos = lambda *shape: (0.05 + rng.random(shape)).astype(np.float32)
    vndf = pos(p, len(thetas), 9, 11)
    channels = 3 if wavelengths is None else len(wavelengths)
    lum, rgb = pos(p, len(thetas), n, n), pos(p, len(thetas), channels, n, n)
    ndf, sigma = pos(5, 7), pos(4, 6) + 0.5
    if p > 1:  # anisotropic: the end slices (phi_i = -pi, pi) are equal
        for a in (vndf, lum, rgb):
            a[-1] = a[0]
    else:  # isotropic: ndf and sigma constant along phi (RGL_FORMAT.md section 3)
        ndf[:], sigma[:] = ndf[0], sigma[0]
    fields = {
        "description": np.frombuffer(b"random tables (test_rgl_reader.py)", np.uint8),
        "phi_i": np.asarray(phis, np.float32),
        "theta_i": np.asarray(thetas, np.float32),
        "ndf": ndf,
        "sigma": sigma,
        "vndf": vndf,
        "luminance": lum,
    }
    if wavelengths is None:
        fields["rgb"] = rgb
    else:
        fields["wavelengths"] = np.asarray(wavelengths, np.float32)
        fields["spectra"] = rgb
    fields["jacobian"] = np.ones(1, np.uint8)
    write_tensor(path, fields)


def uniform_dirs(rng, n):
    th = np.arccos(1 - rng.random(n) * (1 - np.cos(MAX_THETA)))
    return th, rng.random(n) * 2 * np.pi - np.pi


def npf_eval(path, ti, pi_, to, po, wavelengths=None):
    """npf's value f at (theta_i, phi_i) = the light, (theta_o, phi_o) =
    the view (RGL's conditioning direction): RGB, or a spectral file's
    values at `wavelengths`."""
    args = []
    for q in zip(ti, pi_, to, po):
        args += [f"{np.degrees(x):.9f}" for x in q]
    if wavelengths is not None:
        args += ["--wavelengths", ",".join(map(str, wavelengths))]
    lines = npf("eval", path, *args).stdout.splitlines()[1:]
    return np.array([[float(v) for v in l.split(",")[4:]] for l in lines])


def mitsuba_eval(path, wi, wo):
    """Mitsuba's value over cos(theta_o): si.wi is the view."""
    mi.set_variant("scalar_rgb")
    bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
    ctx = mi.BSDFContext()
    out = np.empty((len(wi), 3))
    for k in range(len(wi)):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi[k])
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
        out[k] = [v[0], v[1], v[2]]
    return out / wo[:, 2:3]


def mitsuba_eval_spectral(path, wi, wo, wavelengths):
    """Mitsuba `scalar_spectral`'s value over cos(theta_o) at each of
    `wavelengths` (four per call, the variant's wavelength samples)."""
    mi.set_variant("scalar_spectral")
    bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
    ctx = mi.BSDFContext()
    out = np.empty((len(wi), len(wavelengths)))
    for k in range(len(wi)):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi[k])
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        for j in range(0, len(wavelengths), 4):
            si.wavelengths = wavelengths[j:j + 4]
            v = bsdf.eval(ctx, si, mi.Vector3f(*wo[k]))
            out[k, j:j + 4] = [v[0], v[1], v[2], v[3]]
    return out / wo[:, 2:3]


@pytest.fixture(scope="module", params=["analytic", "random-isotropic", "random-anisotropic", "npf-export"])
def bsdf_file(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    path = d / "m.bsdf"
    rng = np.random.default_rng(11)
    if request.param == "analytic":
        analytic_file(path)
    elif request.param == "random-isotropic":
        random_file(path, rng, [0.0], np.radians([0, 20, 45, 70, 87]))
    elif request.param == "random-anisotropic":
        random_file(path, rng, np.linspace(-np.pi, np.pi, 5), np.radians([0, 30, 60, 87]))
    else:
        from _bsdf_scene import two_lobe_model

        model = d / "two-lobe.json"
        two_lobe_model(model)
        npf("export", model, "-o", path, "--theta-i", 24, "--samples", 32)
    return path


def test_reader_agrees_with_mitsuba(bsdf_file):
    rng = np.random.default_rng(3)
    ti, pi_ = uniform_dirs(rng, PAIRS)  # the light (RGL's wo)
    to, po = uniform_dirs(rng, PAIRS)  # the view (RGL's wi)
    got = npf_eval(bsdf_file, ti, pi_, to, po)
    ref = mitsuba_eval(bsdf_file, sph(to, po), sph(ti, pi_))
    err = np.abs(got - ref)
    bad = err > np.maximum(0.01 * np.abs(ref), 1e-4)
    print(f"{bsdf_file.parent.name}: max relative error {np.max(err / np.maximum(np.abs(ref), 1e-4)):.2e}, "
          f"{bad.any(axis=1).sum()} of {PAIRS} pairs outside the bound")
    assert not bad.any(), f"first outside: pair {np.argwhere(bad)[0]}: npf {got[bad][:3]}, Mitsuba {ref[bad][:3]}"


def test_the_analytic_file_holds_its_brdf(tmp_path):
    """The reader reproduces the BRDF the analytic file tabulates (the
    file's own interpolation error aside): median relative error < 2 %."""
    path = tmp_path / "a.bsdf"
    analytic_file(path)
    rng = np.random.default_rng(5)
    ti, pi_ = uniform_dirs(rng, 2000)
    to, po = uniform_dirs(rng, 2000)
    got = npf_eval(path, ti, pi_, to, po)
    want = ggx_lambert(sph(to, po), sph(ti, pi_))
    rel = np.abs(got - want).sum(1) / want.sum(1)
    print(f"median relative error against the analytic BRDF: {np.median(rel):.4%}")
    assert np.median(rel) < 0.02


# The spectral files' wavelengths, uneven; the queries fall on nodes,
# between them and beyond both ends (where Mitsuba holds the end values).
SPECTRAL_NODES = [380.0, 420.0, 455.0, 530.0, 600.0, 690.0, 730.0]
QUERY_WAVELENGTHS = [360.0, 380.0, 401.5, 455.0, 500.0, 612.25, 729.0, 800.0]


@pytest.fixture(scope="module", params=["random-spectral-isotropic", "random-spectral-anisotropic", "npf-export-spectral"])
def spectral_file(request, tmp_path_factory):
    d = tmp_path_factory.mktemp(request.param)
    path = d / "m.bsdf"
    rng = np.random.default_rng(17)
    if request.param == "random-spectral-isotropic":
        random_file(path, rng, [0.0], np.radians([0, 25, 50, 86]), wavelengths=SPECTRAL_NODES)
    elif request.param == "random-spectral-anisotropic":
        random_file(path, rng, np.linspace(-np.pi, np.pi, 4), np.radians([0, 40, 80]), wavelengths=SPECTRAL_NODES)
    else:
        from _bsdf_scene import two_lobe_model

        model = d / "two-lobe.json"
        two_lobe_model(model)
        npf("export", model, "-o", path, "--spectral", "--theta-i", 24, "--samples", 32)
    return path


def test_spectral_reader_agrees_with_mitsuba_scalar_spectral(spectral_file):
    """Issue 45: `npf eval --wavelengths` against Mitsuba 3 `scalar_spectral`
    at 10,000 random pairs and eight wavelengths each."""
    rng = np.random.default_rng(23)
    ti, pi_ = uniform_dirs(rng, PAIRS)
    to, po = uniform_dirs(rng, PAIRS)
    got = npf_eval(spectral_file, ti, pi_, to, po, QUERY_WAVELENGTHS)
    ref = mitsuba_eval_spectral(spectral_file, sph(to, po), sph(ti, pi_), QUERY_WAVELENGTHS)
    err = np.abs(got - ref)
    bad = err > np.maximum(0.01 * np.abs(ref), 1e-4)
    print(f"{spectral_file.parent.name}: max relative error {np.max(err / np.maximum(np.abs(ref), 1e-4)):.2e}, "
          f"{bad.any(axis=1).sum()} of {PAIRS} pairs outside the bound")
    assert np.all(ref >= 0) and np.any(ref > 0)
    assert not bad.any(), f"first outside: pair {np.argwhere(bad)[0]}: npf {got[bad][:3]}, Mitsuba {ref[bad][:3]}"
