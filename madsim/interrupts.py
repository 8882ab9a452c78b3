"""Ctrl-C and SIGTERM for long commands: finish the step, write what was done, exit with one line.

    with StopRequest() as stop:
        for ...:
            if stop:            # a SIGINT or SIGTERM arrived: leave the loop cleanly
                break
    if stop: ...                # stop.signal_name, stop.exit_status (130 / 143)

The first signal only sets the flag, so a file being written (an MP4 frame going to ffmpeg,
a checkpoint) is never cut in half; a second one raises KeyboardInterrupt at once. With
`grace_s`, a loop that does not look at the flag within that time (numba compiling a kernel,
a long library call) gets KeyboardInterrupt then, so the command still ends promptly. Outside
the main thread (where handlers cannot be installed) the object is a flag nobody sets.
"""

from __future__ import annotations

import _thread
import signal
import threading

__all__ = ["StopRequest", "exit_now"]


class StopRequest:
    """A flag set by SIGINT or SIGTERM while the `with` block runs; truthy once set."""

    def __init__(self, on_stop=None, grace_s: float | None = None,
                 signals: tuple = (signal.SIGINT, signal.SIGTERM)):
        """on_stop: called (from the signal handler) when the first signal arrives, e.g. a
        server's thread-safe `stop`; grace_s: then interrupt the main thread after this long;
        signals: the ones to catch (the others keep their handlers)."""
        self.signals = tuple(signals)
        self.signum: int | None = None
        self.on_stop = on_stop
        self.grace_s = grace_s
        self._previous: dict = {}
        self._timer: threading.Timer | None = None

    def __bool__(self) -> bool:
        return self.signum is not None

    @property
    def signal_name(self) -> str:
        return signal.Signals(self.signum).name if self.signum else ""

    @property
    def exit_status(self) -> int:
        """The shell's status for death by this signal: 128 + signal number."""
        return 128 + (self.signum or 0)

    def _handle(self, signum, frame) -> None:
        if self.signum is not None:
            raise KeyboardInterrupt
        self.signum = signum
        if self.on_stop is not None:
            self.on_stop()
        if self.grace_s is not None:
            self._timer = threading.Timer(self.grace_s, _thread.interrupt_main)
            self._timer.daemon = True
            self._timer.start()

    def settle(self) -> None:
        """The loop has stopped: cancel the pending grace interrupt (the files can be written)."""
        if self._timer is not None:
            self._timer.cancel()

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for s in self.signals:
                self._previous[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        self.settle()
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self._previous = {}


def exit_now(status: int) -> None:
    """End the process at once after an interrupt, the files being written and closed: run the
    atexit handlers, flush stdout/stderr, skip the interpreter's teardown (with torch loaded it
    takes 1-3 s on a busy machine, past the 2 s an interrupted command has)."""
    import atexit
    import os
    import sys

    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)
