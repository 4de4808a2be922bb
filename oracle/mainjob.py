"""The main job: references, every technique model and one combined report for the
built-in default scenes."""

from __future__ import annotations

from pathlib import Path

__all__ = ["MAIN_RESOLUTIONS", "run_main"]

#: Shadow-map resolutions each technique runs at, so the report's cost-versus-error plot
#: has a front to draw.
MAIN_RESOLUTIONS = (512, 2048)


def run_main(names, out: Path, *, spp: int, cache, quiet: bool, echo=print) -> Path:
    """Render references, score each technique at each resolution, write the report."""
    import raster_models
    import scenes

    from .pipeline import get_reference, publish
    from .reference import ReferenceSettings
    from .scoring import combine_reports, score_technique

    settings = ReferenceSettings(spp=spp).validate()
    techniques = raster_models.list_techniques()
    folders = []
    for name in names:
        loaded = scenes.load(name)
        ref = get_reference(loaded, settings, cache=cache, quiet=quiet)
        publish(ref, out / name / "reference")
        m = ref.meta
        echo(
            f"{name:<7} {loaded.width}x{loaded.height} {spp} spp reference ({ref.cache_status}, "
            f"{m['wall_seconds']:.1f} s): {out / name / 'reference' / 'reference.exr'}"
        )
        usable = [t["name"] for t in techniques if loaded.light.kind in t.get("lights", ())]
        for tech in usable:
            for res in MAIN_RESOLUTIONS:
                folder = out / name / f"{tech}-{res}"
                params = raster_models.parse_params(tech, [f"resolution={res}"])
                score_technique(
                    loaded,
                    tech,
                    params,
                    out=folder,
                    spp=spp,
                    seed=0,
                    cache=cache,
                    quiet=True,
                    name=f"{tech} {res} @ {name}",
                )
                folders.append(folder)
        kinds = ", ".join(usable)
        echo(f"{name:<7} scored {kinds} at {MAIN_RESOLUTIONS} ({loaded.light.kind} light)")
    report = out / "report.html"
    combine_reports(folders, report, title="raster-oracle: built-in scenes, every technique")
    return report
