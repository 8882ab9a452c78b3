"""Facts several layers share, stated once: the tick, the SCR sensor fields, rangefinder angles,
the SCR sample driver's gear rule.

The physics (`World`), the sensors (`SensorFrame`), the wire codec (`madsim.net.protocol`) and
the generated docs (`madsim.docs`) all read these; none of them restates them. Imports nothing.
"""

from __future__ import annotations

from typing import NamedTuple

# --- time -----------------------------------------------------------------------------------

SUBSTEP_S = 0.002
"""Physics sub-step, s (TORCS's simulation step)."""
SUBSTEPS_PER_TICK = 10
"""Sub-steps per tick: controls are held for one tick."""
TICK_S = SUBSTEP_S * SUBSTEPS_PER_TICK
"""One tick, s (0.02): a World.step, one SCR state/control exchange, one env step per action
repeat."""


# --- the SCR sensor set (spec/scr-protocol.md section 5) ---------------------------------------

class ScrField(NamedTuple):
    """One field of the SCR state message: name on the wire, number of values, C type
    ('float' or 'int'), unit as SCR reports it, and what it measures."""

    name: str
    width: int
    kind: str
    unit: str
    meaning: str


SCR_FIELDS = (
    ScrField("angle", 1, "float", "rad",
             "track tangent minus car yaw, in (-pi, pi]; positive when the car points right of the track"),
    ScrField("curLapTime", 1, "float", "s",
             "time since the current lap started (the first lap's timer runs from the race start)"),
    ScrField("damage", 1, "int", "points (int)", "accumulated collision damage"),
    ScrField("distFromStart", 1, "float", "m", "distance along the centre line from the start line, [0, L)"),
    ScrField("distRaced", 1, "float", "m",
             "distance driven since the race start (grows backwards when reversing)"),
    ScrField("fuel", 1, "float", "l (kg)", "fuel in the tank"),
    ScrField("gear", 1, "int", "int", "engaged gear: -1 reverse, 0 neutral, 1..6"),
    ScrField("lastLapTime", 1, "float", "s", "time of the last completed lap; 0 before the first"),
    ScrField("opponents", 36, "float", "m",
             "nearest other car in each 10-degree sector clockwise from dead astern, 200 if none"),
    ScrField("racePos", 1, "int", "int", "race position, 1 = leading (laps, then distance)"),
    ScrField("rpm", 1, "float", "rad/s x 10", "engine speed as SCR reports it (about 1.047 x true rpm)"),
    ScrField("speedX", 1, "float", "km/h", "longitudinal speed in the car frame, forward positive"),
    ScrField("speedY", 1, "float", "km/h", "lateral speed in the car frame, left positive"),
    ScrField("speedZ", 1, "float", "km/h", "the body's vertical velocity, up positive (TORCS's `DynGC.vel.z`)"),
    ScrField("track", 19, "float", "m",
             "19 rangefinders to the road edges at the client's angles (positive = clockwise), "
             "200 m range; all -1 when off the road"),
    ScrField("trackPos", 1, "float", "-", "lateral position: 0 on the centre line, +1 left edge, -1 right edge"),
    ScrField("wheelSpinVel", 4, "float", "rad/s",
             "wheel spin, TORCS order front-right, front-left, rear-right, rear-left"),
    ScrField("z", 1, "float", "m", "height of the car's centre of gravity above the road"),
    ScrField("focus", 5, "float", "m",
             "5 rays at focus-2..focus+2 degrees; one valid reading per simulated second, else -1"),
)
"""The SRV13 state message's fields in wire order; gear, racePos and damage are C ints."""

SCR_VALUE_COUNT = sum(f.width for f in SCR_FIELDS)
"""Numbers per state message (79)."""


# --- rangefinder angle sets, deg (positive = clockwise, 0 = straight ahead) --------------------

SCR_SERVER_DEFAULT_ANGLES_DEG = tuple(-90.0 + 10.0 * i for i in range(19))
"""What scr_server uses when a client's `(init ...)` is missing or short: -90..90 step 10."""
SCR_CPP_CLIENT_ANGLES_DEG = (-90.0, -75.0, -60.0, -45.0, -30.0, -20.0, -15.0, -10.0, -5.0, 0.0,
                             5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0)
"""What the SCR C++ client sends in its identification (and madsim's in-process default)."""
SNAKEOIL_ANGLES_DEG = (-45.0, -19.0, -12.0, -7.0, -4.0, -2.5, -1.7, -1.0, -0.5, 0.0,
                       0.5, 1.0, 1.7, 2.5, 4.0, 7.0, 12.0, 19.0, 45.0)
"""What gym_torcs' and MADRaS' snakeoil3 client sends."""


# --- the SCR championship sample driver's gearbox (SimpleDriver) ------------------------------

SAMPLE_GEAR_UP_RPM = (5000.0, 6000.0, 6000.0, 6500.0, 7000.0)
"""SCR `rpm` (engine rad/s x 10) at or above which gears 1..5 shift up."""
SAMPLE_GEAR_DOWN_RPM = (2500.0, 3000.0, 3000.0, 3500.0, 3500.0)
"""SCR `rpm` at or below which gears 2..6 shift down."""


def rpm_gear(gear: int, rpm: float) -> int:
    """The SCR sample driver's rule: next gear from the current gear and SCR `rpm`. Neutral or
    reverse go to first; shift up at 5000/6000/6000/6500/7000 from gears 1-5, down at
    2500/3000/3000/3500/3500 from gears 2-6."""
    gear = int(gear)
    if gear < 1:
        return 1
    if gear < 6 and rpm >= SAMPLE_GEAR_UP_RPM[gear - 1]:
        return gear + 1
    if gear > 1 and rpm <= SAMPLE_GEAR_DOWN_RPM[gear - 2]:
        return gear - 1
    return gear
