"""How a reference is rendered: its settings (every field enters the cache key), the channel
groups that can be asked for, and the memory a render needs.

The exact-coverage budget is a setting like the others (``exact_budget``, seconds), handed
down from the command line or the library call that makes the settings: no process state.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

from ...scenes import backend
from ...scenes.base.memory import available_memory, gib
from ..errors import InputError

__all__ = [
    "ALL_CHANNELS",
    "CENTRE_GROUPS",
    "CHANNEL_GROUPS",
    "CUDA_CHUNK_FACTOR",
    "EXACT_BUDGET_S",
    "ExactBudget",
    "MAX_SEED",
    "OPTIONAL_GROUPS",
    "SAMPLED_GROUPS",
    "SAMPLES_PER_CHUNK",
    "ReferenceSettings",
    "ReferenceSettingsError",
    "available_memory",
    "channel_names",
    "check_memory",
    "estimate_memory",
    "grid_shape",
    "samples_per_chunk",
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
#: Groups read at the pixel centres (one ray each, no sampling noise).
CENTRE_GROUPS = ("id", "depth", "position", "normal", "albedo")
#: Groups whose values are integrated over the pixel by the sampled passes.
SAMPLED_GROUPS = ("visibility", "coverage", "color", "edge", "soft")
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


#: Default ``--exact-budget``: seconds of ``coverage_exact`` work a command may spend.
EXACT_BUDGET_S = 60.0


class ExactBudget:
    """Seconds of ``coverage_exact`` work allowed, and how many were spent: a deadline the
    exact pass checks as it works (:func:`oracle.reference.coverage.exact_channels`).

    One object is one budget: a command makes one and hands it to every reference's
    settings (all views and frames, the noise floors included), so their exact work adds up
    against it; settings given a number make their own. Two budgets of the same seconds
    compare equal (the cache key holds the seconds, never what was spent).

    ``since`` (a :func:`time.perf_counter` reading, the command's start) makes the budget the
    command's deadline: what is left is the budget less the exact work spent or the time since
    the command started, whichever is more, so the exact pass (which runs after a view's Monte
    Carlo work) stops by ``since + seconds`` and the command returns about then (the CLI's
    ``--exact-budget``). Without it only the exact work counts (a sweep's cases, the API).
    """

    def __init__(self, seconds: float = EXACT_BUDGET_S, *, since: float | None = None):
        self.seconds = float(seconds)
        self.spent = 0.0
        self.since = since

    @classmethod
    def of(cls, budget) -> ExactBudget:
        """``budget`` itself when it is one, else a new one of ``budget`` seconds (None:
        :data:`EXACT_BUDGET_S`)."""
        if isinstance(budget, ExactBudget):
            return budget
        return cls(EXACT_BUDGET_S if budget is None else float(budget))

    def left(self) -> float:
        """Seconds not spent yet (0 once the budget is used up or the deadline passed)."""
        used = self.spent
        if self.since is not None:
            used = max(used, time.perf_counter() - self.since)
        return max(0.0, self.seconds - used)

    def charge(self, seconds: float) -> None:
        """Count ``seconds`` of exact work against the budget."""
        self.spent += max(0.0, float(seconds))

    def __eq__(self, other) -> bool:
        return isinstance(other, ExactBudget) and other.seconds == self.seconds

    def __hash__(self) -> int:
        return hash(("ExactBudget", self.seconds))

    def __deepcopy__(self, memo) -> ExactBudget:
        return self  # one ledger, shared: dataclasses.asdict must not copy it

    def __repr__(self) -> str:
        return f"ExactBudget({self.seconds:g} s, {self.spent:.3g} s spent)"


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
    #: ``coverage_exact`` work allowed: an :class:`ExactBudget` (shared by whoever holds it),
    #: seconds (a budget of these settings' own) or None (:data:`EXACT_BUDGET_S`). The
    #: estimate refuses a view that would not fit in what is left, and the exact pass stops
    #: when it runs out (scenes.geometry.exact_coverage); coverage is then scored against the
    #: Monte Carlo truth.
    exact_budget: ExactBudget | float | None = None

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
        budget = ExactBudget.of(self.exact_budget)
        if not budget.seconds >= 0:
            raise ReferenceSettingsError(f"exact budget must be >= 0 seconds, got {budget.seconds}")
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
        seconds = budget.seconds if isinstance(budget, ExactBudget) else budget
        if "coverage_exact" in self.channels and seconds not in (None, EXACT_BUDGET_S):
            rec["exact_budget"] = seconds
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
    sampled = groups & set(SAMPLED_GROUPS)
    spp_max = int(max_spp if max_spp is not None else spp)
    launch = min(pixels * spp_max, SAMPLES_PER_CHUNK) if sampled else min(pixels, SAMPLES_PER_CHUNK)
    if "tangent32" in groups:
        launch = max(launch, min(pixels * 32, SAMPLES_PER_CHUNK))
    per_sample = _BYTES_PER_COLOR_SAMPLE if color else _BYTES_PER_SAMPLE
    outputs = len(channel_names([g for g in CHANNEL_GROUPS if g in groups]))
    per_pixel = _BYTES_PER_PIXEL + (_BYTES_PER_COLOR_PIXEL if color else 0) + 8 * outputs
    return _BASE_BYTES + launch * per_sample + pixels * per_pixel


def check_memory(width: int, height: int, settings: ReferenceSettings) -> None:
    """Raise :class:`ReferenceSettingsError` when a ``width x height`` reference with
    ``settings`` (validated) needs more memory than is available (:func:`estimate_memory`)."""
    need = estimate_memory(
        width,
        height,
        spp=settings.spp,
        channels=settings.channels,
        max_spp=settings.max_spp if settings.adaptive else None,
    )
    have = available_memory()
    if need > have:
        raise ReferenceSettingsError(
            f"a {width}x{height} reference at {settings.spp} spp needs about {gib(need)}; "
            f"only {gib(have)} is available"
        )
