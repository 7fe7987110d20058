"""What the renderer checks share (test_mitsuba_bsdf.py, test_rgl_reader.py
and benches/pbrt_sphere.py): models with known factors written as npf's
JSON model files, and the scene of src/render.rs (lights, environment,
display values) for other renderers to reproduce. numpy only."""

import json

import numpy as np


def ggx_d(t, a):
    return a * a / (np.pi * np.cos(t) ** 4 * (a * a + np.tan(t) ** 2) ** 2)


def smith_g1(t, a):
    t = np.minimum(t, np.pi / 2 - 1e-6)
    return 2 / (1 + np.sqrt(1 + a * a * np.tan(t) ** 2))


def two_lobe_model(path, n=90, separable=False):
    """A model with known factors written as npf's JSON model file
    (docs: the file's `conventions`): a near-mirror GGX lobe (alpha 0.05)
    and a broad one (alpha 0.4), Schlick Fresnel, a little diffuse; with
    `separable`, more diffuse, with the separable form's factor P(theta_i)
    P(theta_o) of Ashikhmin-Shirley's coupled diffuse (16 nodes)."""
    theta_d = (np.arange(n) / n) ** 2 * np.pi / 2  # sqrt_angle nodes
    theta_f = np.arange(n) / n * np.pi / 2  # uniform nodes
    theta_g = np.arange(n) / (n - 1) * np.pi / 2  # Catmull-Rom control points
    lobe = lambda s, a: {"s": s, "d": ggx_d(theta_d, a).tolist(), "g": smith_g1(theta_g, a).tolist()}
    model = {
        "layout": {k: {"kind": kind, "n": n} for k, kind in (("d", "sqrt_angle"), ("f", "uniform"), ("g", "catmull_rom"))},
        "diffuse": [0.02, 0.03, 0.05],
        "fresnel": [(f0 + (1 - f0) * (1 - np.cos(theta_f)) ** 5).tolist() for f0 in (0.9, 0.7, 0.5)],
        "lobes": [lobe([0.12, 0.12, 0.12], 0.05), lobe([0.1, 0.15, 0.2], 0.4)],
    }
    if separable:
        theta_p = np.arange(16) / 15 * np.pi / 2
        model["diffuse"] = [0.1, 0.12, 0.15]
        model["diffuse_form"] = {"form": "separable", "p": (1 - (1 - np.cos(theta_p) / 2) ** 5).tolist()}
    path.write_text(json.dumps({"format": "npf-model", "version": 1, "model": model}))


def anisotropic_model(path, ax=0.2, ay=0.5):
    """The paper's anisotropic layout (src/model.rs `Layout::anisotropic`:
    D on 6 x 48 (theta_h, phi_h) nodes, G on 6 x 48 Catmull-Rom x linear
    phi nodes, F on 90) with an anisotropic GGX D and its Smith G."""
    nphi = 48
    phi = 2 * np.pi * np.arange(nphi) / nphi
    theta_d = np.arange(6) / 6 * np.pi / 2  # uniform nodes
    theta_g = np.arange(6) / 5 * np.pi / 2  # Catmull-Rom control points
    t, p = np.meshgrid(theta_d, phi, indexing="ij")
    e = np.tan(t) ** 2 * (np.cos(p) ** 2 / ax**2 + np.sin(p) ** 2 / ay**2)
    d = 1 / (np.pi * ax * ay * np.cos(t) ** 4 * (1 + e) ** 2)
    t, p = np.meshgrid(theta_g, phi, indexing="ij")
    g = smith_g1(t, np.sqrt(np.cos(p) ** 2 * ax**2 + np.sin(p) ** 2 * ay**2))
    theta_f = np.arange(90) / 90 * np.pi / 2
    plane = lambda kind, n: {"kind": kind, "n": n, "phi": {"n": nphi}}
    model = {
        "layout": {"d": plane("uniform", 6), "f": {"kind": "uniform", "n": 90}, "g": plane("catmull_rom", 6)},
        "diffuse": [0.03, 0.03, 0.03],
        "fresnel": [(f0 + (1 - f0) * (1 - np.cos(theta_f)) ** 5).tolist() for f0 in (0.95, 0.8, 0.6)],
        "lobes": [{"s": [0.2, 0.2, 0.2], "d": d.ravel().tolist(), "g": g.ravel().tolist()}],
    }
    path.write_text(json.dumps({"format": "npf-model", "version": 1, "model": model}))


# --- the scene of src/render.rs ---------------------------------------------

SKY = np.array([0.40, 0.50, 0.70])
GROUND = np.array([0.30, 0.22, 0.15])
LIGHTS = [
    ([-0.5, 0.6, 0.62], [3.0, 2.85, 2.6]),
    ([0.7, 0.2, 0.7], [0.6, 0.7, 0.9]),
    ([0.15, 0.4, -0.9], [2.0, 2.0, 2.0]),
]


def environment(y):
    """Radiance (RGB, last axis) of the environment in directions with world
    y component `y` (any shape)."""
    y = np.asarray(y)[..., None]
    return SKY * (0.55 + 0.45 * y) + GROUND * (0.5 - 0.5 * y) ** 2


def environment_bitmap(h=256):
    """Mitsuba's latitude-longitude envmap of the environment: L(w) depends
    on w_y only, so only its polar coordinate (v = acos(w_y) / pi) matters."""
    L = environment(np.cos(np.pi * (np.arange(h) + 0.5) / h))
    return np.ascontiguousarray(np.repeat(L[:, None, :], 2 * h, axis=1), dtype=np.float32)


def display(l):
    l = np.maximum(l, 0.0)
    x = l / (1 + l)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
