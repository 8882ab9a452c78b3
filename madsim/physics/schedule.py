"""When the driver is called: madsim's exact 20 ms ticks, or TORCS's own 20-or-22 ms schedule.

TORCS 1.3.7's race engine advances its simulated clock in steps of 0.002 s held in a C double and
calls the robots once `currentTime - lastTime >= 0.02` (both doubles). The sum of 0.002s drifts
from the exact multiples, so that test sometimes fails after 10 steps and the call comes one
step later: 11 steps (0.022 s). With the clock started at -1.002 s (the countdown), this
reproduces the time of every message in the real-TORCS traces exactly, countdown included (the
call just before the green light, at -0.002 s, is not answered: the first racing message comes
at +0.018 s). Over the first two minutes about one call in six is 22 ms late; after that the
sum settles and every call is 20 ms apart.

`TorcsClock().substeps()` gives the number of 0.002 s sub-steps before each next racing message
(10 or 11), to hand to `World.step(controls, substeps)`; `FixedClock` always gives 10.
"""

from __future__ import annotations

TORCS_DT = 0.002
"""TORCS's simulation step, s (RCM_MAX_DT_SIMU)."""
TORCS_ROBOT_DT = 0.02
"""TORCS's minimum time between two robot calls, s (RCM_MAX_DT_ROBOTS)."""
TORCS_CLOCK_START = -1.002
"""Race-engine clock at the first countdown step, s (found by matching the traces' curLapTime)."""
FIRST_MESSAGE_TIME = 0.018
"""Race time of TORCS's first racing message, s: madsim's message at reset stands for it."""

SCHEDULES = ("fixed", "torcs")


class FixedClock:
    """madsim's default: every tick is 10 sub-steps (0.02 s)."""

    name = "fixed"

    def reset(self) -> None:
        pass

    def substeps(self) -> int:
        return 10


class TorcsClock:
    """TORCS's driver-call schedule from the green light on: `substeps()` returns the number of
    0.002 s simulation steps to the next call (10 or 11), in order. Deterministic (plain double
    arithmetic as TORCS's); `reset()` starts over at the first racing message."""

    name = "torcs"

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        self._t = self._last = self.time = TORCS_CLOCK_START
        while self.time < -0.01:     # the countdown calls, up to the one just before the green light
            self.substeps()
        self.substeps()              # the first racing call (+0.018 s): madsim's reset state

    def substeps(self) -> int:
        """Sub-steps until the next driver call; advances the clock."""
        k = 0
        t, last = self._t, self._last
        while True:
            t += TORCS_DT
            k += 1
            if t - last >= TORCS_ROBOT_DT:
                break
        self._t, self._last = t, t
        self.time = t
        return k


def make_clock(schedule: str):
    """A clock by name: "fixed" (0.02 s, the default) or "torcs" (TORCS's 20/22 ms calls)."""
    if schedule == "fixed":
        return FixedClock()
    if schedule == "torcs":
        return TorcsClock()
    raise ValueError(f"tick schedule must be one of {SCHEDULES}, got {schedule!r}")
