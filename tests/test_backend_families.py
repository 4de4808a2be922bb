"""CPU tests of the root causes behind the failure families of the first CUDA run (issue
24) that are not covered elsewhere. The others: ACAA's second scene in a kernel in
``test_one_scene_per_kernel.py``, the split launches' order of float sums in
``test_oracle_statistics.py`` (``test_block_sums_do_not_depend_on_the_order``), the memory
guard in ``test_cli_reference.py``."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.raster_models import depth


def test_d32f_flushes_subnormals_whatever_the_conversion_does(mi):
    """D32F texels: CUDA's float64 -> float32 conversion keeps a subnormal, the LLVM
    backend's flushes it to zero (3 D32F cases differed on an H200). The format rule now
    flushes on the bits: with a conversion that keeps subnormals (NumPy's, standing in for
    CUDA's) the stored bytes are still D3D's +-0."""

    class KeepsSubnormals:
        def __getattr__(self, name):
            return getattr(mi, name)

        @staticmethod
        def Float32(values):  # noqa: N802 (Mitsuba's type name)
            return mi.Float32(np.asarray(values.numpy(), np.float64).astype(np.float32))

    tiny = 2.0**-149
    z = np.array([3 * tiny, -5 * tiny, 2.0**-130, 2.0**-126, 0.5, -0.0, 0.0, 1.0])
    kept = KeepsSubnormals.Float32(mi.Float64(z)).numpy()
    assert kept[0] != 0.0  # the stand-in keeps them, as CUDA does
    got = depth.quantize_dr(KeepsSubnormals(), mi.Float64(z), "D32F").numpy()
    want = np.array([0.0, -0.0, 0.0, 2.0**-126, 0.5, -0.0, 0.0, 1.0])
    assert got.tobytes() == want.tobytes()


def test_cuda_runs_with_ieee_division_and_llvm_keeps_its_default():
    """AGAA's rgba16f lanes: CUDA's FastMath compiles float32 division to div.approx (2 ulp)
    and flipped clustering decisions NumPy's IEEE rule makes; the backend turns it off for
    CUDA (an H200 run agreed with NumPy with it off). LLVM's division is IEEE either way and
    keeps Dr.Jit's default, so its bytes do not change."""
    import drjit as dr
    from raster_oracle.scenes import backend

    before = dr.flag(dr.JitFlag.FastMath)
    try:
        assert backend.exact_arithmetic("cuda_ad_rgb") is False
        assert dr.flag(dr.JitFlag.FastMath) is False
        assert backend.exact_arithmetic("llvm_ad_rgb") is True
        assert dr.flag(dr.JitFlag.FastMath) is True
    finally:
        dr.set_flag(dr.JitFlag.FastMath, before)


def test_izb_plane_tests_round_every_product():
    """IZB on a spot light disagreed with the oracle on an H200: its plane values
    ``n . p + c`` and ``base + da a + db b`` must round as NumPy does, and ``ptxas``
    contracts a multiply followed by an add into one fused multiply-add. Every product of
    the pair-test kernels is an explicit ``fma(a, b, -0.0)`` (the product, rounded), never a
    bare multiply: read from the LLVM IR of the kernels that test pairs."""
    import re

    import drjit as dr
    from raster_oracle.scenes import backend

    from raster_oracle import raster_models as rm
    from raster_oracle import scenes

    if not backend.active().variant.startswith("llvm"):
        pytest.skip("reads the LLVM backend's IR")
    s = scenes.load("spot", width=48, height=27)
    rm.run("izb", s, samples=32)  # compiled once
    dr.eval()
    dr.kernel_history()
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        rm.run("izb", s, samples=32)
    finally:
        history = dr.kernel_history()
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    irs = [k["ir"].getvalue() for k in history if k["type"] == dr.KernelType.JIT]
    pair_kernels = [ir for ir in irs if len(re.findall(r"call <\d+ x double> @llvm\.fma", ir)) >= 8]
    assert len(pair_kernels) >= 2  # the bounds kernel and the 32-point kernel
    for ir in pair_kernels:
        assert not re.search(r"= fmul <\d+ x double>", ir)
