"""A snakeoil-compatible SCR client: drives madsim's server or real TORCS' scr_server.

It follows the protocol spec (`spec/scr-protocol.md`), not any quirk of madsim's server:
identification with one re-send per `timeout_s` (§3, §4.4), exactly one control message per
state message (a second one would shift every later command by a tick, §4.2), no re-sending on
silence, `***restart***` / `***shutdown***` handling (§7), and both identification replies,
`***identified***` and MADRaS' `***identified***:<pid>` (§12.1).

    with ScrClient(port=3001) as client:
        result = client.run(simple_driver, max_steps=5000)
"""

from __future__ import annotations

import logging
import math
import socket
import time
from typing import Any, Callable, Mapping, NamedTuple, Sequence

from madsim.facts import rpm_gear
from madsim.net.protocol import (
    RESTART,
    SHUTDOWN,
    SNAKEOIL_ANGLES_DEG,
    ProtocolError,
    decode_sensors,
    encode_controls,
    encode_init,
    parse_identified,
)

__all__ = ["ScrClient", "ScrTimeout", "RunResult", "simple_driver", "STEER_LOCK_RAD"]

log = logging.getLogger(__name__)

_CONTROL_KEYS = ("accel", "brake", "gear", "steer", "clutch", "focus", "meta")


class ScrTimeout(ProtocolError, TimeoutError):
    """The server stayed silent for longer than the client's bounded number of waits."""


class RunResult(NamedTuple):
    """How `ScrClient.run` ended: 'restart', 'shutdown' or 'max_steps'; control messages sent."""

    status: str
    steps: int


class ScrClient:
    """One car's UDP client for an scr_server port (IPv4).

    Arguments: `host`, `port` of the server instance (3001 + car index for TORCS/madsim, 3101
    for gym_torcs' vtorcs); `client_id` (must start with 'SCR'); `angles_deg`, the 19
    rangefinder directions requested (default: snakeoil's list); `timeout_s`, one wait for a
    datagram (1 s like every stock client); `identify_tries`, init datagrams sent before giving
    up (None: forever); `silent_tries`, consecutive `timeout_s` waits without a state message
    before `receive` gives up (None: forever); `style`, control text layout 'cpp' or 'snakeoil'.

    State after `receive()` returned None: `event` is 'restart' or 'shutdown' and the client is
    no longer identified; after a restart the server waits for every client to identify again.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 3001, *, client_id: str = "SCR",
                 angles_deg: Sequence[float] = SNAKEOIL_ANGLES_DEG, timeout_s: float = 1.0,
                 identify_tries: int | None = 60, silent_tries: int | None = 60,
                 style: str = "cpp", recv_bytes: int = 2**17):
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be > 0, got {timeout_s}")
        self.address = (socket.gethostbyname(host), int(port))  # IPv4, resolved once
        self.init_message = encode_init(client_id, angles_deg)  # validates id and angles
        self.timeout_s = float(timeout_s)
        self.identify_tries = identify_tries
        self.silent_tries = silent_tries
        self.style = style
        encode_controls(style=style)  # reject an unknown style now, not at the first tick
        self.recv_bytes = recv_bytes
        self.identified = False
        self.server_pid: int | None = None
        self.event: str | None = None
        self.steps = 0
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    # -- lifecycle --------------------------------------------------------------------------
    def close(self) -> None:
        """Close the socket (the server is not told; TORCS notices nothing)."""
        self._sock.close()

    def __enter__(self) -> "ScrClient":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _wait(self, timeout_s: float) -> bytes | None:
        """One datagram, or None after `timeout_s` of silence."""
        started = time.monotonic()
        self._sock.settimeout(max(timeout_s, 1e-6))
        try:
            data, _ = self._sock.recvfrom(self.recv_bytes)
            return data
        except (socket.timeout, TimeoutError):
            return None
        except ConnectionError:  # ICMP port unreachable (Windows): wait out the period
            time.sleep(max(0.0, timeout_s - (time.monotonic() - started)))
            return None

    def _drain(self) -> None:
        """Drop datagrams left from an earlier race before identifying again."""
        self._sock.setblocking(False)
        try:
            while True:
                self._sock.recvfrom(self.recv_bytes)
        except (BlockingIOError, ConnectionError):
            pass
        finally:
            self._sock.setblocking(True)

    # -- protocol ---------------------------------------------------------------------------
    def identify(self) -> int | None:
        """Send `<id>(init ...)` once per `timeout_s` until the server answers.

        Returns the server's pid from a `***identified***:<pid>` reply, or None for the plain
        reply. Raises ScrTimeout after `identify_tries` unanswered sends (a server that is
        mid-race never answers until its next race, §3.6).
        """
        self._drain()
        self.event = None
        tries = 0
        while self.identify_tries is None or tries < self.identify_tries:
            self._sock.sendto(self.init_message, self.address)
            tries += 1
            deadline = time.monotonic() + self.timeout_s
            while True:
                data = self._wait(deadline - time.monotonic())
                if data is None:
                    break
                reply = parse_identified(data)
                if reply is not None:
                    self.identified = True
                    self.server_pid = reply.pid
                    log.info("identified by %s:%d%s", *self.address,
                             "" if reply.pid is None else f" (server pid {reply.pid})")
                    return reply.pid
                if time.monotonic() >= deadline:  # stray datagrams: re-send on schedule
                    break
            log.info("no identification from %s:%d yet (try %d)", *self.address, tries)
        raise ScrTimeout(f"server {self.address[0]}:{self.address[1]} did not answer "
                         f"{tries} identification requests in {tries * self.timeout_s:g} s")

    def receive(self) -> dict[str, Any] | None:
        """Wait for the next state message and return it as {SCR name: value}.

        Returns None when the server sent `***restart***` or `***shutdown***` (see `event`).
        Never re-sends anything while waiting; raises ScrTimeout after `silent_tries`
        consecutive silent periods and ProtocolError on a malformed state message.
        """
        silent = 0
        while True:
            data = self._wait(self.timeout_s)
            if data is None:
                silent += 1
                log.info("server did not respond in %g s", self.timeout_s)
                if self.silent_tries is not None and silent >= self.silent_tries:
                    raise ScrTimeout(f"no state from {self.address[0]}:{self.address[1]} in "
                                     f"{silent * self.timeout_s:g} s")
                continue
            if data[:3] == b"***":
                word = data.split(b"\0", 1)[0]
                if word == RESTART or word == SHUTDOWN:
                    self.event = "restart" if word == RESTART else "shutdown"
                    self.identified = False
                    log.info("server sent %s", word.decode())
                    return None
                if parse_identified(data) is not None:
                    continue  # a late duplicate answer to a re-sent init
            return decode_sensors(data)

    def send(self, controls: Mapping[str, Any]) -> None:
        """Send one control message; missing keys take the server defaults (gear 1!)."""
        unknown = set(controls) - set(_CONTROL_KEYS)
        if unknown:
            raise ProtocolError(f"unknown control(s) {sorted(unknown)}; valid: "
                                f"{', '.join(_CONTROL_KEYS)}", field=sorted(unknown)[0])
        self._sock.sendto(encode_controls(**controls, style=self.style), self.address)
        self.steps += 1

    def run(self, driver: Callable[[dict[str, Any]], Mapping[str, Any]],
            max_steps: int | None = None, *, reidentify_on_restart: bool = True) -> RunResult:
        """Drive: identify if needed, then answer every state with `driver(state)`.

        Ends on `***shutdown***`, on `***restart***` unless `reidentify_on_restart` (then it
        identifies again and goes on, like the C++ client), or after `max_steps` answers.
        """
        steps = 0
        if not self.identified:
            self.identify()
        while max_steps is None or steps < max_steps:
            state = self.receive()
            if state is None:
                if self.event == "restart" and reidentify_on_restart:
                    self.identify()
                    continue
                return RunResult(self.event or "shutdown", steps)
            self.send(driver(state))
            steps += 1
        return RunResult("max_steps", steps)


STEER_LOCK_RAD = 0.366519  # car1-trb1, the C++ SimpleDriver's value (§9)


def simple_driver(state: Mapping[str, Any], target_speed_kmh: float = 100.0) -> dict[str, Any]:
    """A minimal driver: steer to the track axis, hold a target speed, shift by rpm.

    Steer = (angle - 0.5 trackPos) / steer lock (angle > 0: car points right of the track, so
    steer left = positive; trackPos > 0: car left of centre, so steer right). The speed target
    drops before bends: the longest of the three forward rangefinders gives the free road d
    ahead and the target is capped at sqrt(2 a d) with a = 5 m/s^2 (a safe braking rate), but
    not below 30 km/h. Throttle is proportional to the speed error, brake above target + 5 km/h;
    gears by the SCR sample driver's rpm rule (`madsim.facts.rpm_gear`; rpm = rad/s x 10).
    """
    angle = float(state["angle"])
    track_pos = float(state["trackPos"])
    speed = float(state["speedX"])
    rpm = float(state["rpm"])
    gear = int(state["gear"])
    steer = (angle - 0.5 * track_pos) / STEER_LOCK_RAD
    steer = max(-1.0, min(1.0, steer)) if math.isfinite(steer) else 0.0
    rays = state.get("track")
    if rays is not None and len(rays) == 19 and min(rays) >= 0:
        ahead = max(float(rays[8]), float(rays[9]), float(rays[10]))
        target_speed_kmh = min(target_speed_kmh, max(30.0, 3.6 * math.sqrt(2.0 * 5.0 * ahead)))
    error = target_speed_kmh - speed
    accel = max(0.0, min(1.0, error / 20.0 + 0.2)) if error > 0 else 0.0
    brake = max(0.0, min(1.0, (-error - 5.0) / 20.0)) if error < -5.0 else 0.0
    return {"accel": accel, "brake": brake, "gear": rpm_gear(gear, rpm), "steer": steer, "clutch": 0.0,
            "focus": 0, "meta": 0}
