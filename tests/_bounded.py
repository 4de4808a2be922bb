"""Run a call under a time limit: a hang fails the test instead of stalling the run.

The call runs in a daemon thread; when it has not returned after ``seconds`` the test fails
naming it (the stuck thread, e.g. blocked opening a FIFO, cannot keep the process alive).
"""

from __future__ import annotations

import threading

import pytest

#: Every hostile-input case ends within this many seconds.
CASE_SECONDS = 20.0


def bounded(fn, *args, seconds: float = CASE_SECONDS, **kwargs):
    """``fn(*args, **kwargs)``'s value (or its exception, raised here) within ``seconds``."""
    box: dict = {}

    def run():
        try:
            box["value"] = fn(*args, **kwargs)
        except BaseException as exc:  # handed to the caller's thread as it is
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        pytest.fail(f"{getattr(fn, '__name__', fn)} did not end within {seconds} s (a hang)")
    if "error" in box:
        raise box["error"]
    return box.get("value")
