"""The named gate profiles of the engine teams' tools (``--gate-profile``), judging the
metrics :mod:`oracle.scoring.engine_metrics` adds to a score.

Profiles (the published defaults of each tool):

- ``unreal-low``, ``unreal-medium``, ``unreal-high``: Unreal's screenshot comparison at that
  tolerance, global error <= 0.02 and local error <= 0.10;
- ``unity``: Unity's average JzAzBz delta E <= 0.005 (above 0.001 a pixel);
- ``edge-aware``: at most 0.5 % of the pixels beyond the edge-aware tolerance;
- ``conformance`` (with ``--expect``): the recommended conformance gate, which caught every
  fault of the detection-power table with no correct engine flagged (docs/metrics.md,
  "Detection power of the conformance gate"): misclassified <= 0.001 of the receivers,
  edges <= 0.1 px from the model's, FLIP <= 0.001.
"""

from __future__ import annotations

from dataclasses import replace

from ....metrics import engine_gates as G
from .checks import Gate

__all__ = ["CONFORMANCE_LIMITS", "EDGE_AWARE_LIMIT", "GATE_PROFILES", "profile_gates"]

#: ``edge-aware`` profile: at most 0.5 % of the scored pixels beyond their tolerance (a
#: reference's 3-sigma test flags 0.27 % of an exact candidate's Gaussian pixels).
EDGE_AWARE_LIMIT = 0.005


#: ``conformance`` profile (``oracle/studies/detection.py`` measures it: ``bench detection``).
CONFORMANCE_LIMITS = {
    "conformance_misclassified_fraction": 0.001,
    "conformance_edge_displacement_px": 0.1,
    "conformance_flip_mean": 0.001,
}


def _unreal_profile(level: str) -> tuple[Gate, ...]:
    tol = G.UNREAL_TOLERANCES[level]
    return (
        Gate(f"unreal_{level}_global_error", "<=", tol.maximum_global_error),
        Gate(f"unreal_{level}_local_error", "<=", tol.maximum_local_error),
    )


#: ``--gate-profile NAME`` -> its gates (the published defaults of each tool).
GATE_PROFILES = {
    "unreal-low": _unreal_profile("low"),
    "unreal-medium": _unreal_profile("medium"),
    "unreal-high": _unreal_profile("high"),
    "unity": (Gate("unity_average_delta_e", "<=", G.UNITY_AVERAGE_THRESHOLD),),
    "edge-aware": (Gate("edge_aware_error_fraction", "<=", EDGE_AWARE_LIMIT),),
    "conformance": tuple(Gate(k, "<=", v) for k, v in CONFORMANCE_LIMITS.items()),
}


def profile_gates(names, *, error=ValueError, origin: str = "--gate-profile") -> list[Gate]:
    """The gates of the named profiles, in order, each ``optional`` (skipped on a candidate
    kind its metric does not apply to) and named ``f"{origin} {name}"`` in messages;
    ``error`` naming the valid profiles for an unknown one."""
    gates = []
    for name in names or ():
        if name not in GATE_PROFILES:
            raise error(f"{origin} {name!r}: choose from {', '.join(GATE_PROFILES)}")
        gates.extend(
            replace(g, origin=f"{origin} {name}", optional=True) for g in GATE_PROFILES[name]
        )
    return gates
