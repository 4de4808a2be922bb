"""Digest of every model's output on every built-in scene, to prove a refactor kept the bytes.

Run from the project root, before and after a change, and compare::

    .venv/bin/python tests/model_digests.py --out /tmp/before.json
    .venv/bin/python tests/model_digests.py --out /tmp/after.json --compare /tmp/before.json

Cases: every registered technique on every built-in scene whose light it accepts (the scene's
own size), and on one scene each, every non-default choice of every parameter with choices and
every boolean parameter flipped. A case's digest is the SHA-256 of its output arrays (name,
dtype, shape, bytes) and of its cost and diagnostics records (timings and provenance left
out). Exit 1 when ``--compare`` finds a digest that differs or a case missing on either side.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import numpy as np

from raster_oracle import raster_models, scenes

#: Record keys left out of a digest: timings, and the provenance (package versions), which
#: says how a result was made, not what it is.
_SKIPPED_WORDS = ("seconds", "time", "wall", "provenance")


def _clean(record):
    if isinstance(record, dict):
        return {
            k: _clean(v)
            for k, v in sorted(record.items())
            if not any(w in str(k) for w in _SKIPPED_WORDS)
        }
    if isinstance(record, list | tuple):
        return [_clean(v) for v in record]
    if isinstance(record, np.ndarray):
        return record.tolist()
    if isinstance(record, np.generic):
        return record.item()
    return record


def _digest(result) -> str:
    h = hashlib.sha256()
    for name in sorted(result.outputs):
        arr = np.ascontiguousarray(result.outputs[name])
        h.update(f"{name}|{arr.dtype}|{arr.shape}|".encode())
        h.update(arr.tobytes())
    meta = {"cost": _clean(result.cost), "diagnostics": _clean(result.diagnostics)}
    h.update(json.dumps(meta, sort_keys=True, default=str).encode())
    return h.hexdigest()


def _variants(technique: dict) -> list[dict]:
    out = []
    for p in technique["params"]:
        if p["choices"]:
            out += [{p["name"]: c} for c in p["choices"] if c != p["default"]]
        elif isinstance(p["default"], bool):
            out.append({p["name"]: not p["default"]})
    return out


def cases() -> list[tuple[str, str, dict]]:
    """(technique, scene, params) for every case, in a fixed order."""
    loaded_lights = {name: scenes.load(name).light.kind for name in scenes.scene_names()}
    result = []
    for t in raster_models.list_techniques():
        fits = [s for s, kind in loaded_lights.items() if kind in t["lights"]]
        result += [(t["name"], s, {}) for s in fits]
        home = "city" if "city" in fits else fits[0]
        result += [(t["name"], home, v) for v in _variants(t)]
    return result


def _arrays(args, n: int, key: str, res) -> None:
    """Save the outputs (``--arrays``) and print the largest difference to ``--diff-arrays``."""
    if args.arrays:
        os.makedirs(args.arrays, exist_ok=True)
        np.savez(os.path.join(args.arrays, f"{n}.npz"), key=key, **res.outputs)
    if args.diff_arrays:
        path = os.path.join(args.diff_arrays, f"{n}.npz")
        if not os.path.exists(path):
            return
        old = np.load(path)
        if str(old["key"]) != key:
            return
        for name, arr in res.outputs.items():
            a = np.asarray(arr, dtype=np.float64)
            b = np.asarray(old[name], dtype=np.float64) if name in old else None
            if b is None or a.shape != b.shape:
                print(f"  {name}: missing or shape changed")
            elif not np.array_equal(a, b):
                d = np.abs(a - b)
                rel = d / np.maximum(np.abs(b), 1e-30)
                print(
                    f"  {name}: max |diff| {d.max():.3g}, max rel {rel.max():.3g}, "
                    f"{int((d > 0).sum())} values differ"
                )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="JSON file of case -> digest")
    ap.add_argument("--compare", help="an earlier --out file to compare with")
    ap.add_argument("--arrays", help="also save each case's outputs as DIR/<n>.npz")
    ap.add_argument("--diff-arrays", help="an earlier --arrays folder: print max |diff|")
    args = ap.parse_args(argv)
    digests, skipped = {}, {}
    cache = {}
    for technique, scene, params in cases():
        key = f"{technique} {scene} {json.dumps(params, sort_keys=True)}"
        loaded = cache.setdefault(scene, scenes.load(scene))
        try:
            res = raster_models.run(technique, loaded, **params)
        except raster_models.ModelError as exc:
            skipped[key] = str(exc)
            continue
        digests[key] = _digest(res)
        _arrays(args, len(digests) - 1, key, res)
        print(f"{digests[key][:16]}  {key}", flush=True)
    with open(args.out, "w") as f:
        json.dump({"digests": digests, "skipped": skipped}, f, indent=1, sort_keys=True)
    print(f"{len(digests)} cases, {len(skipped)} refused by the model")
    if not args.compare:
        return 0
    with open(args.compare) as f:
        before = json.load(f)["digests"]
    bad = sorted(k for k in set(before) | set(digests) if before.get(k) != digests.get(k))
    for k in bad:
        print(f"DIFFERS: {k}  {before.get(k, 'missing')[:16]} -> {digests.get(k, 'missing')[:16]}")
    print(f"compare: {len(bad)} of {len(set(before) | set(digests))} cases differ")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
