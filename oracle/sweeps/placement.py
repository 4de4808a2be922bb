"""Where a sweep's work runs on a local cluster: a scene group's references and cases on
one worker (its memos computed once), the costliest groups submitted first.

A *scene group* (:func:`scene_group`) is the cases sharing a worker's memos: same scene,
film, spp, light and path. :func:`grouped` orders the work so a worker runs a group's tasks
one after another, sequence groups (several frames a case) first; :func:`group_homes` gives
each group a preferred worker, balanced by expected work; :func:`at_home` turns that into
``client.submit`` keywords. Preferences are loose (Dask ``allow_other_workers``): an idle
worker still steals, so placement changes where work runs, never what it computes.
"""

from __future__ import annotations

from .cases import WORKER_CACHE, sequence_frames

__all__ = ["at_home", "case_frames", "case_weight", "group_homes", "grouped", "scene_group"]


def scene_group(rec: dict) -> tuple:
    """The cases sharing a worker's memos (loaded scene, noise floors, the reference halves of
    the metrics): same scene, film, spp, light and path."""
    return tuple(
        rec.get(k)
        for k in ("scene", "width", "height", "spp", "light", "camera_path", "light_path")
    )


def case_frames(rec: dict) -> int:
    """Frames a case scores (:func:`oracle.sweeps.cases.sequence_frames`): a sequence's, or
    1. The base scene is this process's (:func:`sweep_keys` loaded it)."""
    return sequence_frames(rec, WORKER_CACHE.base_scene(rec)) or 1


def case_weight(rec: dict) -> float:
    """A case's expected work, for placing it: its pixels times its frames."""
    return float(rec["width"] * rec["height"] * case_frames(rec))


def grouped(todo) -> list:
    """``todo`` with the cases of a scene group (:func:`scene_group`) next to each other: a
    worker then runs a group's cases one after another and its memos (a bounded LRU each)
    hold while the group lasts. Groups of sequence cases (several frames a case: the
    costliest) come first, so the sweep does not end on them with one worker idle; the
    others in order of first appearance."""
    order: dict[tuple, tuple] = {}
    for _, rec, _ in todo:
        group = scene_group(rec)
        if group not in order:
            order[group] = (case_frames(rec) == 1, len(order))
    return sorted(todo, key=lambda item: order[scene_group(item[1])])


def group_homes(todo, workers: list[str]) -> dict[tuple, str]:
    """A preferred worker of each scene group (:func:`scene_group` -> address): a group's
    references and cases on one worker, so its per-process memos (the loaded scene, the
    exact coverage both seeds' references share, noise floors, the reference halves of the
    metrics) are computed once; the groups spread over the workers by expected work,
    largest first. Preferences are loose: an idle worker still steals from a busy one. No
    workers or one: no preferences."""
    if len(workers) < 2:
        return {}
    weights: dict[tuple, float] = {}
    for _, rec, _ in todo:
        group = scene_group(rec)
        weights[group] = weights.get(group, 0.0) + case_weight(rec)
    load = dict.fromkeys(workers, 0.0)
    homes = {}
    for group, weight in sorted(weights.items(), key=lambda gw: (-gw[1], repr(gw[0]))):
        home = min(workers, key=lambda w: (load[w], w))
        load[home] += weight
        homes[group] = home
    return homes


def at_home(homes: dict, record: dict) -> dict:
    """``client.submit`` keywords placing a task of ``record``'s scene group at its home."""
    home = homes.get(scene_group(record))
    return {"workers": [home], "allow_other_workers": True} if home else {}
