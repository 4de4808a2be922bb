"""Rules of the Dr.Jit kernels that must give the same answer on every backend: one Mitsuba
scene per kernel (the rule, the helper that keeps it, and its audit), and products rounded
before they are added where a result must equal a NumPy rule (:func:`product_rounder`).

On the ``cuda_ad_rgb`` backend Mitsuba traces rays with OptiX, and one OptiX launch may use
only one scene's shader binding table. When a Dr.Jit kernel holds traces of two different
``mi.Scene`` objects (a ray of scene B whose origin, direction or mask depends on an
unevaluated hit of scene A), Dr.Jit prints ``jit_eval(): more than one OptiX shader binding
table was used within a single kernel ... Disabling this ray tracing operation`` and the
trace returns *no hits*, silently: every shadow ray sees the light, every primary ray the
sky. The LLVM backend (Embree) has no such limit, so the mistake is invisible on a CPU.

The rule, for every piece of code that traces more than one scene (ACAA's tie-group
scenes, any sub-scene of a model): **evaluate the results of one scene's trace before
tracing another** with :func:`evaluate_trace` (a ``dr.eval`` with this name, so that the
boundary reads as what it is). Tracing the same scene several times in one kernel is fine
(shadow rays after primary rays of the scene, the self-hit rounds of
:func:`.raycast.occluded_from_dr`).

:func:`audit` checks the rule on the CPU: on the LLVM backend, each kernel's IR calls
Embree through a function pointer with the scene's pointer as an argument, both loaded
from the kernel's parameters and deduplicated by Dr.Jit's value numbering; the number of
distinct scene arguments in a kernel is the number of scenes it traces.
"""

from __future__ import annotations

import contextlib
import re
from dataclasses import dataclass, field

__all__ = ["KernelAudit", "audit", "evaluate_trace", "product_rounder", "scenes_in_ir"]

#: An Embree trace call in Dr.Jit's LLVM IR: ``call void %rdF(ptr %mask, ptr %rdS, ...)``
#: (``%rdF`` the function, ``%rdS`` the scene).
_TRACE_CALL = re.compile(r"call void (%rd\d+)\((?:ptr|i8\*) [^,]+, (?:ptr|i8\*) (%rd\d+)")


def evaluate_trace(*values) -> None:
    """Evaluate ``values`` (Dr.Jit arrays or nests of them) that depend on a trace of one
    scene, before anything traces another scene (see the module docstring)."""
    import drjit as dr

    dr.eval(*values)


def scenes_in_ir(ir: str) -> int:
    """Number of distinct scenes traced by one kernel of Dr.Jit's LLVM backend (its IR)."""
    return len({m.group(2) for m in _TRACE_CALL.finditer(ir)})


@dataclass
class KernelAudit:
    """Kernels launched inside :func:`audit`: ``kernels`` (how many), ``scenes`` (scenes
    traced by each kernel that traces any), ``checked`` (False when the backend's IR cannot
    be read this way: not LLVM)."""

    kernels: int = 0
    scenes: list[int] = field(default_factory=list)
    checked: bool = False

    @property
    def worst(self) -> int:
        """Most scenes traced by one kernel (0 when none traced)."""
        return max(self.scenes, default=0)


@contextlib.contextmanager
def audit():
    """Record the Dr.Jit kernels launched in the ``with`` block; yields a
    :class:`KernelAudit` filled when the block ends (pending work is evaluated first).

    Kernel history costs little, but keeps every kernel's IR: for tests and checks, not for
    production runs.
    """
    import drjit as dr

    from .. import backend

    result = KernelAudit()
    was = dr.flag(dr.JitFlag.KernelHistory)
    dr.eval()
    dr.kernel_history()  # clears the history
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        yield result
        dr.eval()
    finally:
        history = dr.kernel_history()
        dr.set_flag(dr.JitFlag.KernelHistory, was)
    result.checked = backend.active().variant.startswith("llvm")
    for entry in history:
        if entry.get("type") != dr.KernelType.JIT:
            continue
        result.kernels += 1
        ir = entry.get("ir")
        text = ir.getvalue() if hasattr(ir, "getvalue") else str(ir or "")
        count = scenes_in_ir(text)
        if count:
            result.scenes.append(count)


def product_rounder(array_type):
    """``mul(a, b)``: the product rounded to ``array_type`` before anything adds to it, on
    every backend.

    ``ptxas`` (CUDA) contracts a multiply followed by an add into one fused multiply-add,
    which rounds once where NumPy rounds twice; Dr.Jit's PTX has no rounding mode on its
    multiplies and adds, and no flag turns this off (the LLVM backend does not contract). A
    fused multiply-add with an opaque ``-0.0`` is the product rounded (``x + -0.0 = x``
    exactly, signs included), an instruction with an explicit rounding mode that ``ptxas``
    leaves alone, and on LLVM the same bits as a multiply. Use ``mul`` wherever a Dr.Jit sum
    of products must equal a NumPy rule bit for bit.
    """
    import drjit as dr

    zero = dr.opaque(array_type, -0.0)  # a kernel parameter: never folded away

    def mul(a, b):
        return dr.fma(a, b, zero)

    return mul
