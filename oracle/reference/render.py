"""Ground-truth rendering: supersampled visibility, coverage and a box-filtered shaded image.

Sub-pixel samples are stratified: ``spp = m * n`` with ``m >= n`` as close as possible, one
jittered sample per cell of an ``m x n`` grid over the pixel, jitter from a 6-round 32-bit TEA
hash of (pixel, sample, seed) (:func:`sample_jitter`), so results do not depend on chunking.
Every cell is used, so the estimate is unbiased for any ``spp`` (a prime ``spp`` stratifies
along x only).

Standard errors are ``sqrt(s^2 / N)`` with the unbiased sample variance ``s^2`` of the pixel's
``N`` samples (conservative for stratified samples), floored for the binary quantities
(visibility, coverage) at the binomial floor of :func:`metrics.stats.binomial_stderr_floor`
(Jeffreys: ``p = 0.5 / (N + 1)``, ``sqrt(p (1 - p) / N)``): a pixel whose samples all agree is
not known exactly, a feature smaller than the sample spacing may have been missed. The colour
standard error is the sample one (its floor depends on the radiance a missed feature could
have; the score's Z-test applies it).

With ``adaptive``, a first pass at ``adaptive_spp`` samples covers every pixel; then a pixel
refines (a further pass of as many samples again, doubling up to ``max_spp``) while it lies
near a feature and its standard error exceeds ``target_stderr``. Near a feature: the pixel or
one of its 3x3 neighbours shows an edge (its samples disagree on shape id, visibility or
coverage, or what they agree on differs from a neighbour's), dilated by one pixel; the
standard error is the Jeffreys binomial one (:func:`binary_stderr`: the floor when all samples
agree) and, with colour, the colour's sample one. A pixel's own standard error cannot see a
thin feature that all its samples missed, its neighbours' samples can: refinement spreads
along a feature from the pixels that caught it (stopped pixels rejoin when a neighbour shows
one), and pixels far from every feature stop after the first pass, reporting their floor.
Adaptive passes take points of a per-pixel scrambled Sobol (0, 2)-sequence
(:func:`sobol_sample`), so each doubling is a stratified net and so is the union.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from ...metrics.stats import binomial_stderr_floor
from ...raster_models.drjit import numpy_view
from ...scenes import backend
from ...scenes.backend.raycast import trace_film_dr
from ..errors import InputError
from ..phases import maybe_phase
from .coverage import centre_shapes, exact_channels, front_hits
from .motion import motion_channels
from .soft import light_samples, soft_samples

__all__ = [
    "ALL_CHANNELS",
    "EXACT_BUDGET_S",
    "CHANNEL_GROUPS",
    "MAX_SEED",
    "ReferenceSettingsError",
    "ReferenceSettings",
    "binary_stderr",
    "channel_names",
    "estimate_memory",
    "feature_mask",
    "grid_shape",
    "render_reference",
    "sample_jitter",
    "samples_per_chunk",
    "set_exact_budget",
    "sobol_sample",
]

#: Channel groups that can be asked for with ``--channels``; each expands to EXR channels.
CHANNEL_GROUPS = {
    "visibility": ["visibility", "visibility_stderr"],
    "coverage": ["coverage", "coverage_stderr", "front_coverage", "front_coverage_stderr"],
    # analytic, noise-free coverage of triangle scenes (scenes.geometry.exact_coverage)
    "coverage_exact": ["coverage_exact", "front_coverage_exact", "coverage_exact_valid"],
    "color": [
        "color.R",
        "color.G",
        "color.B",
        "color_stderr.R",
        "color_stderr.G",
        "color_stderr.B",
    ],
    "edge": ["edge"],
    "id": ["id"],
    "depth": ["depth"],
    "position": ["position.X", "position.Y", "position.Z"],
    "normal": ["normal.X", "normal.Y", "normal.Z"],
    "albedo": ["albedo.R", "albedo.G", "albedo.B"],
    "tangent32": ["visibility_tangent32"],
    # temporal truth (oracle.reference.motion): pixels to the previous frame, and 1 where the
    # point was hidden from the previous frame's camera or outside its image
    "motion": ["motion.X", "motion.Y", "disocclusion"],
    # area-light truth (oracle.reference.soft): the unoccluded fraction of the irradiance and
    # of the light's area; a punctual light's are its visibility
    "soft": [
        "soft_visibility",
        "soft_visibility_stderr",
        "light_fraction",
        "light_fraction_stderr",
    ],
}
#: Groups rendered only when asked for (``--channels ...,tangent32``), never by default.
OPTIONAL_GROUPS = ("tangent32", "motion", "soft")
ALL_CHANNELS = tuple(g for g in CHANNEL_GROUPS if g not in OPTIONAL_GROUPS)
_CENTRE_GROUPS = {"id", "depth", "position", "normal", "albedo"}
#: Samples per Dr.Jit launch: bounds a launch's working set whatever the resolution and spp
#: (about 1 GiB with colour, :func:`estimate_memory`). Fewer, larger launches cost less
#: tracing and launch time: the 1080p 32-spp colour reference took 1.20x the CPU time of
#: Mitsuba's ``direct`` integrator at 2^22 samples a launch, 1.09x at 2^24.
SAMPLES_PER_CHUNK = 1 << 24
#: Launches are this many times larger on a CUDA variant (2^26 samples, about 4 GiB of device
#: memory with colour): each launch records its kernel in Python again (27 ms a launch on
#: this 2-core CPU), which the H200 run of 2026-11-27 showed dominates there (the colour
#: reference took 3.6x the time of Mitsuba's ``direct``, which records once per image).
CUDA_CHUNK_FACTOR = 4


def samples_per_chunk() -> int:
    """Samples per sampling launch of the active backend (:data:`SAMPLES_PER_CHUNK`, times
    :data:`CUDA_CHUNK_FACTOR` on CUDA); results do not depend on it."""
    cuda = "cuda" in backend.active().variant
    return SAMPLES_PER_CHUNK * (CUDA_CHUNK_FACTOR if cuda else 1)


# Memory model of estimate_memory (peak RSS above the loaded scene, plate, LLVM backend,
# measured 2026-11-24; see its docstring).
_BASE_BYTES = 64 << 20
_BYTES_PER_SAMPLE = 32
_BYTES_PER_COLOR_SAMPLE = 64
_BYTES_PER_PIXEL = 64 + 56
_BYTES_PER_COLOR_PIXEL = 48


#: Default ``--exact-budget``: seconds of estimated ``coverage_exact`` work per view.
EXACT_BUDGET_S = 60.0
_EXACT_BUDGET = [EXACT_BUDGET_S]


def set_exact_budget(seconds: float | None) -> None:
    """Set the process's default exact-coverage budget (``--exact-budget``; None: the
    documented default :data:`EXACT_BUDGET_S`). Settings made later take it as theirs, so
    it enters their cache keys."""
    _EXACT_BUDGET[0] = EXACT_BUDGET_S if seconds is None else float(seconds)


class ReferenceSettingsError(InputError):
    """Invalid reference settings (bad spp, unknown channel, too much memory)."""


#: Largest seed: the sampling streams hash a 32-bit seed, so larger seeds would wrap onto
#: smaller ones (2^32 would give the bytes of seed 0 under another cache key).
MAX_SEED = 2**32 - 1


@dataclass(frozen=True)
class ReferenceSettings:
    """How a reference is rendered; every field enters the cache key."""

    spp: int = 64
    seed: int = 0
    channels: tuple[str, ...] = ALL_CHANNELS
    adaptive: bool = False
    adaptive_spp: int = 16
    target_stderr: float = 0.01
    max_spp: int = 4096
    #: Seconds of estimated ``coverage_exact`` work allowed per view (None: the process
    #: default, :data:`EXACT_BUDGET_S` unless ``--exact-budget`` set it); over it the group
    #: is skipped for that view (scenes.geometry.exact_coverage.estimate_cost).
    exact_budget: float | None = None

    def validate(self) -> ReferenceSettings:
        if int(self.spp) < 1:
            raise ReferenceSettingsError(f"spp must be >= 1, got {self.spp}")
        if not 0 <= int(self.seed) <= MAX_SEED:
            raise ReferenceSettingsError(
                f"seed must be in [0, {MAX_SEED}] (sampling streams are keyed by a 32-bit "
                f"seed), got {self.seed}"
            )
        unknown = [c for c in self.channels if c not in CHANNEL_GROUPS]
        if unknown or not self.channels:
            raise ReferenceSettingsError(
                f"unknown channel(s) {', '.join(unknown) or '(none given)'}; choose from "
                f"{', '.join(CHANNEL_GROUPS)}"
            )
        if self.adaptive:
            if int(self.adaptive_spp) < 2:
                raise ReferenceSettingsError(f"adaptive_spp must be >= 2, got {self.adaptive_spp}")
            if not self.target_stderr > 0:
                raise ReferenceSettingsError(f"target_stderr must be > 0, got {self.target_stderr}")
            if int(self.max_spp) < int(self.adaptive_spp):
                raise ReferenceSettingsError("max_spp must be >= adaptive_spp")
        ordered = tuple(c for c in CHANNEL_GROUPS if c in set(self.channels))
        budget = _EXACT_BUDGET[0] if self.exact_budget is None else float(self.exact_budget)
        if not budget >= 0:
            raise ReferenceSettingsError(f"exact budget must be >= 0 seconds, got {budget}")
        return ReferenceSettings(
            int(self.spp),
            int(self.seed),
            ordered,
            bool(self.adaptive),
            int(self.adaptive_spp),
            float(self.target_stderr),
            int(self.max_spp),
            budget,
        )

    def key_record(self) -> dict:
        rec = asdict(self)
        rec["channels"] = list(self.channels)
        if not self.adaptive:
            for k in ("adaptive_spp", "target_stderr", "max_spp"):
                rec.pop(k)
        # the default budget leaves the key (and every cached reference) as it was
        budget = rec.pop("exact_budget")
        if "coverage_exact" in self.channels and budget not in (None, EXACT_BUDGET_S):
            rec["exact_budget"] = budget
        return rec


def channel_names(groups) -> list[str]:
    return [name for g in groups for name in CHANNEL_GROUPS[g]]


def grid_shape(spp: int) -> tuple[int, int]:
    """Stratification grid ``(m, n)``, ``m * n = spp``, ``m >= n``, as square as possible."""
    n = int(math.isqrt(spp))
    while spp % n:
        n -= 1
    return spp // n, n


def estimate_memory(
    width: int, height: int, *, spp: int = 64, channels=ALL_CHANNELS, max_spp: int | None = None
) -> int:
    """Peak bytes a reference of this size, spp and channel groups needs (an upper bound).

    ``base + launch * per_sample + pixels * per_pixel`` with

    - ``launch = min(pixels * spp, SAMPLES_PER_CHUNK)``: the samples of the largest Dr.Jit
      launch (``max_spp`` instead of ``spp`` for adaptive sampling; a launch of the whole
      chunk for ``tangent32``, and ``pixels`` for the pixel-centre groups alone),
    - ``per_sample`` 32 B, 64 B when ``color`` is rendered (its shading doubles the live
      arrays),
    - ``per_pixel`` 120 B of float64/int64 running sums, 48 B more for colour, and 8 B per
      output channel (the float32 image and its copy),
    - ``base`` 64 MiB (kernel compilation, the allocator's slack).

    Fitted with margin to the peak RSS measured above the loaded scene (``plate``, LLVM,
    score's channel sets): visibility set at 80x45/16 spp 3 MB (estimate 70 MB),
    160x90/64 21 MB (99), 320x180/64 99 MB (197), 320x180/256 85 MB (213), 640x360/64
    107 MB (247); colour set at 160x90/64 66 MB (129), 320x180/64 206 MB (316), 320x180/256
    208 MB (349), 640x360/64 247 MB (389); at 1280x720/64 visibility 208 MB (386), colour
    395 MB (549), every default group 458 MB (653). The former fixed 1.41 GiB refused a
    320x180 score on a machine with 1.4 GiB free.
    """
    groups = set(channels)
    pixels = int(width) * int(height)
    color = "color" in groups
    sampled = groups & {"visibility", "coverage", "color", "edge", "soft"}
    spp_max = int(max_spp if max_spp is not None else spp)
    launch = min(pixels * spp_max, SAMPLES_PER_CHUNK) if sampled else min(pixels, SAMPLES_PER_CHUNK)
    if "tangent32" in groups:
        launch = max(launch, min(pixels * 32, SAMPLES_PER_CHUNK))
    per_sample = _BYTES_PER_COLOR_SAMPLE if color else _BYTES_PER_SAMPLE
    outputs = len(channel_names([g for g in CHANNEL_GROUPS if g in groups]))
    per_pixel = _BYTES_PER_PIXEL + (_BYTES_PER_COLOR_PIXEL if color else 0) + 8 * outputs
    return _BASE_BYTES + launch * per_sample + pixels * per_pixel


def _amount(n: int) -> str:
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def available_memory() -> int:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


@dataclass
class _Accum:
    """Per-pixel running sums (float64) over all passes."""

    npix: int
    color: bool
    #: which per-sample quantities are summed: "vis", "cov", "shape", "front" (with
    #: ``centre``; colour: ``color``), "soft" (soft visibility and light fraction with their
    #: squares); the others are empty (a colour-only reference skips their outputs,
    #: reductions and buffers)
    track: frozenset = frozenset({"vis", "cov", "shape"})
    n: np.ndarray = field(init=False)
    vis: np.ndarray = field(init=False)
    cov: np.ndarray = field(init=False)
    #: shape seen through each pixel centre (``front_coverage``; None: not asked for)
    centre: np.ndarray | None = None
    front: np.ndarray = field(init=False)
    rgb: np.ndarray | None = field(init=False)
    rgb2: np.ndarray | None = field(init=False)
    smin: np.ndarray = field(init=False)
    smax: np.ndarray = field(init=False)
    soft: np.ndarray = field(init=False)
    soft2: np.ndarray = field(init=False)
    frac: np.ndarray = field(init=False)
    frac2: np.ndarray = field(init=False)
    #: :class:`oracle.phases.Phases` of a profiled render (None: no profiling, no syncs)
    phases: object = None

    def __post_init__(self):
        def size(name):
            return self.npix if name in self.track else 0

        self.n = np.zeros(self.npix)
        self.vis = np.zeros(size("vis"))
        self.cov = np.zeros(size("cov"))
        self.front = np.zeros(size("front"))
        # planar (3, npix), the layout Dr.Jit hands over: the sums add rows, not a transpose
        self.rgb = np.zeros((3, self.npix)) if self.color else None
        self.rgb2 = np.zeros((3, self.npix)) if self.color else None
        self.smin = np.full(size("shape"), np.iinfo(np.int32).max, dtype=np.int64)
        self.smax = np.full(size("shape"), np.iinfo(np.int32).min, dtype=np.int64)
        for name in ("soft", "soft2", "frac", "frac2"):
            setattr(self, name, np.zeros(size("soft")))

    def stderr(self, s, s2, n):
        """``sqrt(s^2 / N)`` from the sums ``s``, ``s2`` of ``n`` samples (0 where n <= 1);
        computed in place (a 1080p colour reference spent 2 % of its time here)."""
        n = np.broadcast_to(n, s.shape)
        with np.errstate(invalid="ignore", divide="ignore"):
            var = s * s
            var /= n
            np.subtract(s2, var, out=var)
            var /= n - 1
            var /= n
            np.maximum(var, 0.0, out=var)
            np.sqrt(var, out=var)
        var[n <= 1] = 0.0
        return var

    def vis_stderr(self):
        return np.maximum(self.stderr(self.vis, self.vis, self.n), binomial_stderr_floor(self.n))

    def cov_stderr(self):
        return np.maximum(self.stderr(self.cov, self.cov, self.n), binomial_stderr_floor(self.n))

    def front_stderr(self):
        return np.maximum(
            self.stderr(self.front, self.front, self.n), binomial_stderr_floor(self.n)
        )

    def soft_stderr(self, s, s2):
        """Standard error of a soft channel's mean (sample values in [0, 1]): the sample
        one; where every sample is 0 or every one is 1 (no variance to estimate), the
        binomial floor, as visibility's (a feature all samples missed is not excluded)."""
        se = self.stderr(s, s2, self.n)
        alike = (s == 0.0) | (s == self.n)
        return np.where(alike, np.maximum(se, binomial_stderr_floor(self.n)), se)

    def rgb_stderr(self):
        """``(3, npix)``."""
        return self.stderr(self.rgb, self.rgb2, self.n)

    def sample_variance(self):
        """Largest per-pixel sample variance over the tracked quantities."""
        n = np.maximum(self.n, 2)
        parts = [(self.vis - self.vis**2 / n) / (n - 1), (self.cov - self.cov**2 / n) / (n - 1)]
        if self.color:
            parts.append(np.max((self.rgb2 - self.rgb**2 / n) / (n - 1), 0))
        if "soft" in self.track:
            parts.append((self.soft2 - self.soft**2 / n) / (n - 1))
            parts.append((self.frac2 - self.frac**2 / n) / (n - 1))
        return np.maximum(np.max(parts, axis=0), 0.0)


def _mix32(x: int) -> int:
    """A 32-bit integer hash (lowbias32) of a host integer: spreads the seed's bits."""
    x &= 0xFFFFFFFF
    x ^= x >> 16
    x = (x * 0x7FEB352D) & 0xFFFFFFFF
    x ^= x >> 15
    x = (x * 0x846CA68B) & 0xFFFFFFFF
    return x ^ (x >> 16)


def jitter_key(pix, seed: int):
    """Per-pixel key of :func:`sample_jitter`: the pixel index times the golden-ratio
    constant (a bijection of 32-bit integers) XOR a hash of the seed; the 6-round TEA of
    :func:`jitter_from_key` mixes it (a TEA hash of seed and pixel here as well cost 3 % of
    the colour reference's CPU time and changed none of the independence statistics)."""
    mi = backend.mitsuba()
    return (mi.UInt32(pix) * 0x9E3779B9) ^ _mix32(int(seed))


#: TEA rounds of the per-sample hash: 4 leave consecutive samples of a pixel correlated
#: (joint 32x32 chi-square of samples s and s + 1: z = 303), 6 do not (|z| < 2 for every
#: pixel and sample offset the statistics tests try).
JITTER_ROUNDS = 6


def jitter_from_key(key, sample):
    """Jitter of sample ``sample`` of the pixel whose :func:`jitter_key` is ``key``: the two
    32-bit halves of a 6-round TEA hash of key and sample, 24 bits each. 32-bit integer
    operations only (the PCG32 stream seeded from a 64-bit TEA hash that it replaces cost
    four 64-bit multiplies a sample, 8 % of the colour reference's CPU time)."""
    mi = backend.mitsuba()

    a, b = mi.sample_tea_32(key, mi.UInt32(sample), JITTER_ROUNDS)
    scale = 1.0 / (1 << 24)
    return mi.Float(a >> 8) * scale, mi.Float(b >> 8) * scale


def sample_jitter(pix, sample, seed: int):
    """Jitter ``(u, v)`` in ``[0, 1)^2`` of sample ``sample`` of pixel ``pix`` (Dr.Jit UInt32).

    Each (pixel, sample, seed) gets its own hash (:func:`jitter_key`, then
    :func:`jitter_from_key`): seeding PCG32 streams with consecutive stream numbers (an
    earlier scheme) correlated the jitter of neighbouring samples (a joint 32x32 chi-square
    of samples s and s + 2 deviated by thousands of sigma), hashing removes it. The result
    depends only on the three integers, never on chunking.
    """
    return jitter_from_key(jitter_key(pix, seed), sample)


def _reverse_bits(x):
    """Bit reversal of Dr.Jit UInt32 ``x`` (five swap steps)."""
    x = ((x >> 1) & 0x55555555) | ((x & 0x55555555) << 1)
    x = ((x >> 2) & 0x33333333) | ((x & 0x33333333) << 2)
    x = ((x >> 4) & 0x0F0F0F0F) | ((x & 0x0F0F0F0F) << 4)
    x = ((x >> 8) & 0x00FF00FF) | ((x & 0x00FF00FF) << 8)
    return (x >> 16) | (x << 16)


def sobol_sample(pix, sample, seed: int, bits: int = 32):
    """Point ``sample`` of pixel ``pix``'s 2-D Sobol sequence, digitally shifted (Dr.Jit).

    The first two Sobol dimensions (van der Corput and the Pascal-matrix dimension) form a
    (0, 2)-sequence: every aligned block of ``2^k`` points, and every prefix of ``2^k``
    points, has one point in each elementary interval of area ``2^-k``. Adaptive passes
    double a pixel's samples, so each pass is a stratified net and so is their union, as
    good as one grid of the final count (separate jittered grids per pass are not: 16 + 16
    + 32 + ... + 512 samples estimate an edge pixel worse than one 1024 grid). A per-pixel
    random XOR shift (TEA hash of pixel and seed; the shift keeps the net property) makes
    every point uniform over the pixel, so any count is unbiased, and depends only on the
    three integers, never on chunking. ``bits``: how many low bits of ``sample`` can be set
    (the higher ones contribute nothing).
    """
    mi = backend.mitsuba()
    import drjit as dr

    shift_u, shift_v = mi.sample_tea_32(mi.UInt32(int(seed) & 0xFFFFFFFF), mi.UInt32(pix), 8)
    sample = mi.UInt32(sample)
    u_bits = _reverse_bits(sample)
    v_bits = dr.zeros(mi.UInt32, dr.width(sample))
    col = 1 << 31
    for bit in range(min(int(bits), 32)):  # Sobol dimension 2: column c_{k+1} = c_k ^ (c_k >> 1)
        v_bits ^= dr.select(((sample >> bit) & 1) == 1, mi.UInt32(col), mi.UInt32(0))
        col ^= col >> 1
    scale = 1.0 / (1 << 24)
    u = mi.Float((u_bits ^ shift_u) >> 8) * scale
    v = mi.Float((v_bits ^ shift_v) >> 8) * scale
    return u, v


def _pass(
    loaded,
    acc: _Accum,
    pixels: np.ndarray,
    spp: int,
    offset: int,
    seed: int,
    progress,
    progressive: bool = False,
    launch: int | None = None,
) -> tuple[int, int]:
    """Trace ``spp`` stratified samples in each of ``pixels``; returns (primary, shadow) rays.

    With ``progressive`` the samples are points ``offset .. offset + spp - 1`` of each
    pixel's scrambled Sobol sequence (:func:`sobol_sample`), else a jittered ``m x n`` grid.

    A launch holds at most ``launch`` (default :data:`SAMPLES_PER_CHUNK`) samples: several
    pixels' samples, or, when one pixel has more, a block of one pixel's samples at a time,
    so memory is bounded for any ``spp``. Under an area light (colour or soft channels) each
    camera sample casts :func:`oracle.reference.soft.light_samples` shadow rays and a launch
    holds that many times fewer camera samples.
    """
    mi = backend.mitsuba()
    import drjit as dr

    width = loaded.width
    m, n = grid_shape(spp)
    launch = launch or samples_per_chunk()
    if _area_sampled(loaded, acc):
        launch = max(1, launch // light_samples(loaded.light))
    block = min(spp, launch)
    per_chunk = max(1, launch // block)
    bits = max(1, int(offset + spp - 1).bit_length())
    primary = shadow = 0
    for start in range(0, len(pixels), per_chunk):
        chunk = pixels[start : start + per_chunk]
        for s0 in range(0, spp, block):
            bsz = min(block, spp - s0)
            count = len(chunk) * bsz
            idx = dr.arange(mi.UInt32, count)
            local = idx // bsz
            s = idx - local * bsz + s0
            if int(chunk[-1]) - int(chunk[0]) == len(chunk) - 1:
                # a run of pixels: no upload of their indices; the first is opaque, so every
                # chunk reuses one compiled kernel
                pix = local + dr.opaque(mi.UInt32, int(chunk[0]))
            else:
                pix = dr.gather(mi.UInt32, mi.UInt32(chunk), local)
            if progressive:
                u, v = sobol_sample(pix, s + offset, seed, bits=bits)
            else:
                u, v = sample_jitter(pix, s + offset, seed)
                u = (mi.Float(s % m) + u) * (1.0 / m)
                v = (mi.Float(s // m) + v) * (1.0 / n)
            x = mi.Float(pix % width) + u
            y = mi.Float(pix // width) + v
            primary += count
            shadow += _accumulate(loaded, acc, chunk, x, y, bsz, keys=(pix, s + offset, seed))
            if progress is not None:
                progress.update(count)
    return primary, shadow


def _area_sampled(loaded, acc: _Accum) -> bool:
    """Whether the samples integrate over an area light (its colour or soft channels)."""
    return loaded.light.is_area and (acc.color or "soft" in acc.track)


def _accumulate(loaded, acc: _Accum, chunk: np.ndarray, x, y, block: int, keys=None) -> int:
    """Trace the samples ``(x, y)`` (``block`` consecutive ones per pixel of ``chunk``) and
    add their sums to ``acc``; returns the shadow rays cast. ``keys``: the samples' ``(pixel,
    sample index, seed)``, which seed an area light's samples (:mod:`.soft`)."""
    with maybe_phase(acc.phases, "record"):  # Python: recording the kernel's operations
        if _area_sampled(loaded, acc):
            res = _area_trace(loaded, acc, x, y, keys)
        else:
            res = trace_film_dr(loaded, x, y, color=acc.color, albedo=False)
        sums = _sample_sums(acc, res, chunk, block)
    return _reduce_and_add(acc, res, sums, chunk, block)


def _area_trace(loaded, acc: _Accum, x, y, keys) -> dict:
    """:func:`trace_film_dr` with the area light's samples (:func:`.soft.soft_samples`):
    its soft values and area-lit colour replace the punctual proxy's colour."""
    import drjit as dr

    res = trace_film_dr(loaded, x, y, color=False, albedo=acc.color, keep_si=True)
    # the light samples gather the primary hits: trace them in a kernel of their own
    dr.eval(res["si"], res["valid"], res["normal"], res["to_eye"], res.get("albedo"))
    pix, sample, seed = keys
    res.update(soft_samples(loaded, res, pix, sample, jitter_key(pix, seed), color=acc.color))
    return res


def _sample_sums(acc: _Accum, res: dict, chunk, block: int) -> dict:
    """The per-sample values to sum per pixel: name -> (Dr.Jit array, reduction)."""
    import drjit as dr

    sums = {}
    if "vis" in acc.track:
        sums["vis"] = (dr.select(res["lit"], 1.0, 0.0), dr.ReduceOp.Add)
    if "cov" in acc.track:
        sums["cov"] = (dr.select(res["valid"], 1.0, 0.0), dr.ReduceOp.Add)
    if "shape" in acc.track:
        sums["smin"] = (res["shape"], dr.ReduceOp.Min)
        sums["smax"] = (res["shape"], dr.ReduceOp.Max)
    if acc.color:
        sums["rgb"] = (res["color"], dr.ReduceOp.Add)
        sums["rgb2"] = (res["color"] * res["color"], dr.ReduceOp.Add)
    if "front" in acc.track:
        sums["front"] = (front_hits(res["shape"], acc.centre[chunk], block), dr.ReduceOp.Add)
    if "soft" in acc.track:
        # a punctual light's soft values are its visibility
        soft = res.get("soft", dr.select(res["lit"], 1.0, 0.0))
        frac = res.get("fraction", soft)
        sums["soft"], sums["soft2"] = (soft, dr.ReduceOp.Add), (soft * soft, dr.ReduceOp.Add)
        sums["frac"], sums["frac2"] = (frac, dr.ReduceOp.Add), (frac * frac, dr.ReduceOp.Add)
    if "light_rays" in res:
        sums["light_rays"] = (res["light_rays"], dr.ReduceOp.Add)
    return sums


def _reduce_and_add(acc: _Accum, res: dict, sums: dict, chunk, block: int) -> int:
    """Evaluate the samples' values, reduce them per pixel and add them to ``acc``."""
    import drjit as dr

    # one kernel traces every sample; reductions then read the evaluated arrays. A profiled
    # render (acc.phases) waits at the end of each phase so its launches count there.
    ph = acc.phases
    with maybe_phase(ph, "trace+shade", sync=True):
        dr.eval(*[v for v, _ in sums.values()], res["shadow_tested"])
    with maybe_phase(ph, "reductions", sync=True):
        shadow_count = dr.count(res["shadow_tested"])
        outs = {k: block_sum(dr, op, v, block) for k, (v, op) in sums.items()}
        dr.eval(*outs.values(), shadow_count)
    with maybe_phase(ph, "transfer"):
        # numpy_view: a colour vector component by component (Dr.Jit's own conversion
        # compiles a packing kernel for every array length: the last, shorter chunk)
        host = {
            k: np.asarray(numpy_view(v), dtype=None if k in ("smin", "smax") else np.float64)
            for k, v in outs.items()
        }
        shadow_tested = int(shadow_count[0])
        if "light_rays" in host:  # an area light's shadow rays, not its proxy's
            shadow_tested += int(round(float(host.pop("light_rays").sum())))
    with maybe_phase(ph, "accumulate"):
        if len(chunk) and int(chunk[-1]) - int(chunk[0]) == len(chunk) - 1:
            chunk = slice(int(chunk[0]), int(chunk[-1]) + 1)  # a run of pixels: no fancy indexing
        acc.n[chunk] += block
        for k in ("vis", "cov", "front", "soft", "soft2", "frac", "frac2"):
            if k in host:
                getattr(acc, k)[chunk] += host[k]
        for k in ("rgb", "rgb2"):
            if k in host:
                getattr(acc, k)[:, chunk] += host[k]  # (3, pixels) onto planar sums
        if "smin" in host:
            acc.smin[chunk] = np.minimum(acc.smin[chunk], host["smin"])
            acc.smax[chunk] = np.maximum(acc.smax[chunk], host["smax"])
    return shadow_tested


def block_sum(dr, op, values, block: int):
    """``dr.block_reduce`` of per-sample ``values``; float sums in float64. A float32 block
    sum rounds in an order set by the block size and the backend (CUDA reduces in a tree):
    a pixel's samples split over launches gave other bytes on an H200, and the standard
    error of a constant pixel, ``sqrt(s2 - s^2 / n)``, came out as that rounding (4e-6 or
    1.4e-6 instead of 0). In float64 the sums of float32 samples are exact up to 2^29 of
    them and rounded at 2^-53 beyond, whatever the order."""
    if op == dr.ReduceOp.Add and dr.type_v(values) == dr.VarType.Float32:
        return dr.block_reduce(op, dr.float64_array_t(type(values))(values), block, mode="symbolic")
    return dr.block_reduce(op, values, block, mode="evaluated")


def _centre_channels(loaded, groups: set[str], progress) -> dict[str, np.ndarray]:
    """G-buffer channels from one ray through each pixel centre."""
    mi = backend.mitsuba()
    import drjit as dr

    h, w = loaded.height, loaded.width
    npix = w * h
    out = {
        name: np.zeros(npix, dtype=np.float32)
        for name in channel_names(
            [g for g in CHANNEL_GROUPS if g in groups and g in _CENTRE_GROUPS]
        )
    }
    for start in range(0, npix, SAMPLES_PER_CHUNK):
        idx = dr.arange(mi.UInt32, start, min(npix, start + SAMPLES_PER_CHUNK))
        x = mi.Float(idx % w) + 0.5
        y = mi.Float(idx // w) + 0.5
        res = trace_film_dr(loaded, x, y, color=False)
        sl = slice(start, start + dr.width(idx))
        if "id" in groups:
            out["id"][sl] = np.array(res["shape"])
        if "depth" in groups:
            out["depth"][sl] = np.array(res["depth"])
        for g, key, names in (
            ("position", "position", "XYZ"),
            ("normal", "normal", "XYZ"),
            ("albedo", "albedo", "RGB"),
        ):
            if g in groups:
                arr = np.array(res[key])
                valid = np.array(res["valid"])
                for i, c in enumerate(names):
                    out[f"{g}.{c}"][sl] = np.where(valid, arr[i], 0.0)
        if progress is not None:
            progress.update(dr.width(idx))
    return {k: v.reshape(h, w) for k, v in out.items()}


def _tangent32_channel(loaded) -> np.ndarray:
    """Lit fraction of the 32 FTIZB points on the tangent plane at each pixel centre.

    The points ``P + a dP/dx + b dP/dy`` (:data:`scenes.geometry.tangent32.TANGENT_POINTS_32`, the
    table the ``izb`` model uses) of the surface seen through the pixel centre, each with the
    oracle's exact shadow ray (offset along the centre's normal as for a surface point of the
    same shape); N.L and the spot cone are evaluated per point with the centre's normal. Sky
    pixels are 1. Exact for those points: no sampling noise.
    """
    mi = backend.mitsuba()
    import drjit as dr

    from ...scenes.backend.raycast import camera_rays_dr, occluded_from_dr
    from ...scenes.geometry.tangent32 import tangent_derivatives_dr, tangent_offsets
    from ...scenes.shading.phong import facing, receiver_mask

    w, h = loaded.width, loaded.height
    npix = w * h
    a_np, b_np = tangent_offsets()
    k_n = len(a_np)
    out = np.zeros(npix, dtype=np.float64)
    per_chunk = max(1, SAMPLES_PER_CHUNK // k_n)
    light = loaded.light
    for start in range(0, npix, per_chunk):
        stop = min(npix, start + per_chunk)
        idx = dr.arange(mi.UInt32, (stop - start) * k_n)
        pix = idx // k_n + start
        k = idx % k_n
        x = mi.Float(pix % w) + 0.5
        y = mi.Float(pix // w) + 0.5
        ray = camera_rays_dr(loaded.camera, x, y)
        si = loaded.mi_scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True)
        valid = si.is_valid()
        n = facing(si.sh_frame.n, -ray.d)
        dpdx, dpdy = tangent_derivatives_dr(loaded.camera, x, y, si.p, n)
        a = dr.gather(mi.Float, mi.Float(a_np), k)
        b = dr.gather(mi.Float, mi.Float(b_np), k)
        q = si.p + dpdx * a + dpdy * b
        wl, _ = light.to_light(q)
        candidate = receiver_mask(valid=valid, cos_l=dr.dot(n, wl), to_light=wl, light=light)
        blocked = occluded_from_dr(loaded.mi_scene, light, q, si.n, wl, si.shape, candidate)
        lit = dr.select(valid, dr.select(candidate & ~blocked, 1.0, 0.0), 1.0)
        total = dr.block_reduce(dr.ReduceOp.Add, lit, k_n, mode="evaluated")
        dr.eval(total)
        out[start:stop] = np.array(total, dtype=np.float64) / k_n
    return out.reshape(h, w).astype(np.float32)


def _dilate(mask: np.ndarray) -> np.ndarray:
    """3x3 dilation of a boolean ``(H, W)`` image (vectorised: nine shifted ORs)."""
    out = mask.copy()
    out[1:, :] |= mask[:-1, :]
    out[:-1, :] |= mask[1:, :]
    rows = out.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


def _differs_from_neighbour(values: np.ndarray) -> np.ndarray:
    """True where a pixel's value differs from one of its 8 neighbours' (``(H, W, ...)``)."""
    out = np.zeros(values.shape[:2], dtype=bool)
    h, w = out.shape
    for dy, dx in ((0, 1), (1, -1), (1, 0), (1, 1)):
        ys, yd = slice(0, h - dy), slice(dy, h)
        xs = slice(max(0, -dx), w - max(0, dx))
        xd = slice(max(0, dx), w + min(0, dx))
        diff = values[ys, xs] != values[yd, xd]
        if diff.ndim == 3:
            diff = diff.any(axis=2)
        out[ys, xs] |= diff
        out[yd, xd] |= diff
    return out


def feature_mask(acc: _Accum, width: int, height: int) -> np.ndarray:
    """Pixels near a feature: the 3x3 dilation of the pixels that show an edge.

    A pixel shows an edge when its own samples disagree (hit shape id, visibility or
    coverage differ between them), or when what its samples agree on differs from a
    neighbour's (another shape id, visibility or coverage: the two pixels lie on either side
    of an edge, or a thin feature that one of them caught). A pixel whose samples all missed a
    thin feature that crosses a neighbour is thereby flagged by that neighbour, which its own
    standard error (zero sample variance) cannot do.
    """
    shape = (height, width)
    own = (acc.smin != acc.smax) | ((acc.vis > 0) & (acc.vis < acc.n))
    own |= (acc.cov > 0) & (acc.cov < acc.n)
    # what the pixel's samples agree on: shape range and whether any sample was lit/covered
    parts = [acc.smin, acc.smax, acc.vis > 0, acc.cov > 0]
    if "soft" in acc.track:  # a penumbra: soft values other than all 0 or all 1
        own |= (acc.soft > 0) & (acc.soft < acc.n)
        parts += [acc.soft > 0, acc.soft < acc.n]
    state = np.stack(parts, axis=1).reshape(*shape, len(parts))
    edge = own.reshape(shape) | _differs_from_neighbour(state)
    return _dilate(edge).ravel()


def binary_stderr(hits: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Standard error of a binary pixel quantity from ``hits`` of ``n`` samples (Jeffreys).

    ``sqrt(p (1 - p) / n)`` with ``p = (min(hits, n - hits) + 1/2) / (n + 1)``, the
    posterior mean of the rarer outcome: the binomial floor when all samples agree, and
    never below it when a feature was seen only a few times (the plain sample variance
    of 1 hit in 128 samples claims 0.008 where a feature covering 6 % of the pixel is still
    likely).
    """
    p = (np.minimum(hits, n - hits) + 0.5) / (n + 1.0)
    return np.sqrt(p * (1.0 - p) / n)


def _refine_mask(acc: _Accum, settings: ReferenceSettings, width: int, height: int):
    """Pixels of the next adaptive pass.

    A pixel near a feature (:func:`feature_mask`: an edge, id change or visibility change in
    it or a neighbour) refines while the binary standard error (:func:`binary_stderr`) of
    its visibility or coverage exceeds the target; a pixel far from every feature stops
    after the first pass, however few samples agree in it (its neighbours' agreeing samples
    are the evidence). Stopped pixels rejoin when a neighbour later shows a feature, so
    refinement follows thin features from the pixels that caught them. With colour, a pixel
    also refines while the sample standard error of its colour exceeds the target.
    """
    se = np.maximum(binary_stderr(acc.vis, acc.n), binary_stderr(acc.cov, acc.n))
    if "front" in acc.track:
        se = np.maximum(se, binary_stderr(acc.front, acc.n))
    if "soft" in acc.track:  # penumbra values are not binary: their sample standard error
        se = np.maximum(se, _soft_se(acc))
    want = feature_mask(acc, width, height) & (se > settings.target_stderr)
    if acc.color:
        want |= acc.rgb_stderr().max(axis=0) > settings.target_stderr
    return want & (acc.n < settings.max_spp)


def _soft_se(acc: _Accum) -> np.ndarray:
    """Larger standard error of the two soft channels (:meth:`_Accum.soft_stderr`)."""
    return np.maximum(acc.soft_stderr(acc.soft, acc.soft2), acc.soft_stderr(acc.frac, acc.frac2))


def _refine(loaded, acc: _Accum, settings: ReferenceSettings, passes: list, progress, launch):
    """Adaptive passes after the first: each doubles the samples of the pixels of
    :func:`_refine_mask` (grouped by their current count, which differs once stopped pixels
    rejoin), until none is left; returns (primary, shadow) rays."""
    primary = shadow = 0
    while True:
        active = np.nonzero(_refine_mask(acc, settings, loaded.width, loaded.height))[0]
        if len(active) == 0:
            return primary, shadow
        counts = acc.n[active]
        for n_k in np.unique(counts):
            group = active[counts == n_k].astype(np.uint32)
            spp_k = int(min(n_k, settings.max_spp - n_k))
            if progress is not None:
                progress.total += len(group) * spp_k
            p, s = _pass(
                loaded,
                acc,
                group,
                spp_k,
                int(n_k),
                settings.seed,
                progress,
                progressive=True,
                launch=launch,
            )
            primary, shadow = primary + p, shadow + s
            passes.append({"pixels": int(len(group)), "spp": spp_k})


def render_reference(
    loaded,
    settings: ReferenceSettings,
    *,
    quiet: bool = False,
    samples_per_launch: int | None = None,
    phases=None,
):
    """Render the reference channels of ``loaded`` (its current camera frame), at most
    ``samples_per_launch`` samples a Dr.Jit launch (default :func:`samples_per_chunk`; the
    result does not depend on it, which ``doctor --check`` verifies).

    ``phases``: an :class:`oracle.phases.Phases` to profile the render into (``trace+shade``,
    ``reductions``, ``transfer``, ``accumulate``, ``centre``, ``finish``); each phase then
    waits for its Dr.Jit work, which the normal path (None) never does.

    Returns
    -------
    channels : dict of ``(H, W)`` float32 arrays named as in the README's table.
    stats : dict with rays cast, wall seconds, M rays/s, mean/max standard errors and, for
        adaptive sampling, the rays uniform sampling would need for the same maximum error.
    """
    settings = settings.validate()
    w, h = loaded.width, loaded.height
    need = estimate_memory(
        w,
        h,
        spp=settings.spp,
        channels=settings.channels,
        max_spp=settings.max_spp if settings.adaptive else None,
    )
    have = available_memory()
    if need > have:
        raise ReferenceSettingsError(
            f"a {w}x{h} reference at {settings.spp} spp needs about {_amount(need)}; "
            f"only {_amount(have)} is available"
        )
    groups = set(settings.channels)
    sampled = groups & {"visibility", "coverage", "color", "edge", "soft"}
    npix = w * h
    color = "color" in groups
    track = {"vis", "cov", "shape"}
    if not settings.adaptive:
        track = {
            k
            for k, gs in (
                ("vis", ("visibility", "edge")),
                ("cov", ("coverage",)),
                ("shape", ("edge",)),
            )
            if groups & set(gs)
        }
    centre = centre_shapes(loaded) if "coverage" in groups else None
    track |= {"front"} if centre is not None else set()
    track |= {"soft"} & groups
    acc = _Accum(npix, color, centre=centre, track=frozenset(track), phases=phases)
    t0 = time.perf_counter()
    progress = None
    # a bar only on a terminal: in a CI log its carriage-return redraws are noise
    if not quiet and sys.stderr.isatty():
        from tqdm import tqdm

        total = npix * (settings.adaptive_spp if settings.adaptive else settings.spp)
        progress = tqdm(
            total=total,
            unit="spl",
            unit_scale=True,
            desc=f"reference {loaded.name}",
            leave=False,
            mininterval=0.5,
        )
    primary = shadow = 0
    passes = []
    try:
        if sampled:
            all_pixels = np.arange(npix, dtype=np.uint32)
            spp0 = settings.adaptive_spp if settings.adaptive else settings.spp
            p, s = _pass(
                loaded,
                acc,
                all_pixels,
                spp0,
                0,
                settings.seed,
                progress,
                progressive=settings.adaptive,
                launch=samples_per_launch,
            )
            primary, shadow = primary + p, shadow + s
            passes.append({"pixels": int(npix), "spp": spp0})
            if settings.adaptive:
                p, s = _refine(loaded, acc, settings, passes, progress, samples_per_launch)
                primary, shadow = primary + p, shadow + s
        with maybe_phase(phases, "centre", sync=True):
            centre = _centre_channels(loaded, groups, progress) if groups & _CENTRE_GROUPS else {}
            if "tangent32" in groups:
                centre["visibility_tangent32"] = _tangent32_channel(loaded)
            if "motion" in groups:
                centre.update(motion_channels(loaded))
    finally:
        if progress is not None:
            progress.close()
    wall = time.perf_counter() - t0  # rendering only: the images below are not counted
    with maybe_phase(phases, "finish"):
        channels = _finish(acc, groups, centre, w, h)
    stats = _stats(settings, acc, channels, primary, shadow, wall, passes, (w, h), sampled)
    stats.update(_area_stats(loaded, acc))
    if "coverage_exact" in groups:
        with maybe_phase(phases, "coverage_exact"):
            exact, stats["coverage_exact"] = exact_channels(
                loaded, acc.centre, channels, budget=_budget(settings)
            )
        channels.update(exact)
    return channels, stats


def _area_stats(loaded, acc: _Accum) -> dict:
    """How an area light was sampled (nothing for a punctual light, or when neither colour
    nor the soft channels integrate over it)."""
    if not _area_sampled(loaded, acc):
        return {}
    return {
        "light_samples_per_sample": light_samples(loaded.light),
        "light_sampling": f"{loaded.light.area} area light: a jittered 4x4 grid per camera "
        "sample, shifted toroidally per camera sample (oracle.reference.soft)",
    }


def _finish(acc: _Accum, groups: set, centre: dict, w: int, h: int) -> dict[str, np.ndarray]:
    """The output images from the sums: means, standard errors, edge, centre channels."""
    color = acc.color
    channels: dict[str, np.ndarray] = {}

    def img(a):
        return np.asarray(a, dtype=np.float32).reshape(h, w)

    if "visibility" in groups:
        channels["visibility"] = img(acc.vis / acc.n)
        channels["visibility_stderr"] = img(acc.vis_stderr())
    if "coverage" in groups:
        channels["coverage"] = img(acc.cov / acc.n)
        channels["coverage_stderr"] = img(acc.cov_stderr())
        channels["front_coverage"] = img(acc.front / acc.n)
        channels["front_coverage_stderr"] = img(acc.front_stderr())
    if color:
        mean = acc.rgb / acc.n
        se = acc.rgb_stderr()
        for i, c in enumerate("RGB"):
            channels[f"color.{c}"] = img(mean[i])
        for i, c in enumerate("RGB"):
            channels[f"color_stderr.{c}"] = img(se[i])
    if "soft" in groups:
        channels["soft_visibility"] = img(acc.soft / acc.n)
        channels["soft_visibility_stderr"] = img(acc.soft_stderr(acc.soft, acc.soft2))
        channels["light_fraction"] = img(acc.frac / acc.n)
        channels["light_fraction_stderr"] = img(acc.soft_stderr(acc.frac, acc.frac2))
    if "edge" in groups:
        mixed = (acc.vis > 0) & (acc.vis < acc.n)
        channels["edge"] = img((acc.smin != acc.smax) | mixed)
    channels.update(centre)
    return channels


def _stats(settings, acc, channels, primary, shadow, wall, passes, size, sampled) -> dict:
    width, height = size
    rays = primary + shadow
    stats = {
        "rays_cast": int(rays),
        "primary_rays": int(primary),
        "shadow_rays": int(shadow),
        "wall_seconds": wall,
        "mrays_per_second": rays / wall / 1e6 if wall > 0 else 0.0,
        "passes": passes,
    }
    if settings.spp == 1 and not settings.adaptive:
        stats["stderr_note"] = (
            "spp = 1: no variance can be estimated; visibility/coverage stderr is the binomial "
            "floor, colour stderr is 0"
        )
    for name in (
        "visibility_stderr",
        "coverage_stderr",
        "soft_visibility_stderr",
        "light_fraction_stderr",
    ):
        if name in channels:
            stats[f"{name}_mean"] = float(channels[name].mean())
            stats[f"{name}_max"] = float(channels[name].max())
    if "color_stderr.R" in channels:
        cs = np.stack([channels[f"color_stderr.{c}"] for c in "RGB"])
        stats["color_stderr_mean"] = float(cs.mean())
        stats["color_stderr_max"] = float(cs.max())
    if settings.adaptive and sampled:
        stats["adaptive"] = _adaptive_stats(settings, acc, width, height)
    return stats


def _adaptive_stats(settings: ReferenceSettings, acc: _Accum, width: int, height: int) -> dict:
    """The adaptive record: samples spent, standard errors achieved and the uniform spp
    that would meet the same maximum standard error on the pixels near features.

    Pixels far from every feature stop after the first pass and keep their binomial floor
    (``achieved_max_stderr`` includes it, ``achieved_max_stderr_near_features`` does not);
    the uniform comparison is over the near pixels, where the target applies (this is the
    stderr comparison; `bench oracle` measures the true error).
    """
    npix = width * height
    se = np.maximum(acc.vis_stderr(), acc.cov_stderr())
    if acc.color:
        se = np.maximum(se, acc.rgb_stderr().max(axis=0))
    if "soft" in acc.track:
        se = np.maximum(se, _soft_se(acc))
    near = feature_mask(acc, width, height)
    near_se = float(se[near].max()) if near.any() else 0.0
    var = acc.sample_variance()
    target = max(near_se, settings.target_stderr)
    floor_spp = 1
    while binomial_stderr_floor(floor_spp) > target:
        floor_spp *= 2
    uniform_spp = max(
        settings.adaptive_spp, floor_spp, int(math.ceil(float(var.max()) / target**2))
    )
    adaptive_samples = int(acc.n.sum())
    return {
        "target_stderr": settings.target_stderr,
        "achieved_max_stderr": float(se.max()),
        "achieved_max_stderr_near_features": near_se,
        "samples": adaptive_samples,
        "mean_spp": adaptive_samples / npix,
        "max_spp_used": int(acc.n.max()),
        "uniform_spp_for_same_max_stderr": uniform_spp,
        "uniform_samples": int(uniform_spp * npix),
        "rays_ratio_vs_uniform": adaptive_samples / float(uniform_spp * npix),
        "pixels_refined": int((acc.n > settings.adaptive_spp).sum()),
        "pixels_near_features": int(near.sum()),
    }


def _budget(settings) -> float:
    """The exact-coverage budget of ``settings`` (the process default where unset)."""
    return _EXACT_BUDGET[0] if settings.exact_budget is None else float(settings.exact_budget)
