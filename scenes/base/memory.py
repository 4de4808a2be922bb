"""The memory this machine has free now, for size estimates made before allocating."""

from __future__ import annotations

import os

__all__ = ["available_memory", "gib"]


def available_memory() -> int:
    """Bytes available to a new allocation: ``MemAvailable`` of ``/proc/meminfo`` (Linux),
    else the physical memory."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def gib(n: int) -> str:
    """``n`` bytes as GiB (or MiB below one GiB), for messages."""
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"
