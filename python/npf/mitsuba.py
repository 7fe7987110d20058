"""Mitsuba 3 BSDF plugin ``"npf"``: render an npf fit with npf's own kernels.

::

    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    import npf.mitsuba
    npf.mitsuba.register()
    bsdf = mi.load_dict({"type": "npf", "filename": "gold.json"})

Every call goes to npf's evaluator and tabulated importance sampler (no
re-tabulation): ``eval`` is f(wo, wi) cos(theta_light), ``sample`` draws with
npf's sampler and returns its weight f cos / pdf, ``pdf`` is exactly the
density ``sample`` draws with.

Conventions: Mitsuba's ``si.wi`` points towards the viewer (npf's ``wo``) and
Mitsuba's ``wo`` towards the light (npf's ``wi``). The BSDF is one-sided (zero
when either direction is below the surface), reflection only.

Variants: ``scalar_rgb`` calls npf once per query (tested in
python/tests/test_mitsuba.py, renders included); the vectorised RGB variants
(``llvm_ad_rgb``, ``cuda_ad_rgb``) hand over whole wavefronts, which go to
npf's batched calls through numpy (llvm's calls are tested, not its renders;
see docs/python.md). Those need Dr.Jit's symbolic loops and calls switched off
(``register`` does it), since npf runs on concrete arrays; they are not
differentiable (npf's parameters are not Dr.Jit variables). Spectral and
polarised variants are not supported (npf's models are RGB); ``mono``
variants get the mean of the three channels.

Parameters of the plugin: ``filename`` (a ``.json`` or ``.npfb`` model file).
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from . import Model, load

_registered_variants: set = set()


def _scalar(variant: str) -> bool:
    return variant.startswith("scalar")


def _make_class(mi: Any, dr: Any) -> type:
    variant = mi.variant()
    if "spectral" in variant or "polarized" in variant:
        raise RuntimeError(
            f"npf's Mitsuba plugin supports RGB and mono variants, not {variant!r}"
        )
    mono = "mono" in variant
    scalar = _scalar(variant)

    def color(rgb: Any) -> Any:
        if mono:
            if scalar:
                return mi.Color1f(sum(rgb) / 3.0)
            return mi.Color1f(np.asarray(rgb).mean(axis=1))
        if scalar:
            return mi.Color3f(*rgb)
        a = np.asarray(rgb)
        return mi.Color3f(a[:, 0], a[:, 1], a[:, 2])

    def vec_np(v: Any) -> np.ndarray:
        # A Dr.Jit 3-vector of arrays as an (N, 3) numpy array.
        return np.stack([np.asarray(v.x), np.asarray(v.y), np.asarray(v.z)], axis=1).astype(
            np.float64
        )

    flags = (
        mi.BSDFFlags.GlossyReflection
        | mi.BSDFFlags.DiffuseReflection
        | mi.BSDFFlags.FrontSide
    )

    class NpfBSDF(mi.BSDF):
        """npf model as a Mitsuba BSDF (see the module notes)."""

        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            if "filename" not in props:
                raise ValueError('the "npf" BSDF needs a "filename" (.json or .npfb model)')
            path = str(props["filename"])
            resolver = mi.file_resolver() if hasattr(mi, "file_resolver") else mi.Thread.thread().file_resolver()
            self.filename = str(resolver.resolve(path))
            self.model: Model = load(self.filename)
            self.m_flags = flags
            self.m_components = [flags]

        # -- scalar path: one query per call, plain floats.
        def _s_eval(self, si: Any, wo: Any) -> Any:
            v = si.wi
            if v.z <= 0 or wo.z <= 0:
                return color((0.0, 0.0, 0.0))
            f = self.model._eval1((wo.x, wo.y, wo.z), (v.x, v.y, v.z))
            return color(tuple(c * wo.z for c in f))

        def _s_pdf(self, si: Any, wo: Any) -> float:
            v = si.wi
            if v.z <= 0 or wo.z <= 0:
                return 0.0
            return self.model._pdf1((v.x, v.y, v.z), (wo.x, wo.y, wo.z))

        # -- vectorised path: whole wavefronts through numpy.
        def _v_eval_pdf(self, si: Any, wo: Any, active: Any, want_pdf: bool) -> Any:
            v, w = vec_np(si.wi), vec_np(wo)
            ok = (v[:, 2] > 0) & (w[:, 2] > 0) & np.asarray(active, dtype=bool)
            f = np.zeros((len(v), 3))
            p = np.zeros(len(v))
            if ok.any():
                f[ok] = self.model.eval(w[ok], v[ok]) * w[ok, 2:3]
                if want_pdf:
                    p[ok] = self.model.pdf(v[ok], w[ok])
            return color(f), mi.Float(p)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar:
                return self._s_eval(si, wo) if active else color((0.0, 0.0, 0.0))
            return self._v_eval_pdf(si, wo, active, False)[0]

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar:
                return self._s_pdf(si, wo) if active else 0.0
            return self._v_eval_pdf(si, wo, active, True)[1]

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            if scalar:
                if not active:
                    return color((0.0, 0.0, 0.0)), 0.0
                return self._s_eval(si, wo), self._s_pdf(si, wo)
            return self._v_eval_pdf(si, wo, active, True)

        def sample(
            self, ctx: Any, si: Any, sample1: Any, sample2: Any, active: Any = True
        ) -> Any:
            bs = mi.BSDFSample3f()
            if scalar:
                v = si.wi
                if not active or v.z <= 0:
                    return bs, color((0.0, 0.0, 0.0))
                wi, pdf, weight = self.model._sample1(
                    (v.x, v.y, v.z), (sample1, sample2.x, sample2.y)
                )
                bs.wo = mi.Vector3f(*wi)
                bs.pdf = pdf
                bs.eta = 1.0
                bs.sampled_type = +mi.BSDFFlags.GlossyReflection
                bs.sampled_component = 0
                return bs, color(weight)
            v = vec_np(si.wi)
            u = np.stack(
                [np.asarray(sample1), np.asarray(sample2.x), np.asarray(sample2.y)], axis=1
            ).astype(np.float64)
            ok = (v[:, 2] > 0) & np.asarray(active, dtype=bool)
            wi = np.tile([0.0, 0.0, 1.0], (len(v), 1))
            pdf = np.zeros(len(v))
            weight = np.zeros((len(v), 3))
            if ok.any():
                wi[ok], pdf[ok], weight[ok] = self.model.sample(v[ok], u[ok])
            bs.wo = mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])
            bs.pdf = mi.Float(pdf)
            bs.eta = mi.Float(np.ones(len(v)))
            bs.sampled_type = mi.UInt32(np.full(len(v), int(mi.BSDFFlags.GlossyReflection), dtype=np.uint32))
            bs.sampled_component = mi.UInt32(np.zeros(len(v), dtype=np.uint32))
            return bs, color(weight)

        def traverse(self, callback: Any) -> None:
            pass

        def parameters_changed(self, keys: Any = []) -> None:
            pass

        def to_string(self) -> str:
            return f"NpfBSDF[filename={self.filename!r}, {self.model!r}]"

    return NpfBSDF


def register(name: str = "npf") -> None:
    """Register the BSDF plugin ``name`` (default ``"npf"``) for Mitsuba's
    current variant (call ``mi.set_variant`` first; call again after
    switching variants)."""
    import drjit as dr
    import mitsuba as mi

    variant: Optional[str] = mi.variant()
    if variant is None:
        raise RuntimeError("set a Mitsuba variant (mi.set_variant) before npf.mitsuba.register()")
    if not _scalar(variant):
        # npf runs on concrete arrays: Mitsuba must evaluate wavefronts
        # instead of recording symbolic loops and calls.
        dr.set_flag(dr.JitFlag.SymbolicLoops, False)
        dr.set_flag(dr.JitFlag.SymbolicCalls, False)
    cls = _make_class(mi, dr)
    mi.register_bsdf(name, lambda props: cls(props))
    _registered_variants.add((variant, name))
