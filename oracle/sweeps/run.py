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
from dataclasses import dataclass, field
from pathlib import Path

from ... import raster_models
from ...scenes.base.records import package_versions
from ..errors import InputError, one_line
from ..reference.cache import ORACLE_VERSION, ReferenceCache
from ..reference.render import ReferenceSettings
from ..reference.store import get_reference
from ..scoring.channels import METRIC_KEYS, REFERENCE_GROUPS
from ..scoring.technique import score_model, technique_channels
from .spec import Case, Expansion
from .store import SweepStore, case_key
from .thumbnails import case_images

__all__ = [
    "WORKER_CACHE",
    "SweepError",
    "WorkerCache",
    "case_phases",
    "check_scheduler",
    "completed_while_workers",
    "evaluate_case",
    "reference_jobs",
    "render_reference_timed",
    "run_case",
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


@dataclass
class WorkerCache:
    """What a process running sweep tasks keeps from one task to the next.

    Lifetime: the process. On a Dask worker (a process of its own, one task at a time) it
    lives as long as the worker; with ``workers=0`` and in tuning it is the client's, and
    :func:`sweep_keys` fills its scenes there too. Nothing in it changes a result: the
    scenes and noise floors are memos keyed by everything they depend on, the backend is
    selected once per process (by the variant of the sweep's first task).
    """

    #: Loaded base scenes by ``(scene, width, height, light)``; frames are derived from them.
    scenes: dict = field(default_factory=dict)
    #: Noise floors by reference and options (``floor_cache`` of
    #: :func:`oracle.scoring.score.score`).
    floors: dict = field(default_factory=dict)
    #: The Mitsuba variant this process selected (``None``: not yet selected here).
    variant: str | None = None
    #: Dr.Jit threads of this worker (its share of the cores, set by ``Client.run``), applied
    #: when the backend is selected; ``None``: Dr.Jit's default.
    threads: int | None = None

    def ensure_backend(self, variant: str | None) -> None:
        """Select ``variant`` (and this worker's thread count) once in this process."""
        if variant is None or self.variant is not None:
            return
        from ...scenes import backend

        backend.select(variant)
        self.variant = variant
        if backend.self_check() is None:  # a worker process: this machine's cached verdict
            from ..certify.verdict import cached_verdict, summary

            verdict = cached_verdict(variant)
            if verdict is not None:
                backend.set_self_check(summary(verdict))
        if self.threads is not None:
            import drjit as dr

            dr.set_thread_count(self.threads)

    def base_scene(self, rec: dict):
        """The loaded base scene of a case record (loaded once per process)."""
        from ... import scenes

        key = (rec["scene"], rec["width"], rec["height"], rec["light"])
        if key not in self.scenes:
            self.scenes[key] = scenes.load(
                rec["scene"], width=rec["width"], height=rec["height"], light=rec["light"]
            )
        return self.scenes[key]


#: This process's :class:`WorkerCache` (the one instance; its lifetime is the process's).
WORKER_CACHE = WorkerCache()


class SweepError(InputError):
    """A sweep cannot run (no scheduler at the given address)."""


#: Longest error message kept in a failed case's row, in characters.
MAX_ERROR_CHARS = 2000


def _error(exc: BaseException) -> str:
    """A failed case's ``error``: the exception's type and message on one line."""
    return one_line(exc, with_type=True)[:MAX_ERROR_CHARS]


def _reference_groups(technique: str) -> list[tuple[str, ...]]:
    """Channel groups of the references scoring ``technique`` reads (one per channel)."""
    return [REFERENCE_GROUPS[c] for c in technique_channels(technique)]


def _share_cores(threads: int) -> None:
    """Worker set-up (``Client.run``): this worker's Dr.Jit threads, its share of the cores,
    so that the local cluster's workers do not oversubscribe the machine."""
    WORKER_CACHE.threads = max(1, int(threads))


def case_scene(rec: dict):
    """The loaded scene of a case record: its frame of its camera or light path."""
    base = WORKER_CACHE.base_scene(rec)
    if rec.get("light_path"):
        return base.with_light_frame(rec["frame"], path=rec["light_path"], n_frames=rec["n_frames"])
    if rec.get("camera_path"):
        return base.with_frame(rec["frame"], path=rec["camera_path"], n_frames=rec["n_frames"])
    return base


def reference_jobs(rec: dict) -> list[dict]:
    """The reference records a case needs: ``{"scene": ..., "channels", "seed", "spp"}``."""
    scene_part = {
        k: rec[k]
        for k in ("scene", "width", "height", "light", "camera_path", "light_path", "frame")
    }
    scene_part["n_frames"] = (
        rec["n_frames"] if rec.get("camera_path") or rec.get("light_path") else None
    )
    jobs = []
    for groups in _reference_groups(rec["technique"]):
        for seed in (rec["seed"], rec["seed"] + 1):
            jobs.append({**scene_part, "channels": list(groups), "seed": seed, "spp": rec["spp"]})
    return jobs


def render_reference(job: dict, cache_root: str, variant: str | None) -> str:
    """Worker task: render one reference into the cache (or find it there); its status."""
    WORKER_CACHE.ensure_backend(variant)
    settings = ReferenceSettings(
        spp=job["spp"], seed=job["seed"], channels=tuple(job["channels"])
    ).validate()
    rec = dict(job, n_frames=job["n_frames"] or 1)
    ref = get_reference(case_scene(rec), settings, cache=ReferenceCache(cache_root), quiet=True)
    return ref.cache_status


#: Last frames of a sequence case whose metrics are averaged (the steady state).
SEQUENCE_GATE_FRAMES = 4


def sequence_frames(rec: dict, loaded) -> int | None:
    """Frames a case scores as one sequence (None: its own frame alone): every frame of its
    camera path for a temporal family (TAA: ghosting and steady error need the sequence) and
    for any technique on a scene whose objects move (the baselines beside it)."""
    temporal = raster_models.family(rec["technique"]).temporal or bool(loaded.object_motion)
    if temporal and rec.get("camera_path") and rec.get("n_frames", 1) >= 2:
        return int(rec["n_frames"])
    return None


def evaluate_case(
    loaded,
    technique: str,
    params: dict,
    *,
    spp: int,
    seed: int,
    cache,
    images: bool = False,
    frames: int | None = None,
) -> dict:
    """Score one technique configuration on ``loaded``: metrics, noise floor, cost, params.

    Shadow techniques are scored on visibility; anti-aliasing techniques on colour with the
    coverage metrics merged in, exactly as ``raster-oracle score --technique`` does. With
    ``images``, ``"images"`` holds thumbnails (:func:`case_images`). With ``frames``, the
    frames 0.. of ``loaded``'s camera path are scored as one sequence, the per-frame metrics
    averaged over the last :data:`SEQUENCE_GATE_FRAMES` (the temporal AA metrics added).
    """
    seq = {}
    if frames:
        seq = dict(
            frames=frames,
            camera_path=loaded.camera_path,
            gate_frames=min(SEQUENCE_GATE_FRAMES, frames),
        )
    result = score_model(
        loaded,
        technique,
        params,
        spp=spp,
        seed=seed,
        cache=cache,
        quiet=True,
        floor_cache=WORKER_CACHE.floors,
        **seq,
    )
    record = result.record
    info = record["candidate_info"][0]
    metrics = {k: record.get(k) for k in METRIC_KEYS}
    metrics["noise_floor"] = record.get("noise_floor")
    metrics["receiver_count"] = result.frames[0].metrics.get("receiver_count")
    out = {"metrics": metrics, "cost": info["cost"], "params": info["params"]}
    # the models' own seconds (each frame's run, once however many channels are scored)
    out["model_seconds"] = float(
        sum(i.get("model_seconds") or 0.0 for i in record["candidate_info"])
    )
    if images:
        t0 = time.perf_counter()
        out["images"] = case_images(result)
        out["image_seconds"] = time.perf_counter() - t0
    return out


def run_case(rec: dict, cache_root: str, variant: str | None, *_deps, images: bool = False) -> dict:
    """Worker task: evaluate one case record; never raises (a failure is a result)."""
    t0 = time.perf_counter()
    try:
        WORKER_CACHE.ensure_backend(variant)
        loaded = case_scene(rec)
        out = evaluate_case(
            loaded,
            rec["technique"],
            rec["params"],
            spp=rec["spp"],
            seed=rec["seed"],
            cache=ReferenceCache(cache_root),
            images=images,
            frames=sequence_frames(rec, loaded),
        )
        out["status"], out["error"] = "done", None
    except Exception as exc:  # recorded in the store; the sweep goes on
        out = {"status": "failed", "error": _error(exc), "metrics": None, "cost": None}
        out["params"] = rec["params"]
    out["wall_seconds"] = time.perf_counter() - t0
    out["phases"] = case_phases(out)
    return out


def case_phases(res: dict) -> dict[str, float]:
    """A finished case's seconds by phase: ``models`` (the model runs), ``images`` (its
    thumbnails) and ``metrics`` (the rest: reading the cached references, noise floors,
    metrics)."""
    wall = float(res.get("wall_seconds") or 0.0)
    models = float(res.pop("model_seconds", 0.0) or 0.0)
    images = float(res.pop("image_seconds", 0.0) or 0.0)
    return {"models": models, "images": images, "metrics": max(0.0, wall - models - images)}


def render_reference_timed(job: dict, cache_root: str, variant: str | None) -> dict:
    """Worker task of a Dask sweep: :func:`render_reference` and its wall seconds."""
    t0 = time.perf_counter()
    status = render_reference(job, cache_root, variant)
    return {"status": status, "seconds": time.perf_counter() - t0}


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

    Returns
    -------
    dict
        ``{"sweep", "db", "cases", "skipped_done", "ran", "done", "failed", "references",
        "wall_seconds", "not_applicable"}``.
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
    }
    with SweepStore(db) as store:
        finished = store.finished_keys(include_failed=not retry_failed)
        todo = [(k, rec, row) for k, (rec, row) in unique.items() if k not in finished]
        summary["skipped_done"] = len(unique) - len(todo)
        if todo:
            run_id = f"{time.strftime('%Y%m%dT%H%M%S')}-{uuid.uuid4().hex[:8]}"
            if workers == 0 and scheduler is None:
                results = _run_inline(
                    todo, cache_root, variant, summary, quiet=quiet, images=images
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
    summary["wall_seconds"] = time.perf_counter() - t0
    return summary


def _unique_references(todo) -> dict[str, dict]:
    refs: dict[str, dict] = {}
    for _, rec, _ in todo:
        for job in reference_jobs(rec):
            refs.setdefault(json.dumps(job, sort_keys=True), job)
    return refs


def _run_inline(todo, cache_root, variant, summary, *, quiet, images):
    refs = _unique_references(todo)
    summary["references"] = len(refs)
    failed_refs: dict[str, str] = {}
    t0 = time.perf_counter()
    with _progress(len(refs), quiet=quiet, desc="references") as bar:
        for text, job in refs.items():
            try:
                render_reference(job, cache_root, variant)
            except Exception as exc:  # the cases that need it fail with this error
                failed_refs[text] = _error(exc)
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


def _run_dask(
    todo, cache_root, variant, summary, *, workers, scheduler, quiet, images, worker_timeout
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
        client.run(_share_cores, max(1, (os.cpu_count() or 1) // n_workers))
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
        refs = _unique_references(todo)
        summary["references"] = len(refs)
        ref_futures = {
            text: client.submit(render_reference_timed, job, cache_root, variant, pure=False)
            for text, job in refs.items()
        }
        futures = {}
        for item in todo:
            rec = item[1]
            deps = [ref_futures[json.dumps(j, sort_keys=True)] for j in reference_jobs(rec)]
            fut = client.submit(
                run_case, rec, cache_root, variant, *deps, images=images, pure=False
            )
            futures[fut] = item
        with _progress(len(futures), quiet=quiet, desc=summary["sweep"]) as bar:
            for fut in completed_while_workers(
                client, futures, worker_timeout=worker_timeout, where=where
            ):
                key, rec, row = futures.pop(fut)
                try:
                    res = fut.result()
                except Exception as exc:  # a reference failed, or a worker died
                    res = {"status": "failed", "error": _error(exc), "wall_seconds": None}
                bar.update()
                yield key, rec, row, res
        summary["phases"]["references"] += _reference_seconds(ref_futures.values())
    except (SystemExit, KeyboardInterrupt):
        # stopped (SIGTERM, Ctrl-C): the local workers are ended now, not after their task
        stopping = True
        if cluster is not None:
            for nanny in list(getattr(cluster, "workers", {}).values()):
                nanny.auto_restart = False  # a killed worker is not started again
            _end_local_workers()
        raise
    finally:
        _close_dask(client, cluster, quick=stopping)
