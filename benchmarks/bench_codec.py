"""SCR codec speed, microseconds per call (one line per figure).

Run: python benchmarks/bench_codec.py
Inputs are the spec's example messages (spec/scr-protocol.md section 13) and stock-client
control messages; each figure is the best of 7 runs of N calls.
"""

from __future__ import annotations

import time
import timeit

import numba
import numpy as np

from madsim.net import codec_kernels as K
from madsim.net import protocol as P

N = 20_000

STATE = (
    b"(angle 0.0412)(curLapTime 31.74)(damage 0)(distFromStart 742.318)(distRaced 767.902)"
    b"(fuel 93.6118)(gear 3)(lastLapTime 0)(opponents 198.127 201.222 199.816 202.084 197.431 "
    b"201.235 201.577 197.355 206.87 202.226 204.788 197.519 197.042 198.624 199.574 202.528 "
    b"200.994 23.358 196.172 197.918 204.884 196.768 200.979 201.706 194.041 200.194 205.225 "
    b"191.943 198.714 199.575 196.731 201.99 199.751 194.141 203.311 202.677)(racePos 2)"
    b"(rpm 6891.33)(speedX 118.472)(speedY -1.93125)(speedZ -0.0287413)(track 6.1388 6.85581 "
    b"7.11014 8.62883 11.4282 18.0271 27.0479 37.8191 79.7794 98.7994 44.1286 21.7023 11.9139 "
    b"11.7433 7.77472 5.4936 3.54977 3.16252 3.37084)(trackPos -0.26)(wheelSpinVel 100.131 "
    b"100.402 101.937 102.211)(z 0.337149)(focus 43.5077 45.5468 46.9695 48.9583 50.5348)\0")
CPP_CONTROLS = b"(accel 1)(brake 0)(gear 2)(steer -0.0123457)(clutch 0)(focus 0)(meta 0)\0"
SNAKEOIL_CONTROLS = (b"(accel 0.200)(brake 0.000)(clutch 0.000)(gear 1.000)(steer 0.000)"
                     b"(focus -90 -45 0 45 90)(meta 0.000)")
INIT = b"SCR(init -45 -19 -12 -7 -4 -2.5 -1.7 -1 -.5 0 .5 1 1.7 2.5 4 7 12 19 45)"


def us_per_call(fn, *args) -> float:
    best = min(timeit.repeat(lambda: fn(*args), number=N, repeat=7))
    return best / N * 1e6


@numba.njit
def _encode_many(count, rows, is_int, lit, lit_end, max_bytes, out, length):
    for _ in range(count):
        K.encode_rows(rows, is_int, lit, lit_end, max_bytes, out, length)


def kernel_us(row: np.ndarray) -> float:
    """The server tick's encoder (`codec_kernels.encode_rows`) on one row, called from a
    compiled loop as the server's tick calls it: us per message, best of 30 runs of 2,000 (short
    runs: on a shared machine a longer one is mostly preempted)."""
    enc = P.STATE_ENCODER
    rows = row[None, :].astype(np.float64)
    out = np.zeros((1, enc.message_width), dtype=np.uint8)
    length = np.zeros(1, dtype=np.int64)
    args = (rows, *enc.kernel_args(), out, length)
    _encode_many(1, *args)
    best = float("inf")
    for _ in range(30):
        t0 = time.perf_counter()
        _encode_many(2000, *args)
        best = min(best, time.perf_counter() - t0)
    return best / 2000 * 1e6


def main() -> None:
    values = P.decode_sensors(STATE)  # Python floats, as a SensorFrame row would give
    row32 = np.concatenate([np.atleast_1d(np.asarray(values[f.name], dtype=np.float32))
                            for f in P.SENSOR_FIELDS])
    print(f"encode_sensors (mapping of floats/lists, {len(STATE)} B): "
          f"{us_per_call(P.encode_sensors, values):.2f} us/call")
    print(f"encode_sensors_flat (float32 row of 79): "
          f"{us_per_call(P.encode_sensors_flat, row32):.2f} us/call")
    print(f"encode_rows kernel, compiled caller (one car, spec example): {kernel_us(row32):.3f} us/message")
    one_car = row32.copy()
    o = sum(f.width for f in P.SENSOR_FIELDS[:[f.name for f in P.SENSOR_FIELDS].index("opponents")])
    one_car[o:o + 36] = 200.0
    print(f"encode_rows kernel, compiled caller (alone: opponents at 200): {kernel_us(one_car):.3f} us/message")
    print(f"decode_controls (C++ client message): "
          f"{us_per_call(P.decode_controls, CPP_CONTROLS):.2f} us/call")
    print(f"decode_controls (snakeoil message): "
          f"{us_per_call(P.decode_controls, SNAKEOIL_CONTROLS):.2f} us/call")
    print(f"decode_controls (general path, C++ message): "
          f"{us_per_call(P._decode_controls_general, CPP_CONTROLS):.2f} us/call")
    print(f"parse_init (snakeoil init): {us_per_call(P.parse_init, INIT):.2f} us/call")
    print(f"decode_sensors (client side): {us_per_call(P.decode_sensors, STATE):.2f} us/call")
    print(f"encode_controls (client side, cpp style): "
          f"{us_per_call(P.encode_controls, 1.0, 0.0, 2, -0.0123457, 0.0, 0, 0):.2f} us/call")


if __name__ == "__main__":
    main()
