"""The sync mode's usual ticks as one compiled loop: no Python between two ticks.

A tick of `madsim serve --mode sync` with every client answering is: look whether any stale
datagram is queued (one `poll`), send every car's state (`sendto`), read every car's answer
(`recvfrom`, blocking), run the compiled tick (`server_tick.server_tick`). `sync_ticks` does
exactly that, calling libc from the compiled code, tick after tick, and hands back to the
Python loop (`ScrServer._race`) whenever anything else must happen, before doing any part of
it that the Python loop would do differently:
- LIMIT: the tick limit or the wall-time budget is reached (so a stop request, a signal or
  `max_ticks` are looked at in time); nothing of the next tick is done;
- STALE: a datagram is queued before the states go out (the Python loop drains it and sends);
- PENDING: the states went out and the cars before `order[result[1]]` answered, but that car's
  `recvfrom` failed (receive timeout, a signal: result[2] = 0) or brought a datagram from
  another address (dropped: result[2] = 1); result[3]: the ns that car has been waited for
  (since the answer before it, or the sends); the Python loop waits for the rest;
- TICK: a tick ran and `server_tick` returned result[1] != DONE (a stage left to Python, or
  DONE | EVENT: the bookkeeping has work).
The bytes on the wire, their order and the World's trajectory are those of the Python loop.
The kernel runs without the GIL (other threads, e.g. a client in the same process, go on).
Linux only (`SUPPORTED`): the `sockaddr_in` layout and the clock id are Linux's; elsewhere the
server keeps the Python loop.
"""

from __future__ import annotations

import socket
import sys

import numba
import numpy as np
from numba.core import types

from madsim.net.server_tick import DONE, server_tick

LIMIT, STALE, PENDING, TICK = 0, 1, 2, 3
SUPPORTED = sys.platform.startswith("linux")
SOCKADDR_IN_BYTES = 16
CLOCK_MONOTONIC = 1          # Linux's clockid_t, as time.monotonic uses
POLLIN = 1

# libc, declared for the compiled code (resolved by name at load time, so the kernel caches)
_poll = types.ExternalFunction("poll", types.intc(types.voidptr, types.uint64, types.intc))
_sendto = types.ExternalFunction("sendto", types.intp(types.intc, types.voidptr, types.uintp, types.intc,
                                                      types.voidptr, types.uint32))
_recvfrom = types.ExternalFunction("recvfrom", types.intp(types.intc, types.voidptr, types.uintp, types.intc,
                                                          types.voidptr, types.voidptr))
_clock_gettime = types.ExternalFunction("clock_gettime", types.intc(types.intc, types.voidptr))


@numba.njit(cache=True, inline="always")
def _now_ns(timespec):
    _clock_gettime(CLOCK_MONOTONIC, timespec.ctypes.data)
    return timespec[0] * 1_000_000_000 + timespec[1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def sync_ticks(limit, budget_ns, nsub, fds, pollfds, peers, order, inbox, inlen, out, out_len, scratch,
               result, st, snap, table, dt, fuel_on, length, half_width, max_range, max_bytes, max_damage,
               max_lap_s):
    """Up to `limit` sync ticks, for at most about `budget_ns` of wall time; returns the ticks
    run (a TICK hand-back counts its tick) and leaves in result (4,) int64 why it stopped and
    its arguments (module docstring).

    fds (N,) the cars' socket descriptors; pollfds (M, 2) int32 `struct pollfd`s of the cars in
    the race, `order` (M,) their indices in sending order; peers (N, 2) int64 each client's
    `sockaddr_in` as two int64s; inbox (N, B) uint8 / inlen (N,): the answers (as the Python
    loop fills them); out (N, W) uint8 / out_len (N,): the state messages to send (with their
    NUL); scratch (6,) int64: the sender's address (2), its length, the ticks this loop has run
    in the race (cumulative: in memory at once, so a signal between the call's return and the
    caller's bookkeeping loses none), a timespec (2).
    The rest are `server_tick`'s arguments after `nsub` (ServerTick.args)."""
    m = order.shape[0]
    src = scratch[:2]
    srclen = scratch[2:3]
    timespec = scratch[4:6]
    start = now = _now_ns(timespec)
    ticks = 0
    result[0] = LIMIT
    while ticks < limit:
        if _poll(pollfds.ctypes.data, m, 0) != 0:      # something queued (or poll failed)
            result[0] = STALE
            return ticks
        for k in range(m):
            i = order[k]
            _sendto(fds[i], out.ctypes.data + i * out.strides[0], out_len[i], 0,
                    peers.ctypes.data + i * peers.strides[0], SOCKADDR_IN_BYTES)
        for k in range(m):
            i = order[k]
            srclen[0] = SOCKADDR_IN_BYTES
            n = _recvfrom(fds[i], inbox.ctypes.data + i * inbox.strides[0], inbox.shape[1], 0,
                          src.ctypes.data, srclen.ctypes.data)
            # sockaddr_in: family, port and address are its first 8 bytes, the rest is padding
            if n < 0 or src[0] != peers[i, 0]:
                result[0] = PENDING
                result[1] = k
                result[2] = 0 if n < 0 else 1
                result[3] = _now_ns(timespec) - now     # since its wait began
                return ticks
            inlen[i] = n
            now = _now_ns(timespec)                     # the next car's wait begins
        # typed as ServerTick.run passes them (int64, bool), not as literals: one compile
        status = server_tick(np.int64(0), np.int64(DONE), np.bool_(True), np.bool_(True), nsub, st, snap,
                             table, dt, fuel_on, length, half_width, max_range, max_bytes, max_damage,
                             max_lap_s)
        ticks += 1
        scratch[3] += 1
        if status != DONE:
            result[0] = TICK
            result[1] = status
            return ticks
        now = _now_ns(timespec)
        if now - start >= budget_ns:
            return ticks
    return ticks


def sockaddr_in(addr: tuple[str, int]) -> np.ndarray:
    """The `struct sockaddr_in` of an IPv4 (host, port) as recvfrom fills it, viewed as (2,)
    int64."""
    raw = np.zeros(SOCKADDR_IN_BYTES, dtype=np.uint8)
    raw[:2] = np.array([socket.AF_INET], dtype=np.uint16).view(np.uint8)   # host byte order
    raw[2:4] = np.frombuffer(int(addr[1]).to_bytes(2, "big"), dtype=np.uint8)
    raw[4:8] = np.frombuffer(socket.inet_aton(addr[0]), dtype=np.uint8)
    return raw.view(np.int64)


class SyncLoop:
    """`sync_ticks` for one race: its arrays and the call. `fds` and `addrs`: every car's
    socket descriptor and its client's (host, port); `race`: the race's ServerTick; `nsub`: the
    sub-steps of every tick; `budget_s`: the longest run of ticks between two looks of the
    Python loop (at a stop request, a signal)."""

    def __init__(self, fds: list[int], addrs: list[tuple[str, int]], race, nsub: int,
                 budget_s: float = 0.02):
        self.race = race
        self.nsub = int(nsub)
        self.budget_ns = int(budget_s * 1e9)
        self.fds = np.array(fds, dtype=np.int32)
        self.peers = np.stack([sockaddr_in(a) for a in addrs])
        self.scratch = np.zeros(6, dtype=np.int64)
        self.result = np.zeros(4, dtype=np.int64)
        self.set_cars(range(len(fds)))

    @property
    def ticks_run(self) -> int:
        """Ticks this loop has run in the race so far, a TICK hand-back's included (a PENDING
        hand-back's tick is finished and counted by the Python loop)."""
        return int(self.scratch[3])

    def set_cars(self, indices) -> None:
        """The cars still in the race (indices, in sending order)."""
        self.order = np.array(list(indices), dtype=np.int64)
        self.pollfds = np.zeros((len(self.order), 2), dtype=np.int32)   # fd; events | revents << 16
        self.pollfds[:, 0] = self.fds[self.order]
        self.pollfds[:, 1] = POLLIN

    def run(self, limit: int) -> tuple[int, int, int, int, float]:
        """Up to `limit` ticks: (ticks run, LIMIT / STALE / PENDING / TICK, its argument,
        PENDING's foreign flag, PENDING's wait so far in s); see `sync_ticks`."""
        race = self.race
        ticks = sync_ticks(limit, self.budget_ns, self.nsub, self.fds, self.pollfds, self.peers, self.order,
                           race.inbox, race.inlen, race.out, race.out_len, self.scratch, self.result,
                           *race.args)
        why, arg, flag, waited_ns = self.result.tolist()
        return ticks, why, arg, flag, waited_ns * 1e-9
