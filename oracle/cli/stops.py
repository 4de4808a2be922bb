"""Stopping a command within a second or two in every phase, without a traceback (issue 48).

SIGTERM unwinds the command (``SystemExit(143)``) and SIGINT interrupts it
(``KeyboardInterrupt``, exit 130), so that ``finally`` blocks remove scratch folders and
staged outputs. Python runs a signal handler only when the main thread is back in the
interpreter: a long C call (Embree's BVH build of a large scene, a kernel) would delay the
stop by as long as it runs. A watchdog thread, woken by the signal itself
(:func:`signal.set_wakeup_fd`), ends the process when the handler has not run within
:data:`GRACE_S` seconds: this process's scratch folders removed, then ``os._exit`` with the
same status. Staged outputs (:func:`scenes.base.files.staged_folder`) and cache entries are
never half-moved: their temporary folders carry the pid and are swept by the next run; while
an output is being moved in, the watchdog waits for the moves.

While the libraries load (:meth:`Stops.deferred`), the handler does not unwind (an exception
raised inside an extension module's initialisation aborts the interpreter): the watchdog
ends the process at once.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager

from ...scenes.base.files import moves_in_progress

__all__ = ["GRACE_S", "Stops"]

#: Seconds the main thread has to take a signal before the watchdog ends the process.
GRACE_S = 1.0

_SIGNALS = (signal.SIGTERM, signal.SIGINT)


class Stops:
    """The signal handlers and watchdog of one command run (:meth:`install`, :meth:`remove`)."""

    def __init__(self, cleanup=None):
        self.cleanup = cleanup
        self.handled = threading.Event()
        self.deferring = False
        self.stopped: int | None = None
        self._previous: dict = {}
        self._pipe: tuple[int, int] | None = None
        self._wakeup = -1
        self._thread: threading.Thread | None = None

    def install(self) -> None:
        """Install the handlers and start the watchdog (main thread only; else nothing)."""
        if threading.current_thread() is not threading.main_thread():
            return
        r, w = os.pipe()
        os.set_blocking(w, False)
        try:
            self._wakeup = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        except ValueError:
            os.close(r)
            os.close(w)
            return
        self._pipe = (r, w)
        for signum in _SIGNALS:
            self._previous[signum] = signal.signal(signum, self._handle)
        self._thread = threading.Thread(target=self._watch, name="stop-watchdog", daemon=True)
        self._thread.start()

    def remove(self) -> None:
        """Restore the previous handlers and wake-up descriptor; stop the watchdog."""
        if self._pipe is None:
            return
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        signal.set_wakeup_fd(self._wakeup)
        r, w = self._pipe
        self._pipe = None
        os.write(w, b"\0")  # wakes the watchdog: 0 is no signal, it ends
        self._thread.join(timeout=5)
        os.close(r)
        os.close(w)

    def _handle(self, signum, frame):
        self.stopped = 128 + signum
        if self.deferring:
            return  # the watchdog ends the process (see the module's note)
        self.handled.set()
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        raise SystemExit(128 + signum)

    @contextmanager
    def deferred(self):
        """A phase in which a signal must not unwind Python code (library initialisation)."""
        self.deferring = True
        try:
            yield
        finally:
            self.deferring = False

    def _watch(self) -> None:
        r = self._pipe[0]
        while True:
            try:
                data = os.read(r, 64)
            except OSError:
                return
            signums = [b for b in data if b in _SIGNALS]
            if not data or 0 in data and not signums:
                return
            if not signums:
                continue
            if not self.deferring and self.handled.wait(GRACE_S):
                continue
            while moves_in_progress():  # an output being moved in: let it finish
                self.handled.wait(0.05)
            if self.handled.is_set() and not self.deferring:
                continue
            self._exit(128 + signums[0])

    def _exit(self, code: int) -> None:
        if self.cleanup is not None:
            try:
                self.cleanup()
            except Exception:  # noqa: BLE001 - ending anyway
                pass
        print(f"raster-oracle: {'interrupted' if code == 130 else 'terminated'}", file=sys.stderr)
        try:
            sys.stderr.flush()
            sys.stdout.flush()
        finally:
            os._exit(code)
