"""Scene dictionaries to Mitsuba, and what a scene's content hash is made of.

:func:`to_mitsuba_dict` turns the project's scene dictionaries (``ro_mesh`` entries:
vertices, faces and optional normals, ``TEXCOORD_0`` and tangents; 4 x 4 matrices) into
Mitsuba meshes and transforms; :func:`hash_obj` hashes such a dictionary deterministically;
:func:`xml_dependencies` lists a Mitsuba XML file and every file it references, as Mitsuba
resolves them.
"""

from __future__ import annotations

import re
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from .base.untrusted import LIMITS, UntrustedError, read_bounded
from .shading.alpha import ALPHA_ATTRIBUTE

__all__ = ["hash_obj", "to_mitsuba_dict", "xml_dependencies"]


def hash_obj(h, obj) -> None:
    if isinstance(obj, dict):
        for k in sorted(obj):
            h.update(f"<{k}>".encode())
            hash_obj(h, obj[k])
    elif isinstance(obj, list | tuple):
        for v in obj:
            hash_obj(h, v)
    elif isinstance(obj, np.ndarray):
        h.update(str(obj.dtype).encode() + str(obj.shape).encode())
        h.update(np.ascontiguousarray(obj).tobytes())
    else:
        h.update(repr(obj).encode())


def to_mitsuba_dict(mi, d: dict, meshes: dict) -> dict:
    """Replace ``ro_mesh`` entries by Mitsuba meshes and matrices by transforms."""
    out = {}
    for key, value in d.items():
        if isinstance(value, dict) and value.get("type") == "ro_mesh":
            v = np.asarray(value["vertices"], dtype=np.float32)
            f = np.asarray(value["faces"], dtype=np.uint32)
            # optional per-vertex data (glTF meshes, scenes.formats.gltf): normals, uv, tangents
            nrm, uv, tan = (value.get(k) for k in ("normals", "texcoords", "tangents"))
            mesh = mi.Mesh(
                key,
                vertex_count=len(v),
                face_count=len(f),
                has_vertex_normals=nrm is not None,
                has_vertex_texcoords=uv is not None,
            )
            params = mi.traverse(mesh)
            params["vertex_positions"] = mi.Float(v.ravel())
            params["faces"] = mi.UInt32(f.ravel())
            if nrm is not None:
                params["vertex_normals"] = mi.Float(np.asarray(nrm, np.float32).ravel())
            if uv is not None:
                params["vertex_texcoords"] = mi.Float(np.asarray(uv, np.float32).ravel())
            if tan is not None:
                tan = np.asarray(tan, np.float32)
                mesh.add_attribute("vertex_tangent", 3, mi.Float(tan[:, :3].ravel()))
                mesh.add_attribute("vertex_tangent_w", 1, mi.Float(tan[:, 3].ravel()))
            if value.get("vertex_alpha") is not None:  # COLOR_0's alpha (MASK materials)
                va = np.asarray(value["vertex_alpha"], np.float32).ravel()
                mesh.add_attribute(ALPHA_ATTRIBUTE, 1, mi.Float(va))
            params.update()
            bsdf = mi.load_dict(value["bsdf"])
            mesh.set_bsdf(bsdf)
            meshes[key] = (v, f)
            out[key] = mesh
        elif isinstance(value, dict):
            out[key] = to_mitsuba_dict(mi, value, meshes)
        elif isinstance(value, np.ndarray) and value.shape == (4, 4):
            out[key] = mi.ScalarTransform4f(value.tolist())
        else:
            out[key] = value
    return out


_PARAM = re.compile(r"\$(\w+)")


def xml_dependencies(
    path: Path,
    seen: set | None = None,
    *,
    root: Path | None = None,
    params: dict | None = None,
    error=None,
) -> list[Path]:
    """The XML file and every file it references, recursively, as Mitsuba resolves them.

    The XML is parsed (any quoting or attribute order); ``$name`` references are replaced by
    the ``<default name=... value=...>`` values (included files see the includer's defaults);
    references are the ``filename`` attribute of any element (``<include>``, spectra) and the
    ``value`` of every ``<string>`` property (``filename`` of meshes and bitmaps, ...), resolved
    against the referencing file's folder and then the scene's folder. Only existing files count:
    a missing one makes Mitsuba's own load fail.

    Issue 48: every file is read only inside the scene's folder (links resolved): a reference
    to an existing file outside it (an absolute path, ``..``, a link out) is refused with one
    line (``error``, default :class:`scenes.base.untrusted.UntrustedError`), and each XML file
    is read bounded (``LIMITS["scene_bytes"]``).
    """
    seen = set() if seen is None else seen
    path = path.resolve()
    root = path.parent if root is None else root
    params = {} if params is None else params
    if path in seen:
        return []
    seen.add(path)
    files = [path]
    text = read_bounded(path, limit=LIMITS["scene_bytes"], what="scene file", error=error)
    try:
        elements = list(ElementTree.fromstring(text).iter())
    except ElementTree.ParseError:
        return files  # Mitsuba's own load reports the error
    for el in elements:
        if el.tag == "default" and "name" in el.attrib and "value" in el.attrib:
            params.setdefault(el.attrib["name"], el.attrib["value"])

    def subst(text: str) -> str:
        return _PARAM.sub(lambda m: params.get(m.group(1), m.group(0)), text)

    for el in elements:
        refs = []
        if "filename" in el.attrib:
            refs.append(el.attrib["filename"])
        if el.tag == "string" and "value" in el.attrib:
            refs.append(el.attrib["value"])
        for ref in refs:
            ref = subst(ref)
            if not ref:
                continue
            for base in (path.parent, root):
                try:
                    dep = (base / ref).resolve()
                    found = dep.is_file()
                except (OSError, ValueError):  # a name too long, a NUL: no file of the scene
                    continue
                if found and root != dep and root not in dep.parents:
                    raise (error or UntrustedError)(
                        f"scene {path.name}: {ref[:200]!r} names {dep}, outside the scene's "
                        f"folder {root} (a scene reads only its own folder's files)"
                    )
                if found:
                    if dep.suffix.lower() == ".xml":
                        kw = {"root": root, "params": params, "error": error}
                        files.extend(xml_dependencies(dep, seen, **kw))
                    elif dep not in seen:
                        seen.add(dep)
                        files.append(dep)
                    break
    return files
