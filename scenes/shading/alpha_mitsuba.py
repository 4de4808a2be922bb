"""Alpha-tested shapes of a Mitsuba scene (an XML file): shapes whose BSDF is Mitsuba's
``mask`` become alpha-tested with the mask's ``opacity`` as their alpha.

Mitsuba's ``mask`` BSDF is stochastic: a ray meets the surface with probability ``opacity``
and passes through otherwise. The oracle's truth is an alpha test instead: a point is kept
where ``opacity >= cutoff`` (:data:`~.alpha.DEFAULT_CUTOFF`, 0.5, unless the caller gives
another). Where the opacity texture holds only 0 and 1 (a ``bitmap`` with
``filter_type="nearest"``, or a binary mask) both agree exactly, which the tests check against
Mitsuba's own path tracer; with fractional opacity the two differ by design (an alpha test
is what a rasterizer's cut-out does).

The opacity is evaluated by Mitsuba itself at each hit (``BSDF.eval_attribute_1("opacity")``),
so its texture's filter, wrap mode and UV transform are the ones the XML gives.
"""

from __future__ import annotations

import numpy as np

from .alpha import DEFAULT_CUTOFF, AlphaMask, AlphaTable

__all__ = ["alpha_table_from_bsdfs", "is_mask_bsdf"]


def is_mask_bsdf(mi, bsdf) -> bool:
    """Whether ``bsdf`` (a Mitsuba BSDF) is a ``mask``: a null (pass-through) component and
    an ``opacity`` parameter."""
    if bsdf is None:
        return False
    if not (int(bsdf.flags()) & int(mi.BSDFFlags.Null)):
        return False
    return any(k == "opacity" or k.startswith("opacity.") for k in mi.traverse(bsdf).keys())


def alpha_table_from_bsdfs(mi, mi_scene, *, cutoff: float = DEFAULT_CUTOFF) -> AlphaTable | None:
    """The :class:`~.alpha.AlphaTable` of ``mi_scene``'s shapes (in ``shapes()`` order): one
    mask per shape whose BSDF is a ``mask`` (alpha = its opacity, kept at ``cutoff``), or
    None when no shape has one."""
    shapes = mi_scene.shapes()
    masks: list[AlphaMask] = []
    shape_mask = np.full(len(shapes), -1, dtype=np.int32)
    for k, shape in enumerate(shapes):  # shapes of a scene, not pixels
        if is_mask_bsdf(mi, shape.bsdf()):
            shape_mask[k] = len(masks)
            name = shape.id() or f"shape {k}"
            masks.append(AlphaMask(cutoff=float(cutoff), name=name, bsdf_opacity=True))
    if not masks:
        return None
    return AlphaTable(masks, shape_mask)
