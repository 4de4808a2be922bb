"""A tiny engine of our own, independent of the oracle: a NumPy z-buffer rasterizer of an
``export`` folder (``meshes/*.ply``, ``camera.json``, ``lights.json``, ``materials.json``).

It renders as a real-time engine would, through none of the oracle's code: the camera's
OpenGL matrices project the triangles, a homogeneous rasterizer (Olano and Greer 1997: 2-D
homogeneous edge functions, so triangles crossing the camera plane need no clipping) tests
4 samples a pixel at the Direct3D standard 4x positions, a depth buffer keeps the nearest
triangle per sample, a shadow map rendered from a directional light (orthographic, the same
rasterizer) gives each sample a depth-compared light visibility, and the colour is the
two-sided diffuse shading of the export's materials, averaged over the samples (4x
supersampling, what an MSAA resolve gives on these flat-shaded scenes). An export of a glTF
scene (``materials.json`` model ``gltf-metallic-roughness``, factors only) is shaded with the
glTF 2.0 Appendix B BRDF (:func:`gltf_brdf`, written here from the specification) plus the
emissive factor; ``samples=n`` takes an n x n grid of samples a pixel instead of the 4x.

Outputs per pixel: ``shadow`` (the lit fraction of the 4 samples; sky counts as lit),
``coverage`` (the fraction of samples that hit a triangle), ``color`` ``(H, W, 3)`` linear
radiance. Everything is vectorised over samples x triangles in bounded chunks.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from plyfile import PlyData

#: Direct3D's standard 4x sample positions in [0, 1)^2 from the pixel's upper-left corner.
SAMPLES_4X = np.array([[0.375, 0.125], [0.875, 0.375], [0.125, 0.625], [0.625, 0.875]])
#: Entries (samples x triangles) per chunk: bounds the rasterizer's memory.
CHUNK = 1 << 21


def gltf_brdf(base, metallic, roughness, n, l, v, *, alpha_of=lambda r: r * r):
    """The glTF 2.0 BRDF (Appendix B.3, the normative ``mix`` form), float64: GGX ``D`` with
    ``alpha = alpha_of(roughness)`` (the specification's ``roughness^2``; a wrong engine
    passes ``lambda r: r``), height-correlated Smith ``V``, Schlick Fresnel, Lambert
    diffuse, dielectric F0 0.04. Vectors ``(N, 3)``; ``base`` ``(N, 3)`` or ``(3,)``;
    ``metallic``, ``roughness`` scalars or ``(N,)``."""
    base = np.broadcast_to(np.asarray(base, dtype=np.float64), np.shape(n))
    h = l + v
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    nl = np.abs(np.sum(n * l, -1))
    nv = np.abs(np.sum(n * v, -1))
    nh = np.sum(n * h, -1)
    vh = np.abs(np.sum(v * h, -1))
    a = alpha_of(np.asarray(roughness, dtype=np.float64))
    a2 = a * a
    d = np.where(nh > 0, a2 / (math.pi * (nh * nh * (a2 - 1) + 1) ** 2), 0.0)
    vis = 1.0 / ((nl + np.sqrt(a2 + (1 - a2) * nl**2)) * (nv + np.sqrt(a2 + (1 - a2) * nv**2)))
    spec = (vis * d)[..., None]
    fw = ((1.0 - vh) ** 5)[..., None]
    f_d = 0.04 + 0.96 * fw
    dielectric = (1 - f_d) * base / math.pi + f_d * spec
    metal = spec * (base + (1 - base) * fw)
    m = np.asarray(metallic, dtype=np.float64)
    m = m[..., None] if m.ndim else m
    return (1 - m) * dielectric + m * metal


def load_export(folder) -> dict:
    """The export's triangles (world space, float64), per-triangle albedo (base colour),
    metallic, roughness and emissive (glTF exports; None otherwise), camera, light."""
    folder = Path(folder)
    materials = json.loads((folder / "materials.json").read_text())
    tris, albedo, pbr = [], [], []
    for shape in materials["shapes"].values():
        ply = PlyData.read(str(folder / shape["file"]))
        v = np.stack([ply["vertex"][c] for c in "xyz"], -1).astype(np.float64)
        faces = np.stack(ply["face"]["vertex_indices"]).astype(np.int64)
        tris.append(v[faces])
        albedo.append(np.repeat([shape["albedo"]], len(faces), axis=0))
        if "pbr" in shape:
            m = shape["pbr"]
            row = [m["metallic_factor"], m["roughness_factor"], *m["emissive"]]
            pbr.append(np.repeat([row], len(faces), axis=0))
    lights = json.loads((folder / "lights.json").read_text())
    return {
        "triangles": np.concatenate(tris),
        "albedo": np.concatenate(albedo).astype(np.float64),
        "pbr": np.concatenate(pbr).astype(np.float64) if pbr else None,
        "camera": json.loads((folder / "camera.json").read_text()),
        "light": lights["lights"][lights["chosen"]],
    }


def rasterize(clip_tris: np.ndarray, ndc: np.ndarray, *, near_w: float = 0.0, depth=None):
    """Nearest triangle and its perspective-correct barycentrics at each sample.

    Parameters
    ----------
    clip_tris : ``(T, 3, 3)`` the triangles' clip-space ``(x, y, w)`` per vertex.
    ndc : ``(S, 2)`` sample positions in NDC.
    near_w : samples at ``w <= near_w`` are clipped (the near plane).
    depth : ``(T, 3)`` per-vertex depth the depth test compares (default: ``w``, the view
        depth of a perspective camera; an orthographic light passes its own depth).

    Returns ``(index (S,) int, -1 where none; lam (S, 3); depth (S,), inf where none)``.
    """
    m = np.transpose(clip_tris, (0, 2, 1))  # columns are the vertices
    det = np.linalg.det(m)
    ok = np.abs(det) > 1e-12
    inv = np.zeros_like(m)
    inv[ok] = np.linalg.inv(m[ok])
    n_s = len(ndc)
    best = np.full(n_s, -1, dtype=np.int64)
    best_w = np.full(n_s, np.inf)
    best_lam = np.zeros((n_s, 3))
    p = np.concatenate([ndc, np.ones((n_s, 1))], axis=1)
    step = max(1, CHUNK // max(len(m), 1))
    for lo in range(0, n_s, step):
        b = np.einsum("tij,sj->sti", inv, p[lo : lo + step])  # (s, T, 3) homogeneous weights
        total = b.sum(-1)
        inside = (b >= 0).all(-1) & (total > 0) & ok[None, :]
        w = np.where(inside, 1.0 / np.where(inside, total, 1.0), 0.0)
        inside &= w > near_w
        lam = b * w[..., None]  # perspective-correct barycentrics
        z = w if depth is None else np.einsum("sti,ti->st", lam, depth)
        z = np.where(inside, z, np.inf)
        t = np.argmin(z, axis=1)
        rows = np.arange(len(t))
        hit = np.isfinite(z[rows, t])
        best[lo : lo + step] = np.where(hit, t, -1)
        best_w[lo : lo + step] = z[rows, t]
        best_lam[lo : lo + step] = np.where(hit[:, None], lam[rows, t], 0.0)
    return best, best_lam, best_w


def _pixel_samples(width: int, height: int, pattern: np.ndarray = SAMPLES_4X) -> np.ndarray:
    """``(H * W * S, 2)`` sample positions in pixels (x right, y down), pixel-major."""
    y, x = np.mgrid[0:height, 0:width]
    base = np.stack([x, y], -1).reshape(-1, 1, 2).astype(np.float64)
    return (base + pattern[None]).reshape(-1, 2)


def grid_pattern(n: int) -> np.ndarray:
    """An ``n x n`` grid of sample positions in the pixel (cell centres)."""
    c = (np.arange(n) + 0.5) / n
    return np.stack(np.meshgrid(c, c), -1).reshape(-1, 2)


def shadow_map(tris: np.ndarray, to_light: np.ndarray, *, size: int):
    """An orthographic depth map of ``tris`` seen from a directional light; returns a
    function ``depth_of(points) -> (map depth, point depth)`` along the light's direction."""
    fwd = -to_light
    helper = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = np.cross(fwd, helper)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    basis = np.stack([right, up, fwd])
    ls = tris @ basis.T  # (T, 3, 3): light-space x, y, depth
    lo, hi = ls[..., :2].reshape(-1, 2).min(0), ls[..., :2].reshape(-1, 2).max(0)
    scale = (hi - lo) * (1 + 1e-6)

    def to_ndc(xy):
        return 2.0 * (xy - lo) / scale - 1.0

    clip = np.concatenate([to_ndc(ls[..., :2]), np.ones(ls.shape[:2] + (1,))], -1)
    centres = (np.stack(np.mgrid[0:size, 0:size][::-1], -1).reshape(-1, 2) + 0.5) / size
    _, _, depth = rasterize(clip, centres * 2.0 - 1.0, depth=ls[..., 2])
    depth = depth.reshape(size, size)

    def depth_of(points):
        q = points @ basis.T
        uv = (to_ndc(q[:, :2]) + 1.0) * 0.5 * size
        ij = np.clip(np.floor(uv).astype(np.int64), 0, size - 1)
        return depth[ij[:, 1], ij[:, 0]], q[:, 2]

    return depth_of


def light_box_map(tris: np.ndarray, direction, *, size: int, depth_bias: float = 0.005):
    """A shadow map as a D3D engine with a scene-fit orthographic light builds it: a LookAt
    frame along the light's travel ``direction`` with world +Y up (x = up x forward, y =
    forward x x), the light-space box of the 8 corners of the scene's world AABB (padded by
    1e-4 of its size), D3D depth in [0, 1] over the box, ``size`` x ``size`` texels rasterized
    at their centres (empty texels at depth 1). Returns ``lookup(points, pcf, offset)``:
    each point's visibility with ``pcf`` x ``pcf`` bilinear comparison taps one texel apart
    centred on it (D3D ``SampleCmp``, reference ``depth - depth_bias <= stored``, addresses
    clamped), every tap moved by ``offset`` texels (a renderer that reads its map one texel
    over passes ``(1, 1)``)."""
    f = np.asarray(direction, dtype=np.float64)
    f = f / np.linalg.norm(f)
    x = np.cross([0.0, 1.0, 0.0], f)
    x /= np.linalg.norm(x)
    basis = np.stack([x, np.cross(f, x), f])
    flat = tris.reshape(-1, 3)
    lo, hi = flat.min(0), flat.max(0)
    corners = np.array(
        [[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])]
    )
    lc = corners @ basis.T
    bmin, bmax = lc.min(0), lc.max(0)
    pad = 1e-4 * np.maximum(bmax - bmin, 1e-9)
    bmin, bmax = bmin - pad, bmax + pad
    ls = tris @ basis.T
    uv = (ls[..., :2] - bmin[:2]) / (bmax[:2] - bmin[:2])
    depth = (ls[..., 2] - bmin[2]) / (bmax[2] - bmin[2])
    clip = np.concatenate([uv * 2.0 - 1.0, np.ones(uv.shape[:2] + (1,))], -1)
    centres = (np.stack(np.mgrid[0:size, 0:size][::-1], -1).reshape(-1, 2) + 0.5) / size
    _, _, stored = rasterize(clip, centres * 2.0 - 1.0, depth=depth)
    stored = np.where(np.isfinite(stored), stored, 1.0).reshape(size, size)

    def lookup(points, pcf: int = 1, offset=(0.0, 0.0)):
        q = points @ basis.T
        u = (q[:, 0] - bmin[0]) / (bmax[0] - bmin[0]) * size
        v = (q[:, 1] - bmin[1]) / (bmax[1] - bmin[1]) * size
        ref = np.clip((q[:, 2] - bmin[2]) / (bmax[2] - bmin[2]), 0.0, 1.0) - depth_bias
        taps = np.arange(pcf) - (pcf - 1) / 2.0
        acc = np.zeros(len(points))
        for ty in taps:
            for tx in taps:
                su = u + tx + offset[0] - 0.5
                sv = v + ty + offset[1] - 0.5
                i0, j0 = np.floor(su).astype(np.int64), np.floor(sv).astype(np.int64)
                fu, fv = su - i0, sv - j0
                for di, dj, w in (
                    (0, 0, (1 - fu) * (1 - fv)),
                    (1, 0, fu * (1 - fv)),
                    (0, 1, (1 - fu) * fv),
                    (1, 1, fu * fv),
                ):
                    i = np.clip(i0 + di, 0, size - 1)
                    j = np.clip(j0 + dj, 0, size - 1)
                    acc += w * (ref <= stored[j, i])
        return acc / float(pcf * pcf)

    return lookup


def render(
    folder,
    *,
    shadow_map_size: int = 1024,
    bias: float = 0.05,
    samples: int | None = None,
    alpha_of=lambda r: r * r,
    pcf: int | None = None,
    pcf_offset=(0.0, 0.0),
    diffuse: str = "lambert",
    color_scale: float = 1.0,
    depth_bias: float = 0.005,
) -> dict:
    """Render an export folder: ``shadow`` and ``coverage`` ``(H, W)``, ``color``
    ``(H, W, 3)``, all float32 (see the module docstring). ``samples``: an n x n grid a
    pixel (default the 4x pattern); ``alpha_of``: the glTF roughness remapping.

    The faults of a real renderer (pyrender on Mesa, issue 37), each a keyword: ``pcf``
    (an n x n bilinear PCF on a scene-fit D3D shadow map, :func:`light_box_map`, instead of
    the nearest texel with a world-space ``bias``) with ``pcf_offset`` texels (``(1, 1)``:
    the map read one texel over) and its ``depth_bias`` (D3D depth units);
    ``diffuse="fresnel"``: the diffuse weighted by ``1 - F(v.h)`` (Schlick, F0 0.04, as
    metallic-roughness shaders do) instead of Lambert;
    ``color_scale``: every radiance times it (``math.pi``: a BRDF without its 1/pi)."""
    scene = load_export(folder)
    cam, light = scene["camera"], scene["light"]
    if light["kind"] != "directional":
        raise ValueError("this engine renders directional lights only")
    width, height = cam["width"], cam["height"]
    tris, albedo = scene["triangles"], scene["albedo"]
    view = np.asarray(cam["opengl"]["world_to_view"])
    proj = np.asarray(cam["opengl"]["projection"])
    hom = np.concatenate([tris, np.ones(tris.shape[:2] + (1,))], -1)
    clip = hom @ (proj @ view).T  # (T, 3, 4)
    pattern = SAMPLES_4X if samples is None else grid_pattern(samples)
    px = _pixel_samples(width, height, pattern)
    ndc = np.stack([2.0 * px[:, 0] / width - 1.0, 1.0 - 2.0 * px[:, 1] / height], -1)
    idx, lam, _ = rasterize(clip[..., [0, 1, 3]], ndc, near_w=cam["near"])
    hit = idx >= 0
    t = np.maximum(idx, 0)
    pos = np.einsum("si,sij->sj", lam, tris[t])
    normal = np.cross(tris[t, 1] - tris[t, 0], tris[t, 2] - tris[t, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-30)
    to_eye = np.asarray(cam["position"])[None] - pos
    normal *= np.where(np.einsum("sj,sj->s", normal, to_eye) < 0, -1.0, 1.0)[:, None]
    direction = np.asarray(light["direction"], dtype=np.float64)
    to_light = -direction / np.linalg.norm(direction)
    cos_l = normal @ to_light
    if pcf is None:
        depth_of = shadow_map(tris, to_light, size=shadow_map_size)
        map_depth, own_depth = depth_of(pos)
        lit = ((own_depth <= map_depth + bias) & (cos_l > 0)).astype(np.float64)
    else:
        lookup = light_box_map(tris, direction, size=shadow_map_size, depth_bias=depth_bias)
        lit = lookup(pos, pcf, pcf_offset) * (cos_l > 0)
    vis = np.where(hit, lit, 1.0).astype(np.float64)
    irradiance = np.asarray(light["color"])[None] * (np.maximum(cos_l, 0) * vis)[:, None]
    if scene["pbr"] is None:
        rgb = albedo[t] / math.pi * irradiance
        if diffuse == "fresnel":
            to_eye_u = to_eye / np.linalg.norm(to_eye, axis=-1, keepdims=True)
            h = to_eye_u + to_light
            h /= np.linalg.norm(h, axis=-1, keepdims=True)
            vh = np.clip(np.sum(to_eye_u * h, -1), 0.0, 1.0)
            rgb = rgb * (1.0 - (0.04 + 0.96 * (1.0 - vh) ** 5))[:, None]
    else:
        m = scene["pbr"][t]
        to_eye_u = to_eye / np.linalg.norm(to_eye, axis=-1, keepdims=True)
        lv = np.broadcast_to(to_light, normal.shape)
        f = gltf_brdf(albedo[t], m[:, 0], m[:, 1], normal, lv, to_eye_u, alpha_of=alpha_of)
        rgb = f * irradiance + m[:, 2:5]
    rgb = np.where(hit[:, None], rgb, 0.0) * color_scale
    n = len(pattern)
    return {
        "shadow": vis.reshape(height, width, n).mean(-1).astype(np.float32),
        "coverage": hit.reshape(height, width, n).mean(-1).astype(np.float32),
        "color": rgb.reshape(height, width, n, 3).mean(2).astype(np.float32),
    }


def write_engine_exr(path, images: dict) -> None:
    """Engine-style layered EXR with OpenEXR (as an engine's exporter writes it): layers
    ``shadow.Y``, ``msaa.R/G/B`` and ``msaa.coverage``, and with ``images["velocity"]``
    (``(H, W, 2)``) its velocity buffer ``velocity.X/Y``."""
    import OpenEXR

    channels = {
        "shadow.Y": images["shadow"],
        "msaa.R": images["color"][..., 0],
        "msaa.G": images["color"][..., 1],
        "msaa.B": images["color"][..., 2],
        "msaa.coverage": images["coverage"],
    }
    if "velocity" in images:
        channels["velocity.X"] = images["velocity"][..., 0]
        channels["velocity.Y"] = images["velocity"][..., 1]
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    chans = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    with OpenEXR.File(header, chans) as f:
        f.write(str(path))


def write_rgb_png(path, color: np.ndarray, *, gamma: float | None = None) -> None:
    """An 8-bit RGB PNG of linear ``color``: sRGB-encoded, or with a pure ``gamma`` power
    (pyrender and many GL samples write ``x ** (1 / 2.2)``)."""
    from PIL import Image

    c = np.clip(np.asarray(color, dtype=np.float64), 0.0, 1.0)
    if gamma is None:
        enc = np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)
    else:
        enc = c ** (1.0 / gamma)
    Image.fromarray(np.round(enc * 255).astype(np.uint8), mode="RGB").save(path)


def write_grey_png(path, image: np.ndarray) -> None:
    """An 8-bit grey PNG of ``image`` in [0, 1] (an engine's shadow mask)."""
    from PIL import Image

    Image.fromarray(np.round(np.clip(image, 0, 1) * 255).astype(np.uint8), mode="L").save(path)


def velocity(folder, previous_camera: dict) -> np.ndarray:
    """The engine's velocity buffer: ``(H, W, 2)`` float64, at each pixel centre the film
    position (pixels, y down) in the previous frame of the surface the centre sees, minus the
    centre, as an engine computes it from its depth buffer: the point reconstructed from the
    rasterized triangle (a sky pixel: the pixel's ray at the far plane) and projected with
    ``previous_camera`` (an export's ``camera.json`` record) by its OpenGL matrices."""
    scene = load_export(folder)
    cam, tris = scene["camera"], scene["triangles"]
    width, height = cam["width"], cam["height"]
    view_proj = np.asarray(cam["opengl"]["projection"]) @ np.asarray(cam["opengl"]["world_to_view"])
    hom = np.concatenate([tris, np.ones(tris.shape[:2] + (1,))], -1)
    clip = hom @ view_proj.T
    y, x = np.mgrid[0:height, 0:width].reshape(2, -1) + 0.5
    ndc = np.stack([2.0 * x / width - 1.0, 1.0 - 2.0 * y / height], -1)
    idx, lam, _ = rasterize(clip[..., [0, 1, 3]], ndc, near_w=cam["near"])
    pos = np.einsum("si,sij->sj", lam, tris[np.maximum(idx, 0)])
    far = np.concatenate([ndc, np.ones((len(ndc), 2))], -1) @ np.linalg.inv(view_proj).T
    pos = np.where((idx >= 0)[:, None], pos, far[:, :3] / far[:, 3:4])
    prev_vp = np.asarray(previous_camera["opengl"]["projection"]) @ np.asarray(
        previous_camera["opengl"]["world_to_view"]
    )
    p = np.concatenate([pos, np.ones((len(pos), 1))], -1) @ prev_vp.T
    px = (p[:, 0] / p[:, 3] + 1.0) / 2.0 * width
    py = (1.0 - p[:, 1] / p[:, 3]) / 2.0 * height
    return np.stack([px - x, py - y], -1).reshape(height, width, 2)
