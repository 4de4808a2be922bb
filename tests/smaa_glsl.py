"""The published SMAA shader run on the CPU's OpenGL: iryoku/smaa's ``SMAA.hlsl`` compiled
as GLSL 3.30 (``SMAA_GLSL_3``) by Mesa's llvmpipe through moderngl (a headless EGL context),
its passes wrapped as the demo wraps them (``Demo/DX10/Shaders/SMAA.fx``: the offsets come
from the ``*VS`` functions in the vertex shader and are interpolated; a full-screen
triangle; every sampler linear and clamped; the edges target R8G8, the blend target
R8G8B8A8; both cleared to 0 before their pass, so discarded pixels keep 0).

Textures are uploaded row 0 first and read back the same way: GL's texture coordinate
``t`` then grows with the row index exactly like Direct3D's ``v``, so ``SMAA_RT_METRICS``
offsets of -1 in y still mean "the row above".

Used by ``tests/test_smaa_glsl.py`` only: an independent run of the published code to hold
the ``smaa`` model against. The shader is third-party code and is not in this repository:
point ``RASTER_ORACLE_SMAA_HLSL`` at ``SMAA.hlsl`` of iryoku/smaa at commit 71c806a (checked
by its SHA-256 below). :func:`unavailable` says why it cannot run (no shader, no moderngl, no
EGL).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

#: The published shader: a local copy named by the environment (never committed here).
SHADER = Path(os.environ.get("RASTER_ORACLE_SMAA_HLSL", "SMAA.hlsl"))
#: SHA-256 of iryoku/smaa's SMAA.hlsl at commit 71c806a838bdd7d517df19192a20f0c61b3ca29d.
SHADER_SHA256 = "4db53d92ef0b45661f8450303589ffabce93c352cae4282a6f32dd2b80efbeb9"

# full-screen triangle (the header's advice: no quad, no overshading on the diagonal)
_TRIANGLE = np.array([-1.0, -1.0, 3.0, -1.0, -1.0, 3.0], np.float32)

_VS = {
    "edges": (
        "out vec4 offset[3];",
        "SMAAEdgeDetectionVS(texcoord, offset);",
    ),
    "weights": (
        "out vec2 pixcoord; out vec4 offset[3];",
        "SMAABlendingWeightCalculationVS(texcoord, pixcoord, offset);",
    ),
    "blend": ("out vec4 offset;", "SMAANeighborhoodBlendingVS(texcoord, offset);"),
    "resolve": ("", ""),
}
_FS = {
    "edges": (
        "in vec4 offset[3]; uniform sampler2D colorTex;{pred}",
        "fragColor = vec4({fn}(texcoord, offset, colorTex{pred_arg}), 0.0, 0.0);",
    ),
    "depth": (
        "in vec4 offset[3]; uniform sampler2D depthTex;",
        "fragColor = vec4(SMAADepthEdgeDetectionPS(texcoord, offset, depthTex), 0.0, 0.0);",
    ),
    "weights": (
        "in vec2 pixcoord; in vec4 offset[3]; uniform sampler2D edgesTex; "
        "uniform sampler2D areaTex; uniform sampler2D searchTex; uniform vec4 subsampleIndices;",
        "fragColor = SMAABlendingWeightCalculationPS(texcoord, pixcoord, offset, edgesTex, "
        "areaTex, searchTex, subsampleIndices);",
    ),
    "ends": (
        "in vec2 pixcoord; in vec4 offset[3]; uniform sampler2D edgesTex; "
        "uniform sampler2D searchTex;",
        "fragColor = vec4("
        "SMAASearchXLeft(edgesTex, searchTex, offset[0].xy, offset[2].x) * SMAA_RT_METRICS.z,"
        "SMAASearchXRight(edgesTex, searchTex, offset[0].zw, offset[2].y) * SMAA_RT_METRICS.z,"
        "SMAASearchYUp(edgesTex, searchTex, offset[1].xy, offset[2].z) * SMAA_RT_METRICS.w,"
        "SMAASearchYDown(edgesTex, searchTex, offset[1].zw, offset[2].w) * SMAA_RT_METRICS.w)"
        " - pixcoord.xxyy;",
    ),
    "blend": (
        "in vec4 offset; uniform sampler2D colorTex; uniform sampler2D blendTex; "
        "uniform sampler2D velocityTex;",
        "fragColor = SMAANeighborhoodBlendingPS(texcoord, offset, colorTex, blendTex, "
        "velocityTex);",
    ),
    "resolve": (
        "uniform sampler2D currentColorTex; uniform sampler2D previousColorTex; "
        "uniform sampler2D velocityTex;",
        "fragColor = SMAAResolvePS(texcoord, currentColorTex, previousColorTex, velocityTex);",
    ),
}
# GL_SRGB8_ALPHA8 and GL_FRAMEBUFFER_SRGB: the demo's R8G8B8A8_UNORM_SRGB views
_SRGB8_ALPHA8 = 0x8C43
_FRAMEBUFFER_SRGB = 0x8DB9


def _float_sampler() -> None:
    """llvmpipe's default ("AoS") path filters 8-bit textures in 8-bit fixed point: the
    filtered value comes back rounded to 1/255 (a bilinear fetch of edges 0 and 1 at a
    quarter texel gives 191/255, not 0.75), which GPUs do not do and which moves SMAA's
    corner-rounding factors; its "SoA" path filters in float. Read when the driver loads,
    so set before the first context."""
    flags = [f for f in os.environ.get("GALLIVM_PERF", "").split(",") if f]
    if "no_aos_sampling" not in flags:
        os.environ["GALLIVM_PERF"] = ",".join([*flags, "no_aos_sampling"])


def unavailable() -> str | None:
    """None when the published shader can run here, else the reason."""
    if "RASTER_ORACLE_SMAA_HLSL" not in os.environ or not SHADER.is_file():
        return (
            "set RASTER_ORACLE_SMAA_HLSL to a copy of iryoku/smaa's SMAA.hlsl at 71c806a "
            "(third-party code, not in this repository)"
        )
    if hashlib.sha256(SHADER.read_bytes()).hexdigest() != SHADER_SHA256:
        return f"{SHADER} is not iryoku/smaa's SMAA.hlsl at 71c806a (SHA-256 differs)"
    _float_sampler()
    try:
        import moderngl
    except ImportError:
        return "moderngl is not installed (pip install moderngl)"
    try:
        ctx = moderngl.create_standalone_context(backend="egl")
    except Exception as exc:  # noqa: BLE001 - any EGL failure means: not here
        return f"no headless OpenGL context (EGL, Mesa): {exc}"
    ctx.release()
    return None


def _source() -> str:
    raw = SHADER.read_bytes()
    if hashlib.sha256(raw).hexdigest() != SHADER_SHA256:
        raise RuntimeError(f"{SHADER} is not the published SMAA.hlsl")
    # two bytes of the header's ASCII-art comment are not ASCII; GLSL wants ASCII
    return "".join(c if ord(c) < 128 else " " for c in raw.decode("latin-1"))


class SmaaGL:
    """The published passes at ``width`` x ``height`` with ``defines`` (name -> value,
    e.g. ``{"SMAA_PRESET_HIGH": ""}`` or ``{"SMAA_THRESHOLD": "0.1"}``)."""

    def __init__(self, width: int, height: int, defines: dict | None = None):
        import moderngl

        _float_sampler()
        self.mgl = moderngl
        self.ctx = moderngl.create_standalone_context(backend="egl")
        # moderngl resolves #include lines itself, even the one in the header's comment
        self.ctx.includes["SMAA.h"] = ""
        self.w, self.h = int(width), int(height)
        self.defines = dict(defines or {})
        self.vbo = self.ctx.buffer(_TRIANGLE.tobytes())
        self.src = _source()

    def release(self) -> None:
        self.ctx.release()

    def _header(self, stage: str) -> str:
        lines = [
            "#version 330",
            "#define SMAA_GLSL_3",
            f"#define SMAA_RT_METRICS vec4(1.0 / {self.w}.0, 1.0 / {self.h}.0, "
            f"{self.w}.0, {self.h}.0)",
            f"#define SMAA_INCLUDE_VS {1 if stage == 'vs' else 0}",
            f"#define SMAA_INCLUDE_PS {1 if stage == 'fs' else 0}",
        ]
        lines += [f"#define {k} {v}".rstrip() for k, v in self.defines.items()]
        return "\n".join(lines) + "\n" + self.src + "\n"

    def _program(self, vs_kind: str, fs_kind: str, fs_format: dict):
        vs_decl, vs_call = _VS[vs_kind]
        fs_decl, fs_call = _FS[fs_kind]
        vs = (
            self._header("vs")
            + f"in vec2 in_pos; out vec2 texcoord; {vs_decl}\n"
            + "void main() { texcoord = in_pos * 0.5 + 0.5; "
            + f"{vs_call} gl_Position = vec4(in_pos, 0.0, 1.0); }}\n"
        )
        fs = (
            self._header("fs")
            + f"in vec2 texcoord; out vec4 fragColor; {fs_decl.format(**fs_format)}\n"
            + f"void main() {{ {fs_call.format(**fs_format)} }}\n"
        )
        return self.ctx.program(vertex_shader=vs, fragment_shader=fs)

    def _texture(self, data: np.ndarray, *, components: int, dtype: str = "f1", srgb=False):
        h, w = data.shape[:2]
        fmt = {"internal_format": _SRGB8_ALPHA8} if srgb else {}
        raw = np.ascontiguousarray(data).tobytes()
        tex = self.ctx.texture((w, h), components, raw, dtype=dtype, **fmt)
        tex.filter = (self.mgl.LINEAR, self.mgl.LINEAR)
        tex.repeat_x = tex.repeat_y = False  # clamp to edge
        return tex

    def _run(self, prog, textures: dict, components: int, srgb=False, dtype="f1") -> np.ndarray:
        fmt = {"internal_format": _SRGB8_ALPHA8} if srgb else {}
        target = self.ctx.texture((self.w, self.h), components, dtype=dtype, **fmt)
        fbo = self.ctx.framebuffer(color_attachments=[target])
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        if srgb:  # writes to the sRGB target are encoded (the demo's sRGB render targets)
            self.ctx.enable_direct(_FRAMEBUFFER_SRGB)
        for unit, (name, tex) in enumerate(textures.items()):
            tex.use(unit)
            prog[name].value = unit
        vao = self.ctx.vertex_array(prog, [(self.vbo, "2f", "in_pos")])
        vao.render(self.mgl.TRIANGLES, vertices=3)
        if srgb:
            self.ctx.disable_direct(_FRAMEBUFFER_SRGB)
        raw = fbo.read(components=components, dtype=dtype)
        data = np.frombuffer(raw, np.uint8 if dtype == "f1" else np.float32)
        for obj in (vao, fbo, target, *textures.values()):
            obj.release()
        return data.reshape(self.h, self.w, components).copy()

    def edges(self, color8: np.ndarray, *, method: str = "luma", predication=None) -> np.ndarray:
        """``SMAALumaEdgeDetectionPS`` / ``SMAAColorEdgeDetectionPS`` on an (H, W, 3) uint8
        colour buffer read through its UNORM view; ``predication``: (H, W) float32 depth
        (``SMAA_PREDICATION 1``). Returns the R8G8 target, (H, W, 2) uint8."""
        fn = "SMAALumaEdgeDetectionPS" if method == "luma" else "SMAAColorEdgeDetectionPS"
        rgba = np.concatenate([color8, np.full(color8.shape[:2] + (1,), 255, np.uint8)], -1)
        textures = {"colorTex": self._texture(rgba, components=4)}
        fmt = {"fn": fn, "pred": "", "pred_arg": ""}
        if predication is not None:
            fmt.update(pred=" uniform sampler2D predTex;", pred_arg=", predTex")
            depth = np.asarray(predication, np.float32)
            textures["predTex"] = self._texture(depth, components=1, dtype="f4")
        prog = self._program("edges", "edges", fmt)
        return self._run(prog, textures, 4)[..., :2]

    def depth_edges(self, depth: np.ndarray) -> np.ndarray:
        """``SMAADepthEdgeDetectionPS`` on an (H, W) float32 depth buffer: (H, W, 2) uint8."""
        tex = self._texture(np.asarray(depth, np.float32), components=1, dtype="f4")
        prog = self._program("edges", "depth", {})
        return self._run(prog, {"depthTex": tex}, 4)[..., :2]

    def weights(self, edges8: np.ndarray, area8, search8, subsample=(0, 0, 0, 0)) -> np.ndarray:
        """``SMAABlendingWeightCalculationPS`` on an (H, W, 2) uint8 edges texture with the
        area (560, 160, 2) and search (16, 64) textures: (H, W, 4) uint8."""
        textures = {
            "edgesTex": self._texture(edges8, components=2),
            "areaTex": self._texture(area8, components=2),
            "searchTex": self._texture(search8, components=1),
        }
        prog = self._program("weights", "weights", {})
        prog["subsampleIndices"].value = tuple(float(s) for s in subsample)
        return self._run(prog, textures, 4)

    def search_ends(self, edges8: np.ndarray, search8: np.ndarray) -> np.ndarray:
        """The four orthogonal searches of the blending weight pass (``SMAASearchXLeft``,
        ``XRight``, ``YUp``, ``YDown`` with the pass's own offsets) at every pixel, as
        distances in pixels from the pixel's centre (before the pass rounds them): (H, W, 4)
        float32."""
        textures = {
            "edgesTex": self._texture(edges8, components=2),
            "searchTex": self._texture(search8, components=1),
        }
        prog = self._program("weights", "ends", {})
        return self._run(prog, textures, 4, dtype="f4")

    def blend(self, color8, weights8, velocity, *, srgb: bool = True) -> np.ndarray:
        """``SMAANeighborhoodBlendingPS`` (``SMAA_REPROJECTION 1`` for the velocity, as the
        demo's T2x) on an (H, W, 3) uint8 colour buffer read through its sRGB view, the
        (H, W, 4) uint8 blend texture and an (H, W, 2) float velocity (texture units, stored
        RG16F), written to an sRGB RGBA8 target: (H, W, 4) uint8 (alpha: packed velocity);
        ``srgb=False``: UNORM views and target (blending in gamma space)."""
        rgba = np.concatenate([color8, np.full(color8.shape[:2] + (1,), 255, np.uint8)], -1)
        textures = {
            "colorTex": self._texture(rgba, components=4, srgb=srgb),
            "blendTex": self._texture(weights8, components=4),
            "velocityTex": self._texture(np.asarray(velocity, np.float16), components=2,
                                         dtype="f2"),
        }  # fmt: skip
        prog = self._program("blend", "blend", {})
        return self._run(prog, textures, 4, srgb=srgb)

    def resolve(self, current8: np.ndarray, previous8: np.ndarray, velocity) -> np.ndarray:
        """``SMAAResolvePS`` (``SMAA_REPROJECTION 1``) on two (H, W, 4) uint8 frames read
        through sRGB views (the demo's ``previousRT``: ``R8G8B8A8_UNORM_SRGB``; alpha, the
        packed velocity, is linear) and the (H, W, 2) velocity, written to an sRGB target."""
        textures = {
            "currentColorTex": self._texture(current8, components=4, srgb=True),
            "previousColorTex": self._texture(previous8, components=4, srgb=True),
            "velocityTex": self._texture(np.asarray(velocity, np.float16), components=2,
                                         dtype="f2"),
        }  # fmt: skip
        for tex in textures.values():  # SMAASamplePoint: the HLSL port's PointSampler
            tex.filter = (self.mgl.NEAREST, self.mgl.NEAREST)
        prog = self._program("resolve", "resolve", {})
        return self._run(prog, textures, 4, srgb=True)
