#!/usr/bin/env python3
"""pbrt-v4 renders npf's spectral `.bsdf` exports: the sphere of npf's
renderer (src/render.rs), rendered by pbrt-v4's `measured` material from
`npf export --spectral`, against npf's own render of the model.

    PBRT=/path/to/pbrt python3 benches/pbrt_sphere.py [--res 64] [--spp 256] [--keep DIR]

Needs a pbrt-v4 binary (npf does not build it; docs/export.md says how it
was built here and what it measured), numpy and pillow, and npf's release
binary (NPF_BIN, default target/release/npf). Materials are made by npf:
the quick `npf demo` fit (isotropic), a two-lobe model with known factors,
and an anisotropic GGX model on the paper's 6 x 48 layout
(python/tests/_bsdf_scene.py, shared with the Mitsuba 3 test).

The scene is the one test_mitsuba_bsdf.py gives Mitsuba: an orthographic
view down -z of a unit sphere whose pole is +y (so pbrt's shading tangent,
dp/du around the pole, is npf's), three distant lights and the smooth
environment as an equal-area octahedral map (pbrt's only layout), direct
lighting only (path tracer, maxdepth 1). pbrt's camera frame is
left-handed; `Scale -1 1 1` before `LookAt` makes image x world x, as in
npf. Printed per material: PSNR of pbrt's display values against npf's
(`npf compare --images`, inner pixels, as the Mitsuba test), and the ratio
of the mean linear values per channel (a colour shift of the spectral
route shows there). Exit status 1 if a PSNR is below --min-psnr.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "python" / "tests"))
from _bsdf_scene import LIGHTS, anisotropic_model, display, environment, two_lobe_model  # noqa: E402

NPF = os.environ.get("NPF_BIN", str(ROOT / "target" / "release" / "npf"))


def npf(*args):
    run = subprocess.run([NPF, *map(str, args)], capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"npf {' '.join(map(str, args))}: exit {run.returncode}\n{run.stderr}")
    return run


def write_pfm(path, rgb):
    """`rgb`: (h, w, 3), row 0 at the top; PFM stores the bottom row first."""
    h, w, _ = rgb.shape
    with open(path, "wb") as f:
        f.write(f"PF\n{w} {h}\n-1\n".encode())
        f.write(np.ascontiguousarray(rgb[::-1], dtype="<f4").tobytes())


def read_pfm(path):
    data = Path(path).read_bytes()
    parts = data.split(b"\n", 3)
    assert parts[0] == b"PF", f"{path}: not an RGB PFM file"
    w, h = map(int, parts[1].split())
    scale = float(parts[2])
    img = np.frombuffer(parts[3], dtype="<f4" if scale < 0 else ">f4", count=w * h * 3)
    return img.reshape(h, w, 3)[::-1].astype(np.float64) * abs(scale)


def equal_area_square_to_sphere(u, v):
    """Clarberg's equal-area octahedral map of [0,1]^2 onto the sphere (the
    layout of pbrt-v4's image infinite lights), +z at the square's centre."""
    u, v = 2 * u - 1, 2 * v - 1
    up, vp = np.abs(u), np.abs(v)
    signed = 1 - (up + vp)
    r = 1 - np.abs(signed)
    phi = np.where(r == 0, 1.0, (vp - up) / np.where(r == 0, 1.0, r) + 1) * np.pi / 4
    z = np.copysign(1 - r * r, signed)
    s = r * np.sqrt(np.maximum(2 - r * r, 0.0))
    return np.copysign(np.cos(phi), u) * s, np.copysign(np.sin(phi), v) * s, z


def environment_octahedral(n=256):
    """The environment at pixel centres of pbrt's map: pixel (i, j), j from
    the top, is read at uv = ((i + 1/2) / n, (j + 1/2) / n). The light is
    declared with the identity transform, so its frame is the world's."""
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, c)  # u along columns, v along rows
    _, y, _ = equal_area_square_to_sphere(u, v)
    return environment(y)


def scene_text(bsdf, env, out, res, spp):
    lights = "\n".join(
        'LightSource "distant" "point3 from" [{} {} {}] "point3 to" [0 0 0] "rgb L" [{} {} {}]'.format(
            *(np.array(d) / np.linalg.norm(d)), *e
        )
        for d, e in LIGHTS
    )
    return f"""Scale -1 1 1
LookAt 0 0 5  0 0 0  0 1 0
Camera "orthographic"
Sampler "independent" "integer pixelsamples" {spp}
Integrator "path" "integer maxdepth" 1
PixelFilter "box"
Film "rgb" "integer xresolution" {res} "integer yresolution" {res} "string filename" "{out}"
WorldBegin
{lights}
LightSource "infinite" "string filename" "{env}"
AttributeBegin
  Rotate -90 1 0 0
  Material "measured" "string filename" "{bsdf}"
  Shape "sphere" "float radius" 1
AttributeEnd
"""


def material(kind, d):
    """(model, table for `npf compare`, export options)."""
    if kind == "demo-fit":
        npf("demo", "-o", d / "demo", "--quiet", "--lobes", "1", "--max-sweeps", "4", "--force")
        return d / "demo" / "ggx-lambert.json", d / "demo" / "ggx-lambert.binary", []
    if kind == "two-lobe":
        model, table = d / "two-lobe.json", d / "two-lobe.binary"
        two_lobe_model(model)
    else:
        model, table = d / "aniso.json", d / "aniso.bin"
        anisotropic_model(model)
    npf("reconstruct", model, "-o", table, "--force")
    # The anisotropic file as small as the Mitsuba test's (13 x 48 slices of 48 x 48).
    return model, table, (["--theta-i", 32, "--samples", 48] if kind == "anisotropic" else [])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pbrt", default=os.environ.get("PBRT"), help="pbrt-v4 binary (or PBRT)")
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--min-psnr", type=float, default=35.0)
    ap.add_argument("--keep", type=Path, help="keep the scenes and images here")
    ap.add_argument("--materials", default="demo-fit,two-lobe,anisotropic")
    a = ap.parse_args()
    if not a.pbrt:
        ap.error("no pbrt-v4 binary: give --pbrt or set PBRT")
    from PIL import Image

    base = a.keep or Path(tempfile.mkdtemp(prefix="npf-pbrt-"))
    base.mkdir(parents=True, exist_ok=True)
    env = base / "environment.pfm"
    write_pfm(env, environment_octahedral())
    c = 2 * (np.arange(a.res) + 0.5) / a.res - 1
    x, y = np.meshgrid(c, -c)
    # Pixels well inside the silhouette: the box filter averages edge pixels with the background.
    inner = x * x + y * y < (1 - 2.5 / a.res) ** 2
    worst = np.inf
    print(f"{'material':<12} {'PSNR dB':>8}  mean pbrt / npf (linear R, G, B)   pbrt s")
    for kind in a.materials.split(","):
        d = base / kind
        d.mkdir(exist_ok=True)
        model, table, opts = material(kind, d)
        bsdf = d / "m-spectral.bsdf"
        npf("export", model, "-o", bsdf, "--spectral", "--force", *opts)
        (d / "img").mkdir(exist_ok=True)
        npf("compare", table, model, "--images", d / "img", "--res", a.res, "--n-theta", 96, "--force")
        ref = np.asarray(Image.open(d / "img" / "test.png").convert("RGB"), dtype=np.float64) / 255.0
        (d / "scene.pbrt").write_text(scene_text(bsdf, env, d / "pbrt.pfm", a.res, a.spp))
        start = time.monotonic()
        run = subprocess.run(
            [a.pbrt, "--quiet", str(d / "scene.pbrt")], capture_output=True, text=True
        )
        secs = time.monotonic() - start
        if run.returncode != 0:
            sys.exit(f"{kind}: pbrt failed ({run.returncode}):\n{run.stderr[-2000:]}")
        lin = read_pfm(d / "pbrt.pfm")
        got = display(lin)
        psnr = 10 * np.log10(1 / ((got - ref)[inner] ** 2).mean())
        # npf's linear values, undone from its 8-bit display image (Reinhard + sRGB).
        r = np.where(ref <= 0.04045, ref / 12.92, ((ref + 0.055) / 1.055) ** 2.4)
        r = np.minimum(r, 0.999)
        ratio = lin[inner].mean(0) / (r / (1 - r))[inner].mean(0)
        print(f"{kind:<12} {psnr:8.2f}  {ratio[0]:.4f} {ratio[1]:.4f} {ratio[2]:.4f}   {secs:.1f}")
        worst = min(worst, psnr)
    print(f"worst PSNR {worst:.2f} dB (bar {a.min_psnr} dB); files in {base}")
    sys.exit(0 if worst >= a.min_psnr else 1)


if __name__ == "__main__":
    main()
