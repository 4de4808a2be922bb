"""Where do two backends part? The failure families of the first CUDA run, each computed on
two Mitsuba variants in one process, stage by stage (issue 24; not a test: a diagnosis for a
machine that has both backends).

Usage, from the project root (the GPU machine: ``PYTHONPATH`` from ``.gpu/run.sh``)::

    python3 tests/backend_compare.py cuda_ad_rgb llvm_ad_rgb > compare.txt

For each case it prints, per stage, how many values differ between the two variants: the
oracle's pixel-centre G-buffer (surface, hit position, light visibility), then what a model or
Mitsuba's ``direct`` makes of it. The first stage that differs is where the root cause is.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

SPOT_XML = """<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="3,8,8" target="3,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="160"/><integer name="height" value="90"/>
      <rfilter type="box"/></film></sensor>
  <emitter type="spot">
    <transform name="to_world"><lookat origin="0,4,0" target="3,0,0" up="0,0,1"/></transform>
    <rgb name="intensity" value="50"/><float name="cutoff_angle" value="35"/></emitter>
  <shape type="rectangle" id="ground">
    <transform name="to_world"><rotate x="1" angle="-90"/><scale value="50"/></transform></shape>
  <shape type="cube" id="beam"><transform name="to_world">
      <scale x="10" y="0.2" z="0.2"/><translate x="0" y="2" z="0.4"/></transform></shape>
</scene>
"""


def _cases(folder: Path) -> list[tuple[str, str, dict, list]]:
    """(name, scene, load keywords, [(technique, params)]) of the failing families."""
    from test_models_xml import box, ground, write_scene  # the extremes tests' scenes

    xml = folder / "spot_crossing.xml"
    xml.write_text(SPOT_XML)
    forward = np.array([0.0, -3.0, 6.0]) / np.sqrt(45.0)
    view = write_scene(
        folder,
        name="view_direction",
        shapes=[ground(40.0), box((-1, 0, 2), (1, 2, 4))],
        origin=(0, 3, -6),
        target=(0, 0, 0),
        sun=tuple(forward),
    )
    outside = write_scene(
        folder,
        name="outside",
        shapes=[ground(80.0), box((-1.5, 0, -8), (1.5, 12, -6))],
        origin=(0, 2, 0),
        target=(0, 0, 10),
        sun=(0, -0.5, 1),
    )
    sm = {"resolution": 512, "filter": "hw_pcf"}
    biased = {**sm, "bias": 0.0005, "normal_offset": 1.5}
    return [
        ("view-direction", str(view), {}, [("shadow-map", biased)]),
        ("pancaking", str(outside), {}, [("csm", {**sm, "depth_clamp": True})]),
        ("point", "point", {"width": 160, "height": 90}, [("shadow-map", {"resolution": 2048})]),
        ("spot", "spot", {"width": 160, "height": 90}, [("izb", {}), ("izb", {"samples": 32})]),
        ("spot-crossing", str(xml), {}, [("izb", {})]),
        ("plate", "plate", {"width": 160, "height": 90}, [("shadow-map", {"resolution": 1024})]),
    ]


def _run(variant: str, folder: Path) -> dict:
    from raster_oracle.raster_models.gbuffer import trace_gbuffer
    from raster_oracle.scenes import backend

    from raster_oracle import raster_models as rm
    from raster_oracle import scenes

    backend.select(variant, replace=True)
    mi = backend.mitsuba()
    out: dict = {}
    for name, scene, kw, models in _cases(folder):
        s = scenes.load(scene, **kw)
        g = trace_gbuffer(s, with_lit=True)
        out[(name, "valid")] = g.valid
        out[(name, "shape")] = g.shape
        out[(name, "position")] = g.position
        out[(name, "lit")] = g.lit
        for technique, params in models:
            vis = rm.run(technique, s, **params).outputs["visibility"]
            out[(name, f"{technique} {params}")] = vis
        if name == "point":
            integrator = mi.load_dict({"type": "direct", "emitter_samples": 1, "bsdf_samples": 0})
            runs = [
                np.array(mi.render(s.mi_scene, integrator=integrator, spp=64, seed=k))
                for k in (0, 1)
            ]
            out[(name, "mitsuba direct 64 spp")] = runs[0]
            # seeds must give independent renders (the colour test's error bars need them)
            out[(name, "values differing between seeds 0 and 1")] = np.array(
                [np.count_nonzero(runs[0] != runs[1])]
            )
    return out


def main(argv: list[str]) -> int:
    a, b = argv[1:3] if len(argv) >= 3 else ("cuda_ad_rgb", "llvm_ad_rgb")
    with tempfile.TemporaryDirectory() as tmp:
        first = _run(a, Path(tmp))
        second = _run(b, Path(tmp))
    print(f"{'case':<14} {'stage':<60} differing values (of), largest |difference|  [{a} vs {b}]")
    for key, x in first.items():
        y = second[key]
        x64, y64 = np.asarray(x, np.float64), np.asarray(y, np.float64)
        differ = int(np.count_nonzero(x64 != y64))
        big = float(np.nanmax(np.abs(x64 - y64))) if x64.size else 0.0
        print(f"{key[0]:<14} {key[1]:<60} {differ:>8} ({x64.size}), {big:.3g}")
        if x64.size == 1:  # a count: show it on each backend
            print(f"{'':<14} {'':<60} {a}: {x64.item():g}, {b}: {y64.item():g}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
