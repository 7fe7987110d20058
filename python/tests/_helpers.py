"""Shared helpers of npf's Python tests: models and tables the tests make
themselves (no measured data), and the npf program (NPF_BIN)."""

import math
import os
import shutil
import subprocess

import numpy as np

import npf

HALF_PI = math.pi / 2


def ggx_d(theta, alpha):
    c2 = np.cos(theta) ** 2
    t2 = (1 - c2) / np.maximum(c2, 1e-300)
    a2 = alpha * alpha
    return 1 / (math.pi * a2 * c2 * c2 * (1 + t2 / a2) ** 2)


def smith_g1(theta, alpha):
    c = np.cos(theta)
    t2 = (1 - c * c) / np.maximum(c * c, 1e-300)
    return np.where(c > 1e-12, 2 / (1 + np.sqrt(1 + alpha * alpha * t2)), 0.0)


def known_factor_model(alphas=(0.05, 0.2, 0.5), n=90):
    """Smooth known factors (npf::synth::known_factor_model's shapes): GGX D
    per lobe on MERL's theta_h nodes, Smith-like G at the Catmull-Rom control
    points, Schlick F per channel on the theta_d nodes."""
    k = np.arange(n)
    theta_h = (k / n) ** 2 * HALF_PI
    theta_d = k / n * HALF_PI
    theta_g = k / (n - 1) * HALF_PI
    f0 = np.array([0.9, 0.6, 0.3])
    F = f0[:, None] + (1 - f0[:, None]) * (1 - np.cos(theta_d))[None, :] ** 5
    scales = np.array([[0.8, 0.5, 0.3], [0.2, 0.3, 0.5], [0.1, 0.1, 0.1]])
    s = np.array([scales[m % 3] for m in range(len(alphas))])
    D = np.array([ggx_d(theta_h, a) for a in alphas])
    G = np.array([smith_g1(theta_g, 1.5 * a) for a in alphas])
    return npf.Model(np.array([0.05, 0.08, 0.03]), s, F, D, G)


def spherical(theta, phi):
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def random_directions(rng, n, max_theta=math.radians(85)):
    """Directions uniform in solid angle over the cap theta <= max_theta."""
    z = 1 - rng.random(n) * (1 - math.cos(max_theta))
    phi = rng.random(n) * 2 * math.pi
    r = np.sqrt(np.maximum(0, 1 - z * z))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def npf_bin():
    """The npf program: NPF_BIN (tests/run-all.sh sets it), else on PATH."""
    path = os.environ.get("NPF_BIN") or shutil.which("npf")
    if not path or not os.path.exists(path):
        raise RuntimeError("set NPF_BIN to the npf program (cargo build --release)")
    return path


def run_npf(*args):
    return subprocess.run(
        [npf_bin(), *map(str, args)], check=True, capture_output=True, text=True
    ).stdout
