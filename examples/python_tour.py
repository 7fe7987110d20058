"""A tour of npf from Python, notebook style (run: python examples/python_tour.py [OUT_DIR]).

1. Make a table: a GGX + Lambert BRDF tabulated as a MERL table in numpy
   (npf's own demo material, nothing measured).
2. Fit it with npf.fit, watching the sweeps; save and reload the model.
3. Plot the factors (if matplotlib is installed).
4. Render a sphere in Mitsuba 3 with the "npf" plugin (if Mitsuba is
   installed), and next to it the exported .bsdf in Mitsuba's "measured"
   plugin when this build can export .bsdf (issue 13); skipped otherwise.
"""

import math
import sys
import time
from pathlib import Path

import numpy as np

import npf

out = Path(sys.argv[1] if len(sys.argv) > 1 else "python-tour")
out.mkdir(parents=True, exist_ok=True)

# %% 1. A synthetic MERL table: GGX (alpha 0.15) + Lambert, Schlick Fresnel.
kd, f0, alpha = np.array([0.05, 0.08, 0.12]), np.array([0.95, 0.64, 0.54]), 0.15
i_h, i_d, i_p = np.meshgrid(np.arange(90), np.arange(90), np.arange(180), indexing="ij")
th, td, pd = (i_h / 90) ** 2 * math.pi / 2, i_d * math.pi / 180, i_p * math.pi / 180
# Directions from the half/difference angles (phi_h = 0): rotate (theta_d,
# phi_d) about y by theta_h.
wi_l = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
wo_l = wi_l * [-1, -1, 1]
rot = lambda v: np.stack(  # noqa: E731
    [v[..., 0] * np.cos(th) + v[..., 2] * np.sin(th), v[..., 1], -v[..., 0] * np.sin(th) + v[..., 2] * np.cos(th)], -1
)
ci, co = rot(wi_l)[..., 2], rot(wo_l)[..., 2]
a2, c2 = alpha**2, np.cos(th) ** 2
D = 1 / (math.pi * a2 * c2 * c2 * (1 + (1 - c2) / c2 / a2) ** 2)
g1 = lambda c: 2 / (1 + np.sqrt(1 + a2 * (1 - c * c) / np.maximum(c * c, 1e-12)))  # noqa: E731
F = f0[:, None, None, None] + (1 - f0[:, None, None, None]) * (1 - np.cos(td)) ** 5
with np.errstate(divide="ignore", invalid="ignore"):
    rho = kd[:, None, None, None] / math.pi + D * F * g1(ci) * g1(co) / (4 * ci * co)
table = np.where((ci > 0) & (co > 0), rho, -1.0)
npf.write_merl(out / "ggx.binary", table, overwrite=True)
print(f"table: {np.sum(table[0] >= 0)} valid cells of {table[0].size}")

# %% 2. Fit (GIL released; progress gets every sweep's report).
t0 = time.perf_counter()
model = npf.fit(
    out / "ggx.binary",
    lobes=3,
    progress=lambda r: r["sweep"] % 10 == 0 and print(f"  sweep {r['sweep']:3d}  objective {r['objective']:.6e}"),
)
print(f"fitted {model!r} in {time.perf_counter() - t0:.1f} s; errors: {model.fit_info['metrics']}")
model.save(out / "ggx.json", overwrite=True)
model = npf.load(out / "ggx.json")
wo = np.array([[math.sin(0.5), 0.0, math.cos(0.5)]])
print("albedo at 28.6 deg:", model.albedo(wo)[0])

# %% 3. The factors.
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(12, 3.5))
    axes = model.axes
    for m in range(model.lobes):
        ax[0].semilogy(np.degrees(axes["D"]["theta"]), np.maximum(model.D[m], 1e-6), label=f"lobe {m}")
        ax[2].plot(np.degrees(axes["G"]["theta"]), model.G[m], label=f"lobe {m}")
    for c, name in enumerate("RGB"):
        ax[1].plot(np.degrees(axes["F"]["theta"]), model.F[c], color=name.lower().replace("g", "green"), label=name)
    for a, t in zip(ax, ["D(theta_h)", "F(theta_d)", "G(theta)"]):
        a.set_title(t), a.set_xlabel("degrees"), a.legend()
    fig.tight_layout()
    fig.savefig(out / "factors.png", dpi=100)
    print(f"factors plotted: {out / 'factors.png'}")
except ImportError:
    print("matplotlib not installed: no factor plot")

# %% 4. Render a sphere with the plugin (and the exported .bsdf).
try:
    import mitsuba as mi
except ImportError:
    mi = None
    print("Mitsuba 3 not installed (pip install mitsuba): no renders")

if mi is not None:
    mi.set_variant("scalar_rgb")
    import npf.mitsuba

    npf.mitsuba.register()

    def sphere(bsdf):
        return mi.load_dict(
            {
                "type": "scene",
                "integrator": {"type": "path", "max_depth": 4},
                "sensor": {
                    "type": "perspective",
                    "fov": 28,
                    "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 4.5], target=[0, 0, 0], up=[0, 1, 0]),
                    "film": {"type": "hdrfilm", "width": 96, "height": 96},
                    "sampler": {"type": "independent", "sample_count": 16},
                },
                "sphere": {"type": "sphere", "bsdf": bsdf},
                "light": {"type": "point", "position": [3, 3, 4], "intensity": {"type": "rgb", "value": 40.0}},
                "env": {"type": "constant", "radiance": {"type": "rgb", "value": 0.15}},
            }
        )

    t0 = time.perf_counter()
    img = np.array(mi.render(sphere({"type": "npf", "filename": str(out / "ggx.json")})))
    print(f"npf plugin render: {time.perf_counter() - t0:.1f} s, NaN: {np.isnan(img).any()}")
    images = [img]
    if ".bsdf" in npf.EXPORT_FORMATS:
        model.export(out / "ggx.bsdf", overwrite=True)
        try:
            images.append(np.array(mi.render(sphere({"type": "measured", "filename": str(out / "ggx.bsdf")}))))
        except Exception as e:  # the measured plugin's variants differ by release
            print(f"Mitsuba's measured plugin could not render the .bsdf: {e}")
    else:
        print("this npf build exports no .bsdf yet (issue 13): plugin render only")
    side = np.concatenate(images, axis=1)
    mi.util.write_bitmap(str(out / "spheres.png"), side)
    print(f"rendered: {out / 'spheres.png'} ({len(images)} image(s) side by side)")
