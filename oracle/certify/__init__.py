"""The oracle certifies its backend: a battery of closed-form checks (:mod:`.battery`) and
per-machine verdicts that decide which backend the command line trusts (:mod:`.verdict`)."""

from .battery import CHECKS, Check, run_battery
from .verdict import BackendRefused, cached_verdict, certified_select, run_check

__all__ = [
    "CHECKS",
    "BackendRefused",
    "Check",
    "cached_verdict",
    "certified_select",
    "run_battery",
    "run_check",
]
