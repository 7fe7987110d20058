"""npf: fit measured BRDFs with the shared-factor non-parametric microfacet model.

The compiled core (``npf._npf``) does the work; this package re-exports it::

    import npf
    model = npf.fit("gold.binary", lobes=3)       # or a (3, 90, 90, 180) array
    model.save("gold.json")
    rgb = npf.load("gold.json").eval(wi, wo)      # (N, 3) arrays, local frame

Directions are unit vectors in the local shading frame (normal +z); ``wi``
points towards the light, ``wo`` towards the viewer (as ``npf eval``).
``npf.mitsuba.register()`` adds the Mitsuba 3 BSDF plugin ``"npf"``.
"""

from ._npf import (
    EXPORT_FORMATS,
    Model,
    __version__,
    fit,
    from_json,
    load,
    read_merl,
    write_merl,
)

__all__ = [
    "EXPORT_FORMATS",
    "Model",
    "__version__",
    "fit",
    "from_json",
    "load",
    "read_merl",
    "write_merl",
]
