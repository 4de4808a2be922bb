"""oracle.scoring.passes: the passes of a score, one module each (``applies(request) -> bool``
and ``run(context)``); :mod:`oracle.scoring.passes.plan` decides which run."""
