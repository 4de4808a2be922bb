"""The ``rtshadows-*`` models: one shadow ray a pixel a frame (:mod:`.rays`), denoised over
frames by a transcribed denoiser (:mod:`.ffx`, :mod:`.svgf`, :mod:`.sigma`) or not at all.

Frame ``k`` of the scene's sequence (camera path, object paths) is the result of running the
denoiser from frame 0 to ``k`` on that frame's inputs (:func:`.frames.build_frame`: exact
motion vectors and disocclusion, one ray a pixel); the state after each frame is kept (keyed
by the sequence and the technique's parameters) so that scoring frames 0..N-1 in order costs
one frame each, as the ``taa`` model does. The frames' inputs do not depend on the denoiser:
they are built once per sequence and process and shared by every denoiser (:data:`_FRAMES`,
read-only arrays), so the five models on one sequence trace it once.

Outputs: ``soft_visibility`` and ``light_fraction`` (the denoised shadow factor, ``(H, W)``
float32 in [0, 1], 0 off receivers), ``noisy`` (the frame's one-ray visibility),
``penumbra`` (NRD's packed input, capped at 1 for display: world units).

Cost record: ``rays_per_pixel`` (1), ``shadow_rays``, ``taps_per_pixel`` (texel reads of the
denoiser's passes a pixel a frame), ``memory_bytes`` and ``framebuffer_bytes_per_pixel`` (the
denoiser's own buffers: history, moments, intermediate passes, at their GPU formats).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .. import params as _params
from ..result import model_result
from .ffx import ffx_step
from .frames import build_frame
from .sigma import sigma_step
from .svgf import SvgfParams, svgf_step

__all__ = [
    "DENOISERS",
    "LIGHTS",
    "NoParams",
    "clear_shared_frames",
    "cost_record",
    "denoise_step",
    "make_runner",
]

MAX_SEQUENCES = 8
_STATES: OrderedDict = OrderedDict()
#: Frames kept (:func:`.frames.build_frame` inputs, shared by the denoisers), LRU; a 160x90
#: frame is about 1 MB, a 1080p one about 190 MB, so the bound is in bytes.
MAX_FRAME_BYTES = 256 << 20
_FRAMES: OrderedDict = OrderedDict()


@dataclass(frozen=True)
class NoParams:
    """A model without parameters (the transcriptions take their sources' constants)."""


#: Light kinds the models accept (an area light's punctual proxy is a point light,
#: :mod:`scenes.lights`; a disk is a sun of angular size, a rectangle sampled over its area,
#: the others give hard shadows: :mod:`.rays`).
LIGHTS = ("directional", "point", "spot")

#: denoiser -> (per-pixel bytes of its buffers, texel taps a pixel a frame, source)
DENOISERS = {
    "none": (0, 0, "the one-ray visibility as it is (an integration that denoises nothing)"),
    # moments RGB32F 12 + history RG16F 4 + reprojection RG16F 4 + filter ping-pong RG16F 4 +
    # previous depth R32F 4 + 1 mask bit; taps: 17x17 moments from masks (3 mask reads) +
    # 4 bilinear history + 1 moments + 1 depth, 3 passes x (9 + 9 variance) x (input, depth,
    # normal)
    "ffx": (28, 3 + 4 + 1 + 1 + 3 * 18 * 3, "FidelityFX-SDK v1.1.4 shadow denoiser"),
    # illumination RGBA16F 8 x 3 (current, ping-pong 2, filtered past) + moments RG16F 4 x 2
    # + history R16F 2 x 2 + linear z and normal RGBA32F 16 x 2; taps: 4 bilinear + 4
    # z/normal + 49 moments-filter x 3 + 4 iterations x 25 x 3
    "svgf": (68, 4 + 4 + 49 * 3 + 4 * 25 * 3, "Falcor eb540f6 SVGFPass"),
    "asvgf": (72, 4 + 4 + 49 * 3 + 4 * 25 * 3 + 3 * 25 * 2 // 9, "A-SVGF on Falcor's SVGF"),
    # penumbra R16F 2 x 2 + shadow R8 1 x 3 + history R32UI 4 x 2 + tiles; taps: 2 blur passes
    # x (25 dense + 8 sparse) x 3 (shadow, penumbra, depth) + 25 + 4 history
    "sigma": (18, 2 * 33 * 3 + 25 + 4, "SIGMA-class from NRD a822d87 settings"),
}


def cost_record(denoiser: str, width: int, height: int) -> dict:
    """The technique's own GPU budget at this resolution (see the module docstring)."""
    per_pixel, taps, _ = DENOISERS[denoiser]
    n = int(width) * int(height)
    return {
        "rays_per_pixel": 1,
        "taps_per_pixel": int(taps),
        "framebuffer_bytes_per_pixel": int(per_pixel),
        "memory_bytes": int(per_pixel * n),
        "framebuffer_bytes": int(per_pixel * n),
        "width": int(width),
        "height": int(height),
    }


def _scene_key(scene) -> tuple:
    return (
        scene.content_hash,
        scene.camera_path,
        scene.light_path,
        scene.light_index,
        scene.camera_file,
        scene.n_frames,
        scene.width,
        scene.height,
    )


def _sequence_key(scene, denoiser: str, p) -> tuple:
    return (*_scene_key(scene), denoiser, repr(p))


def _frame_bytes(frame) -> int:
    return sum(v.nbytes for v in vars(frame).values() if isinstance(v, np.ndarray))


def clear_shared_frames() -> None:
    """Forget the shared frames (and the denoisers' states built on them): the next run
    traces its sequence again (a test auditing each model's own kernels)."""
    _FRAMES.clear()
    _STATES.clear()


def shared_frame(scene, j: int, previous):
    """Frame ``j`` of ``scene``'s sequence (:func:`.frames.build_frame`, ``previous`` frame
    ``j - 1`` of the same sequence), built once per process: its arrays are read-only."""
    key = (*_scene_key(scene), j)
    frame = _FRAMES.get(key)
    if frame is None:
        frame = build_frame(_frame_scene(scene, j), j, previous)
        for value in vars(frame).values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        _FRAMES[key] = frame
        while len(_FRAMES) > 1 and sum(map(_frame_bytes, _FRAMES.values())) > MAX_FRAME_BYTES:
            _FRAMES.popitem(last=False)
    _FRAMES.move_to_end(key)
    return frame


def _frame_scene(scene, j: int):
    if j == scene.frame:
        return scene
    return scene.with_frame(j, n_frames=scene.n_frames)


def denoise_step(denoiser: str, frame, state, p):
    """One frame of ``denoiser`` (a key of :data:`DENOISERS`) on a :class:`.frames.Frame`:
    ``(visibility, new state, record)``; ``p`` an :class:`.svgf.SvgfParams` or None."""
    if denoiser == "none":
        return frame.noisy.copy(), None, {}
    if denoiser == "ffx":
        return ffx_step(frame, state)
    if denoiser == "sigma":
        return sigma_step(frame, state)
    sp = p if isinstance(p, SvgfParams) else None
    return svgf_step(frame, state, sp, adaptive=denoiser == "asvgf")


def make_runner(technique: str, denoiser: str):
    """The registry's entry point of ``technique`` running ``denoiser``."""

    def run(scene, p=None):
        t0 = time.perf_counter()
        p = p if p is not None else NoParams()
        key = _sequence_key(scene, denoiser, p)
        k = int(scene.frame)
        start, prev, state, out = 0, None, None, None
        if key in _STATES and _STATES[key][0] <= k:
            done, prev, state, out = _STATES[key]
            start = done + 1
        rays = 0
        for j in range(start, k + 1):
            prev = shared_frame(scene, j, prev)
            out, state, _ = denoise_step(denoiser, prev, state, p)
            rays += prev.rays
        _STATES[key] = (k, prev, state, out)
        _STATES.move_to_end(key)
        while len(_STATES) > MAX_SEQUENCES:
            _STATES.popitem(last=False)
        vis = np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0).astype(np.float32)
        cost = cost_record(denoiser, scene.width, scene.height)
        cost["shadow_rays"] = int(rays)
        outputs = {
            "soft_visibility": vis,
            "light_fraction": vis,
            "noisy": prev.noisy.astype(np.float32),
            "penumbra": np.minimum(prev.penumbra, 1.0).astype(np.float32),
        }
        diagnostics = {
            "denoiser": denoiser,
            "source": DENOISERS[denoiser][2],
            "frames_run": k + 1 - start,
            "frame": k,
            "gradient_samples": int(prev.grad_valid.sum()),
        }
        return model_result(
            technique,
            scene,
            outputs=outputs,
            cost=cost,
            diagnostics=diagnostics,
            params=_params.as_dict(p),
            t0=t0,
        )

    run.__name__ = f"run_{denoiser}"
    return run
