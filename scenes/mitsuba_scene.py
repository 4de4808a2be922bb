"""What a loaded Mitsuba scene holds for the scene model: its camera (the first sensor,
perspective or orthographic, :func:`camera_from_sensor`) and its usable lights (directional,
point, spot and area lights on a rectangle, disk or sphere, :func:`lights_of`), each refused
with one line (:class:`scenes.loaded.SceneError`) where it cannot be used.
"""

from __future__ import annotations

import math

import numpy as np

from .camera import Camera
from .lights import AREA_SHAPES, Light
from .loaded import SceneError

__all__ = ["camera_from_sensor", "lights_of"]


def camera_from_sensor(mi, sensor, width, height) -> Camera:
    params = mi.traverse(sensor)
    keys = set(params.keys())
    size = [int(c) for c in params["film.size"]]
    w = int(width or size[0])
    h = int(height or size[1])
    to_world = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    near, far = float(params["near_clip"]), float(params["far_clip"])
    if "x_fov" in keys:
        fov = float(np.ravel(params["x_fov"])[0])
        for k in ("principal_point_offset_x", "principal_point_offset_y"):
            if k in keys and abs(float(np.ravel(params[k])[0])) > 0:
                raise SceneError(f"sensor {k} is not supported (must be 0)")
        return Camera("perspective", to_world, w, h, near, far, fov)
    if sensor.class_name() == "OrthographicCamera":
        return Camera("orthographic", to_world, w, h, near, far)
    raise SceneError(
        f"sensor type {sensor.class_name()} is not supported; use a perspective or "
        "orthographic sensor"
    )


def _light_from_emitter(mi, emitter, name: str) -> Light | None:
    kind = emitter.class_name()
    p = mi.traverse(emitter)

    def rgb(key):
        return tuple(float(c) for c in np.broadcast_to(np.array(p[key]).ravel(), (3,)))

    def matrix():
        return np.array(p["to_world"].matrix, dtype=np.float64).reshape(4, 4)

    if kind == "DirectionalEmitter":
        d = matrix()[:3, 2]
        norm = float(np.linalg.norm(d))
        if not (np.isfinite(d).all() and norm > 1e-12):
            raise SceneError(
                f"directional light {name!r} has no direction (got {tuple(d.tolist())}); "
                "give a non-zero direction"
            )
        return Light(
            "directional", rgb("irradiance.value"), tuple(d / np.linalg.norm(d)), name=name
        )
    if kind == "PointLight":
        pos = tuple(float(c) for c in np.array(p["position"]).ravel()[:3])
        return Light("point", rgb("intensity.value"), position=pos, name=name)
    if kind == "SpotLight":
        m = matrix()
        if not (np.isfinite(m).all() and np.linalg.norm(m[:3, 2]) > 1e-12):
            raise SceneError(f"spot light {name!r} has no valid direction (to_world is degenerate)")
        d = m[:3, 2] / np.linalg.norm(m[:3, 2])
        return Light(
            "spot",
            rgb("intensity.value"),
            tuple(d),
            tuple(m[:3, 3]),
            cutoff_angle=float(np.ravel(p["cutoff_angle"])[0]),
            beam_width=float(np.ravel(p["beam_width"])[0]),
            name=name,
        )
    if kind == "AreaLight":
        return _area_light(mi, emitter, rgb("radiance.value"), name)
    return None


#: Largest radiance of an area light per channel: its square stays finite in float32 sums
#: (1e30 gave NaN standard errors).
RADIANCE_MAX = 1e15

#: Relative tolerance of an area light's shape checks (orthogonal axes, round disk, sphere).
_AREA_TOLERANCE = 1e-4


def _area_light(mi, emitter, radiance, name: str) -> Light | None:
    """An area light (:mod:`scenes.lights`) from a Mitsuba ``area`` emitter on a rectangle,
    disk or sphere; None on any other shape (not a usable light, as other emitters);
    :class:`SceneError` for a sheared rectangle, an elliptical disk or a non-uniformly scaled
    sphere."""
    shape = emitter.get_shape()
    name = shape.id() or name  # the shape's id names the light (its emitter has none of its own)
    kind = shape.class_name().lower()
    if kind not in AREA_SHAPES:
        return None
    m = np.array(mi.traverse(shape)["to_world"].matrix, dtype=np.float64).reshape(4, 4)
    u, v, w, centre = m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3]
    lu, lv, lw = (float(np.linalg.norm(a)) for a in (u, v, w))
    tol = _AREA_TOLERANCE * max(lu, lv, 1e-30)
    if not (np.isfinite(m).all() and lu > 0 and lv > 0 and abs(float(u @ v)) <= tol * max(lu, lv)):
        raise SceneError(
            f"area light {name!r}: its {kind}'s to_world must scale and rotate without shear "
            "(orthogonal, non-zero axes)"
        )
    # issue 48: a flattened to_world (scale z = 0) has no normal (np.linalg.inv failed)
    if not lw > 0 or abs(float(np.linalg.det(m[:3, :3]))) <= 1e-9 * lu * lv * lw:
        raise SceneError(
            f"area light {name!r}: its {kind}'s to_world is singular (an axis scaled to zero or "
            "the axes in one plane); give every axis a non-zero scale"
        )
    rgb = np.asarray(radiance, dtype=np.float64)
    if not (np.isfinite(rgb).all() and (rgb >= 0).all() and (rgb <= RADIANCE_MAX).all()):
        raise SceneError(
            f"area light {name!r}: radiance {tuple(float(c) for c in rgb)} must be finite, "
            f"non-negative and at most {RADIANCE_MAX:g} per channel"
        )
    if kind == "sphere":
        if abs(lu - lv) > tol or abs(lu - lw) > tol:
            raise SceneError(f"area light {name!r}: a sphere light must be scaled uniformly")
        r = lu
        return Light(
            "point",
            tuple(float(c) for c in rgb * math.pi * r * r),
            position=tuple(float(c) for c in centre),
            name=name,
            area="sphere",
            radius=r,
            radiance=tuple(float(c) for c in rgb),
        )
    # Mitsuba's planar shapes face the transformed local +Z normal (the inverse transpose)
    n = np.linalg.inv(m[:3, :3]).T @ np.array([0.0, 0.0, 1.0])
    n = n / np.linalg.norm(n)
    if float(np.cross(u, v) @ n) < 0.0:  # a mirroring to_world: keep u x v along the normal
        v = -v
    if kind == "disk" and abs(lu - lv) > tol:
        raise SceneError(f"area light {name!r}: a disk light must be round (equal axes)")
    area = 4.0 * lu * lv if kind == "rectangle" else math.pi * lu * lu
    return Light(
        "point",
        tuple(float(c) for c in rgb * area),
        direction=tuple(float(c) for c in n),
        position=tuple(float(c) for c in centre),
        name=name,
        area=kind,
        axes=(tuple(float(c) for c in u), tuple(float(c) for c in v)),
        radius=lu if kind == "disk" else 0.0,
        radiance=tuple(float(c) for c in rgb),
    )


def _emitter_kind(emitter) -> str:
    """An emitter's class for messages (an area light with its shape's)."""
    shape = emitter.get_shape() if emitter.class_name() == "AreaLight" else None
    return emitter.class_name() + (f" on a {shape.class_name()}" if shape is not None else "")


def lights_of(mi, mi_scene, name: str, gl, light: int) -> list[Light]:
    """The scene's usable lights (glTF: with the KHR_lights_punctual attenuation);
    :class:`SceneError` when there is none or ``light`` is out of range."""
    emitters = mi_scene.emitters()
    lights = []
    for i, e in enumerate(emitters):
        lt = _light_from_emitter(mi, e, e.id() or f"emitter_{i}")
        if lt is not None:
            lights.append(lt)
    if gl is not None:
        lights = gl.lights(lights)
    # area lights after the punctual ones: a scene's punctual lights keep the indices they
    # had before area lights were read
    lights = [lt for lt in lights if not lt.is_area] + [lt for lt in lights if lt.is_area]
    if not lights:
        kinds = ", ".join(_emitter_kind(e) for e in emitters) or "none"
        raise SceneError(
            f"scene {name!r} has no usable light (directional, point, spot or an area light "
            f"on a rectangle, disk or sphere); found: {kinds}"
        )
    if not 0 <= int(light) < len(lights):
        raise SceneError(
            f"light index {light} out of range: scene {name!r} has {len(lights)} usable "
            f"light(s) (0..{len(lights) - 1})"
        )
    return lights
