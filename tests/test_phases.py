"""Where the time goes (oracle.phases): the phase timer, the kernel-history summary, kernel
reuse across launches and camera frames, and the profiled colour reference (same bytes as
the plain one). Counts and structure only: no timed assertions."""

from __future__ import annotations

import numpy as np
import pytest
from raster_oracle.oracle.phases import (
    Phases,
    device_description,
    kernel_profile,
    maybe_phase,
    summarise_history,
)
from raster_oracle.oracle.reference import render as R
from raster_oracle.oracle.reference import settings as settings_module
from raster_oracle.oracle.reference.render import ReferenceSettings, render_reference

from raster_oracle import raster_models, scenes

#: Phases a profiled sampled reference reports (render_reference's docstring).
REFERENCE_PHASES = {"record", "trace+shade", "reductions", "transfer", "accumulate", "finish"}


def test_phases_add_merge_and_print_one_line_each():
    ph = Phases()
    ph.add("a", 1.0)
    ph.merge({"b": 3.0, "a": 1.0})
    assert ph.record() == {"a": 2.0, "b": 3.0} and ph.total() == 5.0
    lines = ph.lines(title="job", wall=10.0)
    assert lines[0] == "job: 10.00 s"
    assert [ln.split()[0] for ln in lines[1:]] == ["a", "b"]
    assert [ln.split()[-2] for ln in lines[1:]] == ["20.0", "30.0"]  # shares of the wall
    with ph.phase("c"):
        pass
    assert list(ph.record()) == ["a", "b", "c"] and ph.record()["c"] >= 0.0


def test_maybe_phase_without_phases_records_nothing():
    with maybe_phase(None, "x", sync=True):
        value = 1
    assert value == 1
    ph = Phases()
    with maybe_phase(ph, "x"):
        pass
    assert list(ph.record()) == ["x"]


class _IR:
    def __init__(self, text):
        self.text = text

    def getvalue(self):
        return self.text


def test_summarise_history_splits_by_kind_closed_form():
    history = [
        {"type": "KernelType.JIT", "cache_hit": 1, "execution_time": 10.0, "uses_optix": 1},
        {
            "type": "KernelType.JIT",
            "cache_hit": 0,
            "execution_time": 4.0,
            "codegen_time": 1.0,
            "backend_time": 2.0,
            "ir": _IR("; -------- Ray trace -------"),
        },
        {"type": "KernelType.JIT", "cache_hit": 0, "execution_time": 2.0, "ir": _IR("add")},
        {"type": "KernelType.BlockReduce", "execution_time": 3.0},
        {"type": "KernelType.Reduce", "execution_time": 1.0},
        {"type": "KernelType.Memcpy", "execution_time": 0.5},
    ]
    rec = summarise_history(history)
    # Dr.Jit reports milliseconds
    assert rec["trace_seconds"] == pytest.approx(0.014)
    assert rec["kernel_seconds"] == pytest.approx(0.002)
    assert rec["reduction_seconds"] == pytest.approx(0.004)
    assert rec["copy_seconds"] == pytest.approx(0.0005)
    assert rec["compile_seconds"] == pytest.approx(0.003)
    assert (rec["launches"], rec["cache_hits"], rec["compiled"]) == (3, 1, 2)


def test_an_opaque_value_reuses_the_kernel_a_literal_does_not(mi):
    import drjit as dr

    def launch(value, opaque):
        c = dr.opaque(mi.Float, value) if opaque else value
        x = dr.arange(mi.Float, 4096) * c + 1.0
        dr.eval(x)
        return float(dr.sum(x)[0])

    # values never launched before in this process: the in-memory cache cannot know them
    base = 1.0 + float(np.random.default_rng().random())
    _, first = kernel_profile(launch, base, False)
    _, literal = kernel_profile(launch, base + 1.0, False)
    assert first["compiled"] >= 1 and literal["compiled"] >= 1  # a new literal, a new kernel
    kernel_profile(launch, base, True)
    result, opaque = kernel_profile(launch, base + 2.0, True)
    assert opaque["compiled"] == 0 and opaque["cache_hits"] >= 1
    assert result == pytest.approx(4096 * 1.0 + (base + 2.0) * 4095 * 4096 / 2, rel=1e-5)
    assert opaque["wall_seconds"] >= 0 and opaque["host_seconds"] >= 0


def test_a_new_camera_frame_reuses_the_reference_and_model_kernels():
    base = scenes.load("decal", width=32, height=18)
    f1, f2 = (base.with_frame(k, path="dolly", n_frames=8) for k in (1, 2))
    assert not np.array_equal(f1.camera.to_world, f2.camera.to_world)
    settings = ReferenceSettings(spp=4)  # every channel group: samples and pixel centres
    render_reference(f1, settings, quiet=True)
    _, ref = kernel_profile(render_reference, f2, settings, quiet=True)
    assert ref["launches"] > 0 and ref["compiled"] == 0
    for technique in ("noaa", "ssaa"):
        raster_models.run(technique, f1)
        _, rec = kernel_profile(raster_models.run, technique, f2)
        assert rec["compiled"] == 0, technique


def test_profiled_reference_has_its_phases_and_the_same_bytes():
    loaded = scenes.load("city", width=24, height=14)
    settings = ReferenceSettings(spp=4, seed=7, channels=("visibility", "color", "coverage"))
    plain, _ = render_reference(loaded, settings, quiet=True)
    ph = Phases()
    profiled, _ = render_reference(loaded, settings, quiet=True, phases=ph)
    assert REFERENCE_PHASES <= set(ph.record())
    assert all(v >= 0 for v in ph.record().values())
    assert plain.keys() == profiled.keys()
    for k in plain:
        assert plain[k].tobytes() == profiled[k].tobytes(), k


def test_contiguous_chunks_give_the_bytes_of_uploaded_pixel_indices(monkeypatch):
    """A run of pixels adds an opaque first index; any other pixel list is uploaded and
    gathered (the former path for every chunk): the sums agree bit for bit."""
    loaded = scenes.load("city", width=16, height=10)
    monkeypatch.setattr(settings_module, "SAMPLES_PER_CHUNK", 8 * 16)  # launches of 16 pixels
    npix = loaded.width * loaded.height
    runs = np.arange(npix, dtype=np.uint32)
    scattered = np.concatenate([runs[0::2], runs[1::2]])  # no chunk is a run
    sums = []
    for pixels in (runs, scattered):
        acc = R.make_accumulators(loaded, ("visibility", "coverage", "edge", "color"))
        R.sample_pass(loaded, acc, pixels, 8, 0, 3, None)
        g = acc.groups
        sums.append(
            {
                "n": acc.n,
                "vis": g["visibility"].vis,
                "cov": g["coverage"].cov,
                "front": g["coverage"].front,
                "rgb": g["color"].rgb,
                "rgb2": g["color"].rgb2,
                "smin": g["edge"].smin,
                "smax": g["edge"].smax,
            }
        )
    for k in sums[0]:
        assert sums[0][k].tobytes() == sums[1][k].tobytes(), k


def test_device_description_names_the_machine(_backend):
    dev = device_description(_backend.variant)
    assert dev["variant"] == _backend.variant
    assert dev["kind"] == ("gpu" if "cuda" in _backend.variant else "cpu")
    assert dev["name"] and dev["cores"] >= 1 and dev["drjit_threads"] >= 1


def test_numpy_view_of_a_vector_launches_no_kernel(mi):
    """Dr.Jit's own conversion of a vector packs it with a kernel whose literal is the
    length (a new compile per length); component by component nothing is launched."""
    import drjit as dr
    from raster_oracle.raster_models.drjit import numpy_view

    for n in (1000, 1001):
        i = dr.arange(mi.Float, n)
        v = mi.Vector3f(i, i * 2.0, i * 3.0)
        dr.eval(v)
        arr, rec = kernel_profile(numpy_view, v)
        assert rec["launches"] == 0
        assert arr.shape == (3, n)
        np.testing.assert_array_equal(arr, np.arange(n, dtype=np.float32) * [[1], [2], [3]])


def test_numpy_view_broadcasts_a_narrow_component(mi):
    """A vector may hold a width-1 component (a literal): it is broadcast as Dr.Jit does
    (the glTF scenes' MSAA failed on np.stack of unequal parts without it)."""
    import drjit as dr
    from raster_oracle.raster_models.drjit import numpy_view

    v = mi.Vector3f(dr.arange(mi.Float, 5), 2.0, dr.arange(mi.Float, 5) * 3.0)
    np.testing.assert_array_equal(numpy_view(v), np.asarray(v.numpy()))
    assert numpy_view(v).shape == (3, 5)


def test_aligned_copies_start_on_the_boundary_and_reuse_the_kernel(mi):
    import drjit as dr
    from raster_oracle.raster_models.drjit import DRJIT_ALIGN, aligned

    def launch(a):
        y = mi.Float(a) * 2.0 + 1.0
        dr.eval(y)
        return y

    src = np.arange(100, dtype=np.float64)
    recs = []
    for start in (0, 1, 3):  # three source addresses; NumPy's own copies are 16-aligned
        a = aligned(src[start : start + 64])
        assert a.ctypes.data % DRJIT_ALIGN == 0 and a.dtype == np.float32
        np.testing.assert_array_equal(a, src[start : start + 64])
        y, rec = kernel_profile(launch, a)
        np.testing.assert_array_equal(np.asarray(y), 2 * a + 1)
        recs.append(rec)
    assert [r["compiled"] for r in recs[1:]] == [0, 0]
    flags = aligned(np.array([True, False, True]), bool)
    assert flags.ctypes.data % DRJIT_ALIGN == 0 and flags.tolist() == [True, False, True]
