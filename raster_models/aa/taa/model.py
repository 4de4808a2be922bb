"""The ``taa`` model: one jittered sample a pixel a frame, accumulated into a history that
is reprojected with the model's own motion vectors, rectified and blended.

Frame ``k`` of a sequence (the scene's camera path, light path, camera file or object paths;
a scene without any is its own sequence of still frames) is the result of running the TAA
from frame 0 to ``k``: each frame renders its G-buffer and colour at the jittered sample of
every pixel (the oracle's shading and exact shadow ray, as ``noaa``), computes its velocity
buffer from that G-buffer (the sample's surface point carried back along its object path and
projected by the previous camera: :func:`scenes.geometry.motion.film_motion`, what an engine's
velocity pass writes), optionally dilated to the nearest-depth 3x3 neighbour's, reads the
previous output there (bilinear or Catmull-Rom), rejects it off screen (and optionally where
the previous depth disagrees), rectifies it against the current samples' neighbourhood and
blends. The state after each frame is kept (keyed by the scene's sequence and the resolved
parameters) so that scoring frames 0..N-1 in order costs one TAA frame each.

An engine preset with no part set (``ue4``, ``ue4-high``, ``ue4-18``, ``ue4-20``, ``inside``,
``hdrp``, ``hdrp-high``, ``filament``; ``resolved["engine"]``) replaces the part-by-part resolve by
that engine's transcription (:mod:`.ue4`, :mod:`.inside`, :mod:`.hdrp`, :mod:`.filament`),
fed what the engine's own passes would hand it: the jittered frame at the engine's jitter,
each sample's motion (its velocity buffer; UE4 only for moving objects, which write it, and
the camera reprojection of the pixel centre at a depth elsewhere; Filament the camera
reprojection alone), view depth; its state is the engine's stored history (8-bit sRGB for
INSIDE, R11G11B10 for HDRP, half float for UE4 with its dynamic flag and for Filament).

Cost record (the technique's budget at this resolution, from the preset's part values):
``framebuffer_bytes`` with ``framebuffer_bytes_by_buffer`` (``color`` RGBA16F current frame,
``depth`` D32F, twice with depth rejection, ``velocity`` RG16F, ``history`` 2 x RGBA16F read
and written), ``history_bytes``, ``velocity_bytes``, ``taps_per_pixel`` (current-frame
texels + history fetches + depth/velocity taps), ``bandwidth_bytes`` (texels read + history
and output written, per frame), ``samples`` (1 shaded sample a pixel a frame),
``shading_events_mean``.
"""

from __future__ import annotations

import time
from collections import OrderedDict

import numpy as np

from ....scenes.geometry.motion import film_motion
from ... import params as _params
from ...result import model_result
from ..trace import sample_colors
from . import filament, hdrp, inside, ue4
from .blend import blend
from .filters import bilinear, catmull_rom, filter_current, neighbours
from .jitter import jitter_offsets
from .params import PRESET_SOURCES, TaaParams, resolve
from .rectify import rectify

__all__ = ["NAME", "cost_record", "run"]

NAME = "taa"
#: Relative depth difference above which ``reject=depth`` drops the history.
DEPTH_REJECT_REL = 0.01
#: Sequences whose last TAA state is kept (each holds one frame's buffers).
MAX_SEQUENCES = 8
_STATES: OrderedDict = OrderedDict()


def _sequence_key(scene, r: dict) -> tuple:
    return (
        scene.content_hash,
        scene.camera_path,
        scene.light_path,
        scene.light_index,
        scene.camera_file,
        scene.n_frames,
        scene.width,
        scene.height,
        tuple(sorted(r.items())),
    )


def _frame(scene, j: int):
    if scene.camera_path is None and scene.light_path is None and not scene.object_motion:
        return scene
    return scene.with_frame(j, n_frames=scene.n_frames)


def _velocity(m: dict, h: int, w: int, dilation: str):
    """``(H, W, 2)`` velocity (pixels to the previous frame), ``(H, W)`` depth (inf sky)."""
    mv = np.stack([m["motion_x"], m["motion_y"]], -1).reshape(h, w, 2)
    depth = np.where(m["valid"], m["depth"], np.inf).reshape(h, w)
    if dilation == "none":
        return mv, depth
    nearest = np.argmin(neighbours(depth[..., None])[..., 0], axis=0)
    mv = np.take_along_axis(neighbours(mv), nearest[None, ..., None], axis=0)[0]
    return mv, depth


def _camera_reprojection(scene, x, y, depth):
    """The previous film position of the point at view depth ``depth`` on each pixel
    centre's ray (camera motion alone; an infinite depth, the sky, is the ray's direction):
    Filament's reprojection and UE4's camera velocity."""
    cam, pcam = scene.camera, scene.previous().camera
    o, d, tmax = cam.rays(x, y)
    z = np.asarray(depth, dtype=np.float64).ravel()
    finite = np.isfinite(z)
    with np.errstate(invalid="ignore"):
        t = (np.where(finite, z, 0.0) - cam.view_depth(o)) / (d @ cam.forward)
    q = o + d * t[:, None]
    sky = pcam.position + d if cam.kind == "perspective" else o + d * tmax[:, None]
    film = pcam.project(np.where(finite[:, None], q, sky))
    return film[:, 0].reshape(x.shape), film[:, 1].reshape(x.shape)


def _engine_module(engine: str):
    return {
        "inside": inside,
        "filament": filament,
        "hdrp": hdrp,
        "hdrp-high": hdrp,
        "ue4": ue4,
        "ue4-18": ue4,
        "ue4-20": ue4,
        "ue4-high": ue4,
    }[engine]


def _engine_step(scene, state, r: dict, frame: int) -> tuple[dict, dict]:
    """One frame of an engine's transcribed resolve (``r["engine"]``: inside, filament)."""
    h, w = scene.height, scene.width
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    mod = _engine_module(r["engine"])
    jit = mod.jitter(frame)
    res, rays = sample_colors(scene, np.array([[0.5 + jit[0], 0.5 + jit[1]]]))
    samples = res["color"].reshape(h, w, 3).astype(np.float64)
    m = film_motion(scene, x + jit[0], y + jit[1], disocclusion=False)
    depth = np.where(m["valid"], m["depth"], np.inf).reshape(h, w)
    previous = None if state is None else state["history"]
    discarded = np.zeros((h, w), bool)  # INSIDE and Filament never drop their history
    if mod is ue4:
        mv = np.stack([m["motion_x"], m["motion_y"]], -1).reshape(h, w, 2)
        moving = [scene.shape_names.index(n) for n in scene.object_motion]
        dynamic = (m["valid"] & np.isin(m["shape"], moving)).reshape(h, w)
        if state is None:
            mv, dynamic = 0.0 * mv, np.zeros_like(dynamic)

            def camera_prev(_depth):
                return x, y
        else:

            def camera_prev(z):
                return _camera_reprojection(scene, x, y, z)

        version = {"ue4-18": "4.18", "ue4-20": "4.20", "ue4-high": "4.19-high"}.get(
            r["engine"], "4.19"
        )
        out, weight, vel, discarded = ue4.step(
            previous, samples, frame, mv, depth, dynamic, camera_prev, version
        )
        history, out = out, out[..., :3]
    elif mod is hdrp:
        mv = np.stack([m["motion_x"], m["motion_y"]], -1).reshape(h, w, 2)
        mv = mv if state is not None else 0.0 * mv
        quality = "high" if r["engine"] == "hdrp-high" else "medium"
        out, weight, vel, discarded = hdrp.step(previous, samples, frame, mv, depth, quality)
        history = out
    elif mod is inside:
        mv = np.stack([m["motion_x"], m["motion_y"]], -1).reshape(h, w, 2)
        out, history, k = inside.step(previous, samples, jit, mv, depth)
        weight = 1.0 - k
        vel = inside.closest_velocity(mv if state is not None else 0.0 * mv, depth)
    else:
        hx, hy = (x, y) if state is None else _camera_reprojection(scene, x, y, depth)
        out, weight = filament.step(previous, samples, frame, hx, hy)
        history = out
        vel = np.stack([hx - x, hy - y], -1)
    rejected = np.full((h, w), state is None) | discarded
    outputs = {
        "color": out.astype(np.float32),
        "current_weight": np.asarray(weight, dtype=np.float32),
        "rejected": rejected.astype(np.float32),
        "velocity_x": vel[..., 0].astype(np.float32),
        "velocity_y": vel[..., 1].astype(np.float32),
    }
    return {"history": history, "depth": depth, "rays": rays}, outputs


def _step(scene, state, r: dict, jitter: np.ndarray) -> tuple[dict, dict]:
    """One TAA frame: the new state and the frame's outputs."""
    h, w = scene.height, scene.width
    y, x = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    res, rays = sample_colors(scene, np.array([[0.5 + jitter[0], 0.5 + jitter[1]]]))
    samples = res["color"].reshape(h, w, 3).astype(np.float64)
    m = film_motion(scene, x + jitter[0], y + jitter[1], disocclusion=False)
    mv, depth = _velocity(m, h, w, r["dilation"])
    current = filter_current(samples, jitter, r["input_filter"])
    alpha = np.full((h, w), r["alpha"])
    rejected = np.ones((h, w), bool)
    hist = current
    if state is not None:
        hx, hy = (x + mv[..., 0], y + mv[..., 1]) if r["reprojection"] == "motion" else (x, y)
        rejected = np.zeros((h, w), bool)
        if r["reject"] in ("offscreen", "depth"):
            rejected |= (hx < 0) | (hx >= w) | (hy < 0) | (hy >= h)
        if r["reject"] == "depth":
            ix = np.clip(np.floor(hx).astype(int), 0, w - 1)
            iy = np.clip(np.floor(hy).astype(int), 0, h - 1)
            before = state["depth"][iy, ix]
            expect = m["depth_previous"].reshape(h, w)
            with np.errstate(invalid="ignore"):
                off = np.abs(before - expect) > DEPTH_REJECT_REL * np.minimum(before, expect)
            rejected |= off & ~(np.isinf(before) & np.isinf(expect))
        sampler = catmull_rom if r["history_filter"] == "catmull-rom" else bilinear
        hist = np.maximum(sampler(state["color"], hx, hy), 0.0)
        hist = rectify(
            hist,
            samples,
            rectifier=r["rectify"],
            space=r["color_space"],
            shape=r["neighbourhood"],
            gamma=r["gamma"],
        )
    alpha = np.where(rejected, 1.0, alpha)
    speed = np.hypot(mv[..., 0], mv[..., 1])
    out, weight = blend(hist, current, kind=r["blend"], alpha=alpha, speed_px=speed)
    outputs = {
        "color": out.astype(np.float32),
        "current_weight": weight.astype(np.float32),
        "rejected": rejected.astype(np.float32),
        "velocity_x": mv[..., 0].astype(np.float32),
        "velocity_y": mv[..., 1].astype(np.float32),
    }
    return {"color": out, "depth": depth, "rays": rays}, outputs


def cost_record(r: dict, width: int, height: int) -> dict:
    """The TAA's GPU budget at ``width`` x ``height`` for the resolved parameters ``r``
    (see the module docstring)."""
    n = int(width) * int(height)
    depth_buffers = 2 if r["reject"] == "depth" else 1
    buffers = {
        "color": 8 * n,
        "depth": 4 * n * depth_buffers,
        "velocity": 4 * n,
        "history": 2 * 8 * n,
    }
    wide = r["input_filter"] == "ue4" or r["rectify"] != "none" and r["neighbourhood"] != "plus"
    current_texels = 9 if wide else (5 if r["rectify"] != "none" else 1)
    cubic = r["history_filter"] == "catmull-rom"
    history_fetches, history_texels = (9, 16) if cubic else (1, 4)
    depth_taps = (9 if r["dilation"] != "none" else 0) + (1 if r["reject"] == "depth" else 0)
    taps = current_texels + history_fetches + depth_taps + 1
    per_pixel = current_texels * 8 + history_texels * 8 + depth_taps * 4 + 4 + 8
    return {
        "framebuffer_bytes": int(sum(buffers.values())),
        "framebuffer_bytes_by_buffer": buffers,
        "history_bytes": buffers["history"],
        "velocity_bytes": buffers["velocity"],
        "taps_per_pixel": int(taps),
        "bandwidth_bytes": int(per_pixel * n),
        "samples": 1,
        "shading_events_mean": 1.0,
        "width": int(width),
        "height": int(height),
    }


def run(scene, params: TaaParams | None = None, **kwargs):
    """Run ``taa`` up to the scene's frame; see :func:`raster_models.run`.

    Returns a :class:`raster_models.result.ModelResult` with outputs ``color`` (linear,
    ``(H, W, 3)``), ``current_weight`` (the current frame's blend weight), ``rejected`` (1
    where the history was dropped), ``velocity_x``/``velocity_y`` (the model's velocity
    buffer, pixels to the previous frame, after dilation).
    """
    t0 = time.perf_counter()
    p = params or _params.make(NAME, TaaParams, kwargs)
    r = resolve(p)
    if r["engine"] != "none":
        mod = _engine_module(r["engine"])
        offsets = np.array([mod.jitter(i) for i in range(mod.N_SAMPLES + 1)])
    else:
        offsets = jitter_offsets(r["jitter"], r["samples"] or 1)
    key = _sequence_key(scene, r)
    k = int(scene.frame)
    start, state, outputs = 0, None, None
    if key in _STATES and _STATES[key][0] <= k:
        done, state, outputs = _STATES[key]
        start = done + 1
    rays = 0
    for j in range(start, k + 1):
        if r["engine"] != "none":
            state, outputs = _engine_step(_frame(scene, j), state, r, j)
        else:
            state, outputs = _step(_frame(scene, j), state, r, offsets[j % len(offsets)])
        rays += state["rays"]
    _STATES[key] = (k, state, outputs)
    _STATES.move_to_end(key)
    while len(_STATES) > MAX_SEQUENCES:
        _STATES.popitem(last=False)
    cost = cost_record(r, scene.width, scene.height)
    cost["shadow_rays"] = int(rays)
    diagnostics = {
        "resolved": r,
        "preset_source": PRESET_SOURCES[p.preset],
        "jitter_offsets": offsets.tolist(),
        "frames_run": k + 1 - start,
        "frame": k,
    }
    return model_result(
        NAME,
        scene,
        outputs=dict(outputs),
        cost=cost,
        diagnostics=diagnostics,
        params=_params.as_dict(p),
        t0=t0,
    )
