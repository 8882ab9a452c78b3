"""Ctrl-C and SIGTERM for long commands: finish the step, write what was done, exit with one line.

    with StopRequest() as stop:
        for ...:
            if stop:            # a SIGINT or SIGTERM arrived: leave the loop cleanly
                break
    if stop: ...                # stop.signal_name, stop.exit_status (130 / 143)

The first signal only sets the flag, so a file being written (an MP4 frame going to ffmpeg,
a checkpoint) is never cut in half; a second one raises KeyboardInterrupt at once. Outside the
main thread (where handlers cannot be installed) the object is a flag nobody sets.
"""

from __future__ import annotations

import signal
import threading

__all__ = ["StopRequest"]


class StopRequest:
    """A flag set by SIGINT or SIGTERM while the `with` block runs; truthy once set."""

    def __init__(self, on_stop=None):
        """on_stop: called (from the signal handler) when the first signal arrives, e.g. a
        server's thread-safe `stop`."""
        self.signum: int | None = None
        self.on_stop = on_stop
        self._previous: dict = {}

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

    def __enter__(self) -> StopRequest:
        if threading.current_thread() is threading.main_thread():
            for s in (signal.SIGINT, signal.SIGTERM):
                self._previous[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self._previous = {}
