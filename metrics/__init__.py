"""raster-oracle metrics: plain functions of NumPy arrays, no rendering.

Conventions: images are float ``(H, W)`` or ``(H, W, C)``, row 0 at the top, linear values;
visibility and coverage are in [0, 1] with 1 = lit / covered. Invalid input raises
:class:`MetricError` (a ``ValueError``) with a message naming the parameter.

Modules: :mod:`metrics.tonemap` (the shared tone-mapping pipeline), :mod:`metrics.perceptual`
(FLIP, SSIM, PSNR, CIEDE2000), :mod:`metrics.shadow` (visibility on receivers),
:mod:`metrics.aliasing` (edge/interior and coverage error, straight-edge floor),
:mod:`metrics.temporal` (flicker), :mod:`metrics.depth` (linear view depth),
:mod:`metrics.ghosting` (convergence, ghosting, lag, flicker ratio and map of a temporal
AA), :mod:`metrics.motion` (motion-vector conventions and end-point error),
:mod:`metrics.stats` (Z-test, noise floor),
:mod:`metrics.catalog` (every scored metric's direction, unit and applicability).
"""

from .aliasing import (
    COVERAGE_FLOOR_RMS,
    COVERAGE_KEYS,
    coverage_error,
    coverage_metrics,
    edge_interior_error,
    edges_from_id,
    half_plane_square_area,
    straight_edge_error_floor,
)
from .catalog import CATALOG
from .depth import DEPTH_KEYS, depth_metrics, hyperbolic_rounding
from .diagnose import diagnose
from .ghosting import (
    convergence,
    disocclusion_age,
    flicker_map,
    flicker_ratio,
    frame_errors,
    ghosting,
    history_error,
)
from .motion import from_oracle_motion, motion_errors, to_oracle_motion
from .perceptual import (
    DEFAULT_PPD,
    delta_e2000,
    delta_e2000_lab,
    flip,
    hdr_exposure_range,
    psnr_db,
    ssim,
)
from .shadow import SHADOW_KEYS, shadow_edges, shadow_metrics
from .stats import (
    FRACTION_FLOOR_Z,
    binomial_stderr_floor,
    exact_surrogate,
    fraction_floor,
    noise_floor,
    z_test,
)
from .temporal import added_flicker, flicker, temporal_error
from .tonemap import (
    exposure_from_reference,
    luminance,
    srgb_decode,
    srgb_encode,
    tonemap,
)
from .validate import MetricError

__all__ = [
    "CATALOG",
    "COVERAGE_FLOOR_RMS",
    "COVERAGE_KEYS",
    "added_flicker",
    "coverage_metrics",
    "DEFAULT_PPD",
    "SHADOW_KEYS",
    "MetricError",
    "convergence",
    "coverage_error",
    "disocclusion_age",
    "flicker_map",
    "flicker_ratio",
    "frame_errors",
    "from_oracle_motion",
    "ghosting",
    "history_error",
    "motion_errors",
    "to_oracle_motion",
    "delta_e2000",
    "delta_e2000_lab",
    "edge_interior_error",
    "edges_from_id",
    "exposure_from_reference",
    "flicker",
    "flip",
    "half_plane_square_area",
    "hdr_exposure_range",
    "luminance",
    "noise_floor",
    "FRACTION_FLOOR_Z",
    "binomial_stderr_floor",
    "DEPTH_KEYS",
    "depth_metrics",
    "diagnose",
    "hyperbolic_rounding",
    "fraction_floor",
    "exact_surrogate",
    "psnr_db",
    "shadow_edges",
    "shadow_metrics",
    "srgb_decode",
    "srgb_encode",
    "ssim",
    "straight_edge_error_floor",
    "temporal_error",
    "tonemap",
    "z_test",
]
