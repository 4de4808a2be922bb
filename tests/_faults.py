"""Faults injected into the LLVM backend, as the first CUDA run showed them (issue 24):
``no_hits`` makes every ``ray_test`` answer "nothing hit" (what OptiX returns when it
disables a trace), ``perturbed`` moves every ``ray_intersect`` hit 1e-4 of its distance
further along its ray (an intersection routine a little off)."""

from __future__ import annotations

import contextlib

#: Relative error of a perturbed intersection's distance.
PERTURBATION = 1e-4


@contextlib.contextmanager
def no_hits(mi):
    import drjit as dr

    original = mi.Scene.ray_test

    def ray_test(self, ray, *args, **kwargs):
        return dr.zeros(mi.Bool, dr.width(ray.o))

    mi.Scene.ray_test = ray_test
    try:
        yield
    finally:
        mi.Scene.ray_test = original


@contextlib.contextmanager
def perturbed(mi):
    original = mi.Scene.ray_intersect

    def ray_intersect(self, ray, *args, **kwargs):
        si = original(self, ray, *args, **kwargs)
        si.p = ray.o + ray.d * (si.t * (1.0 + PERTURBATION))
        return si

    mi.Scene.ray_intersect = ray_intersect
    try:
        yield
    finally:
        mi.Scene.ray_intersect = original


FAULTS = {"no-hits": no_hits, "perturbed": perturbed}
