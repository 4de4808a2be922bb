"""Sweeps: run the cases of a spec on Dask and keep the results in a resumable SQLite store.

One task is one case: one technique configuration scored on one scene frame
(:class:`oracle.sweeps.spec.Case`). The references a case needs (its channel groups at the
case's seed and at ``seed + 1`` for the noise floor, per scene, frame, resolution, spp and
light) are tasks of their own, submitted first; every case that needs one depends on it, so a
reference is rendered once, into the content-addressed cache, and read by every case after
it. Workers therefore need the client's cache folder (``RASTER_ORACLE_CACHE``): on a
``--scheduler`` cluster of several machines it must be a shared folder at the same path.

Results are written by the client only, one committed row per finished case
(:class:`oracle.sweeps.store.SweepStore`); cases whose key is already in the store are skipped,
and a case that raises is recorded as ``failed`` with its error while the sweep goes on.
``workers=0`` runs everything in the client process, in order, without Dask (small sweeps,
tuning, debugging).
"""

from __future__ import annotations

import json
import logging
import os
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from ... import raster_models
from ...scenes.base.records import package_versions
from ..errors import InputError
from ..reference.cache import ORACLE_VERSION
from .cases import (
    WORKER_CACHE,
    case_error,
    reference_jobs,
    render_reference,
    render_reference_timed,
    run_case,
    run_side_task,
    share_cores,
)
from .placement import at_home, group_homes, grouped
from .spec import Case, Expansion
from .store import SweepStore, case_key

__all__ = [
    "SideTask",
    "SweepError",
    "check_scheduler",
    "completed_while_workers",
    "run_sweep",
    "store_row",
    "sweep_keys",
]

#: Seconds to wait for a ``--scheduler`` to answer.
SCHEDULER_TIMEOUT_S = 20

#: How long a sweep on a Dask scheduler waits with no worker connected (at the start, or
#: after every worker is gone) before it stops with "no workers" (``--worker-timeout``).
NO_WORKERS_TIMEOUT_S = 120.0

#: Seconds between checks for finished cases and connected workers.
WORKER_POLL_S = 1.0


class SweepError(InputError):
    """A sweep cannot run (no scheduler at the given address)."""


class SideTask(NamedTuple):
    """Work run on the sweep's workers beside its cases (the main job's sections): a worker
    calls ``study(cache=<the sweep's reference cache>, **kwargs)``; ``study`` and ``kwargs``
    must pickle. Tasks of higher ``priority`` start first (cases have 0): long tasks given
    a high one start early and leave no tail. Its result (:func:`oracle.sweeps.cases.
    run_side_task`) lands in the summary's ``side`` under ``name``."""

    name: str
    study: Callable[..., dict]
    kwargs: dict
    priority: int = 1


def _versions(variant: str) -> dict:
    """What a case's result depends on besides its inputs: backend, oracle and packages."""
    return {"variant": variant, "oracle_version": ORACLE_VERSION, **package_versions()}


def sweep_keys(cases: list[Case], variant: str) -> list[tuple[str, dict, dict]]:
    """``(key, record, row)`` of each case: the store key, the worker record and the row
    fields known before it runs (scene content hash and every parameter resolved)."""
    from ...raster_models import params

    versions = _versions(variant)
    out = []
    for case in cases:
        rec = case.record()
        base = WORKER_CACHE.base_scene(rec)
        rec["width"], rec["height"] = base.width, base.height
        tech = raster_models.TECHNIQUES[case.technique]
        full = params.as_dict(params.make(case.technique, tech.params, case.params))
        identity = {
            "scene": Path(case.scene).name
            if case.scene.endswith((".xml", ".gltf", ".glb"))
            else case.scene,
            "scene_hash": base.content_hash,
            "technique": case.technique,
            "params": full,
            **{k: rec[k] for k in ("light", "camera_path", "light_path", "spp", "seed")},
            "frame": case.frame,
            "n_frames": case.n_frames if case.frame_path else None,
            "versions": versions,
        }
        row = {
            "scene": base.name,
            "technique": case.technique,
            "family": raster_models.family_of(case.technique),
            "frame": case.frame,
            "path": case.frame_path,
            "width": base.width,
            "height": base.height,
            "spp": case.spp,
            "seed": case.seed,
        }
        out.append((case_key(identity), rec, row))
    return out


def check_scheduler(address: str) -> None:
    """Raise :class:`SweepError` when no Dask scheduler answers at ``address``."""
    from distributed import Client

    try:
        Client(address, timeout=SCHEDULER_TIMEOUT_S).close()
    except (OSError, TimeoutError, ValueError) as exc:
        raise SweepError(f"--scheduler {address}: cannot connect: {exc}") from None


def _default_workers() -> int:
    return max(1, os.cpu_count() or 1)


def _progress(total: int, *, quiet: bool, desc: str):
    """A bar on a terminal; in a CI log (its carriage-return redraws are noise there) plain
    lines instead (:class:`LogProgress`)."""
    from tqdm import tqdm

    if not quiet and not sys.stderr.isatty():
        return LogProgress(total, desc=desc)
    return tqdm(total=total, desc=desc, unit="case", disable=quiet, leave=False)


class LogProgress:
    """Progress as plain lines on stderr, for logs: ``desc: done/total cases (pct%), s``
    at every tenth of the work and at the end (at most 11 lines, whatever the total)."""

    STEPS = 10

    def __init__(self, total: int, *, desc: str):
        self.total, self.desc, self.done = int(total), desc, 0
        self.t0 = time.perf_counter()
        self.next_step = 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def close(self) -> None:
        """Nothing to clear (tqdm's interface)."""

    def update(self, n: int = 1) -> None:
        self.done += n
        if self.total <= 0:
            return
        step = self.done * self.STEPS // self.total
        if step >= self.next_step or self.done == self.total:
            self.next_step = step + 1
            pct = 100 * self.done // self.total
            wall = time.perf_counter() - self.t0
            print(
                f"{self.desc}: {self.done}/{self.total} cases ({pct}%), {wall:.0f} s",
                file=sys.stderr,
                flush=True,
            )


def run_sweep(
    expansion: Expansion,
    db: str | os.PathLike,
    *,
    cache_root: str | os.PathLike,
    workers: int | None = None,
    scheduler: str | None = None,
    quiet: bool = False,
    retry_failed: bool = False,
    images: bool = True,
    worker_timeout: float | None = None,
    side: tuple[SideTask, ...] | list[SideTask] = (),
    echo=print,
) -> dict:
    """Run the cases of ``expansion`` not yet in the store ``db``; returns a summary.

    Parameters
    ----------
    expansion : from :func:`oracle.sweeps.spec.load_spec`.
    db : the SQLite store (created when missing).
    cache_root : the reference cache folder every worker reads and writes.
    workers : worker processes of the local Dask cluster (default: one per core); 0 runs
        everything in this process without Dask.
    scheduler : address of an existing Dask scheduler (``tcp://host:8786``) instead of a
        local cluster.
    retry_failed : run again the cases recorded as failed (default: they count as finished).
    images : keep thumbnails of each case (reference, candidate, error map) in the store.
    worker_timeout : seconds without any Dask worker (at the start or after all are gone)
        before a :class:`SweepError` "no workers" (None: :data:`NO_WORKERS_TIMEOUT_S`); the
        cases finished until then are kept.
    side : :class:`SideTask` s run on the same workers, whatever the store holds (inline:
        after the cases); their results are the summary's ``side`` (name -> ``{"value",
        "error", "seconds"}``).

    Returns
    -------
    dict
        ``{"sweep", "db", "cases", "skipped_done", "ran", "done", "failed", "references",
        "wall_seconds", "not_applicable", "side"}``.
    """
    from ...scenes import backend

    t0 = time.perf_counter()
    if worker_timeout is None:
        worker_timeout = NO_WORKERS_TIMEOUT_S
    variant = backend.active().variant
    cache_root = str(Path(cache_root).resolve())
    Path(cache_root).mkdir(parents=True, exist_ok=True)
    keyed = sweep_keys(expansion.cases, variant)
    # the same case listed twice in a spec runs once
    unique = {}
    for key, rec, row in keyed:
        unique.setdefault(key, (rec, row))
    summary = {
        "sweep": expansion.name,
        "db": str(db),
        "cases": len(unique),
        "not_applicable": list(expansion.skipped),
        "skipped_done": 0,
        "ran": 0,
        "done": 0,
        "failed": 0,
        "references": 0,
        # seconds by phase: wall in this process (workers=0), else summed over the workers
        "phases": {"references": 0.0, "models": 0.0, "metrics": 0.0, "images": 0.0},
        # the cases' scoring seconds by score pass (oracle.scoring.passes), summed likewise
        "passes": {},
        "side": {},
    }
    with SweepStore(db) as store:
        finished = store.finished_keys(include_failed=not retry_failed)
        todo = [(k, rec, row) for k, (rec, row) in unique.items() if k not in finished]
        summary["skipped_done"] = len(unique) - len(todo)
        if todo or side:
            run_id = f"{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}"
            if workers == 0 and scheduler is None:
                results = _run_inline(
                    todo, cache_root, variant, summary, quiet=quiet, images=images, side=side
                )
            else:
                results = _run_dask(
                    todo,
                    cache_root,
                    variant,
                    summary,
                    workers=workers,
                    scheduler=scheduler,
                    quiet=quiet,
                    images=images,
                    worker_timeout=worker_timeout,
                    side=side,
                )
            for key, rec, row, res in results:
                store.put(
                    store_row(row, key=key, rec=rec, res=res, sweep=expansion.name, run_id=run_id),
                    images=res.get("images"),
                )
                summary["ran"] += 1
                summary[res["status"]] += 1
                for name, seconds in (res.get("phases") or {}).items():
                    summary["phases"][name] = summary["phases"].get(name, 0.0) + seconds
                for name, seconds in (res.pop("passes", None) or {}).items():
                    summary["passes"][name] = summary["passes"].get(name, 0.0) + seconds
    summary["wall_seconds"] = time.perf_counter() - t0
    return summary


def _unique_references(todo) -> dict[str, dict]:
    refs: dict[str, dict] = {}
    for _, rec, _ in todo:
        for job in reference_jobs(rec):
            refs.setdefault(json.dumps(job, sort_keys=True), job)
    return refs


def _run_inline(todo, cache_root, variant, summary, *, quiet, images, side=()):
    todo = grouped(todo)
    refs = _unique_references(todo)
    summary["references"] = len(refs)
    failed_refs: dict[str, str] = {}
    t0 = time.perf_counter()
    with _progress(len(refs), quiet=quiet, desc="references") as bar:
        for text, job in refs.items():
            try:
                render_reference(job, cache_root, variant)
            except Exception as exc:  # the cases that need it fail with this error
                failed_refs[text] = case_error(exc)
            bar.update()
    summary["phases"]["references"] += time.perf_counter() - t0

    with _progress(len(todo), quiet=quiet, desc=summary["sweep"]) as bar:
        for key, rec, row in todo:
            broken = [
                failed_refs[t]
                for t in (json.dumps(j, sort_keys=True) for j in reference_jobs(rec))
                if t in failed_refs
            ]
            if broken:
                res = {"status": "failed", "error": f"reference: {broken[0]}", "wall_seconds": 0.0}
            else:
                res = run_case(rec, cache_root, variant, images=images)
            bar.update()
            yield key, rec, row, res
    for task in side:
        summary["side"][task.name] = run_side_task(task.study, task.kwargs, cache_root, variant)


def store_row(row: dict, *, key: str, rec: dict, res: dict, sweep: str, run_id: str) -> dict:
    """The store row of a finished case: its keyed ``row`` (:func:`sweep_keys`) with the
    result ``res`` of :func:`run_case` (parameters as run, metrics, cost, status, error)."""
    return {
        **row,
        "key": key,
        "sweep": sweep,
        "params": res.get("params") or rec["params"],
        "metrics": res.get("metrics"),
        "cost": res.get("cost"),
        "wall_seconds": res.get("wall_seconds"),
        "status": res["status"],
        "error": res.get("error"),
        "run_id": run_id,
    }


def completed_while_workers(client, futures, *, worker_timeout: float, where: str):
    """Yield ``futures`` as they finish; raise :class:`SweepError` after ``worker_timeout``
    seconds with no worker connected (a cluster whose workers are all gone never finishes)."""
    from distributed import wait

    pending, idle_since = set(futures), None
    while pending:
        try:
            done, pending = wait(pending, timeout=WORKER_POLL_S, return_when="FIRST_COMPLETED")
        except TimeoutError:
            if client.scheduler_info()["workers"]:
                idle_since = None
            elif idle_since is None:
                idle_since = time.monotonic()
            elif time.monotonic() - idle_since > worker_timeout:
                raise SweepError(
                    f"{where}: no workers for {worker_timeout:g} s; {len(pending)} case(s) not "
                    "run (the finished ones are kept in the store)"
                ) from None
            continue
        yield from done


def _worker_addresses(client) -> list[str]:
    return sorted(client.scheduler_info()["workers"])


def _side_result(fut) -> dict:
    """A finished side task's result; a worker that died running it is its error."""
    try:
        return fut.result()
    except Exception as exc:  # run_side_task never raises: the worker died
        return {"value": None, "error": case_error(exc), "seconds": 0.0}


def _reference_seconds(futures) -> float:
    """Worker seconds of the finished reference tasks (failed ones are not counted)."""
    total = 0.0
    for fut in futures:
        if fut.status == "finished":
            total += float(fut.result().get("seconds", 0.0))
    return total


#: Seconds the Dask client and local cluster get to close.
STOP_TIMEOUT_S = 1.0


def _end_local_workers() -> None:
    """Kill this process's child processes (the local cluster's nannies and workers): a
    worker inside a long kernel would otherwise finish its task before it noticed; its
    results are not stored, the store keeps what finished (each row one transaction)."""
    import psutil

    children = []
    for child in psutil.Process().children(recursive=True):
        try:  # multiprocessing's resource tracker stays: it ends with this process
            if not any("resource_tracker" in part for part in child.cmdline()):
                children.append(child)
        except psutil.Error:
            pass
    for child in children:
        try:
            child.kill()
        except psutil.Error:
            pass
    psutil.wait_procs(children, timeout=STOP_TIMEOUT_S)


def _close_dask(client, cluster, *, quick: bool) -> None:
    """Close the client and the local cluster; ``quick`` (stopping on a signal): a second
    each, and a timeout closing what was killed is no error."""
    for closing in (client, cluster):
        if closing is None:
            continue
        if not quick:
            closing.close()
            continue
        try:
            closing.close(timeout=STOP_TIMEOUT_S)
        except Exception:  # stopping anyway
            pass


def _submit_cases(client, todo, homes, cache_root, variant, images):
    """Submit the references of ``todo`` (each once) and its cases, each case depending on
    its references, both at their scene group's home; ``(reference futures by record text,
    {case future: todo item})``."""
    refs = _unique_references(todo)
    ref_futures = {
        text: client.submit(
            render_reference_timed, job, cache_root, variant, pure=False, **at_home(homes, job)
        )
        for text, job in refs.items()
    }
    futures = {}
    for item in todo:
        rec = item[1]
        deps = [ref_futures[json.dumps(j, sort_keys=True)] for j in reference_jobs(rec)]
        fut = client.submit(
            run_case,
            rec,
            cache_root,
            variant,
            *deps,
            images=images,
            pure=False,
            **at_home(homes, rec),
        )
        futures[fut] = item
    return ref_futures, futures


def _submit_sides(client, side, homes, cache_root, variant) -> dict:
    """Submit the side tasks; ``{future: name}``. A local cluster's cases are placed on
    workers at once (they have homes), so unplaced side tasks would wait in the scheduler's
    queue until the cases were done: placed too (on any worker, loosely), their priority
    then orders them on a worker."""
    anywhere = {"workers": _worker_addresses(client), "allow_other_workers": True} if homes else {}
    return {
        client.submit(
            run_side_task,
            task.study,
            task.kwargs,
            cache_root,
            variant,
            pure=False,
            priority=task.priority,
            **anywhere,
        ): task.name
        for task in side
    }


def _run_dask(
    todo, cache_root, variant, summary, *, workers, scheduler, quiet, images, worker_timeout, side
):
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers or _default_workers(),
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",  # any free port: several sweeps may run at once
            silence_logs=logging.ERROR,
        )
        client = Client(cluster)
        n_workers = workers or _default_workers()
        client.run(share_cores, max(1, (os.cpu_count() or 1) // n_workers))
    else:
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise SweepError(f"--scheduler {scheduler}: cannot connect: {exc}") from None
    where = "local cluster" if scheduler is None else f"--scheduler {scheduler}"
    stopping = False
    try:
        if scheduler is not None:
            try:
                client.wait_for_workers(1, timeout=worker_timeout)
            except TimeoutError:
                raise SweepError(
                    f"{where}: no workers connected within {worker_timeout:g} s"
                ) from None
        todo = grouped(todo)
        homes = {} if scheduler is not None else group_homes(todo, _worker_addresses(client))
        ref_futures, futures = _submit_cases(client, todo, homes, cache_root, variant, images)
        summary["references"] = len(ref_futures)
        sides = _submit_sides(client, side, homes, cache_root, variant)
        with _progress(len(futures), quiet=quiet, desc=summary["sweep"]) as bar:
            for fut in completed_while_workers(
                client, [*futures, *sides], worker_timeout=worker_timeout, where=where
            ):
                if fut in sides:
                    summary["side"][sides.pop(fut)] = _side_result(fut)
                    continue
                key, rec, row = futures.pop(fut)
                try:
                    res = fut.result()
                except Exception as exc:  # a reference failed, or a worker died
                    res = {"status": "failed", "error": case_error(exc), "wall_seconds": None}
                bar.update()
                yield key, rec, row, res
        summary["phases"]["references"] += _reference_seconds(ref_futures.values())
    except (SystemExit, KeyboardInterrupt):
        # stopped (SIGTERM, Ctrl-C): the local workers are ended now, not after their task
        stopping = True
        # the cluster's own loggers report the workers killed below as errors, with an
        # asyncio.CancelledError traceback: a stop is no error (issue 48)
        logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)
        if cluster is not None:
            for nanny in list(getattr(cluster, "workers", {}).values()):
                nanny.auto_restart = False  # a killed worker is not started again
            _end_local_workers()
        raise
    finally:
        _close_dask(client, cluster, quick=stopping)
