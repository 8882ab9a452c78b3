"""Compiled SCR codec kernels: state rows -> message bytes, control bytes -> control values.

The server's per-tick codec without per-field Python. Both kernels work on the car axis first
and give up on a row (status -1) whenever exactness is not certain, so the caller re-does that
row with the exact Python codec in `madsim.net.protocol`; the result is byte-identical to it
(and so to the C++ scr_server: float32 values printed with glibc's `%g`).

`encode_rows`: a value is printed by rounding it to 6 significant digits in double arithmetic
(its decimal exponent found against a table of powers of ten, then one product by an exact
power of ten for every fixed-notation value). For a float32 value the scaled product is within
~1e-9 of the exact decimal expansion, so a rounding decision closer than `TIE_MARGIN` to a half
is left to the exact path (it happens for about one value in 10^8), as are non-finite values,
ints beyond 32 bits and over-long messages. The digits go out two at a time from a table.

`decode_controls_row`: the two stock control layouts (C++ client / pyScrcClient, and
snakeoil) with plain decimal numbers of at most 15 significant digits and small exponents,
where a double is exactly digits x 10^k with one rounding (then rounded to float32 as the
C++ server stores it); anything else is left to the exact path.
"""

from __future__ import annotations

import math

import numba
import numpy as np

MAX_DATAGRAM_BYTES = 1000  # receive buffer of the C++ server and clients (`UDP_MSGLEN`)
TIE_MARGIN = 1e-7          # |fraction - 0.5| below this: the exact path decides the rounding
MAX_VALUE_CHARS = 16       # the longest %g text of a float32 ("-1.23457e-05" is 12) or a C int

_POW10 = np.array([10.0 ** k for k in range(23)])   # exact doubles
_NO_REFCOUNT = {"_nrt": False}
"""The kernels allocate nothing: compiled without numba's array reference counts (as
physics.kernel.NO_REFCOUNT), which cost an atomic increment and decrement at every inlined
digit writer (a third of the encoder's time)."""
_POW10_UP = np.array([float("1e%d" % k) for k in range(40)])     # 10^k correctly rounded
_POW10_DOWN = np.array([float("1e-%d" % k) for k in range(47)])  # 10^-k correctly rounded
_PAIRS = np.frombuffer(b"".join(b"%02d" % k for k in range(100)), dtype=np.uint8).copy()
"""The two digits of 0..99: a table look-up writes two digits for one division by 100."""


# unsigned arithmetic for the digits: a division of a uint64 by a constant is a multiplication;
# a signed one with Python's floor semantics stays a hardware division, ~10x slower (a uint64
# mixed with an int64 is a float in numba, hence these typed constants)
U10, U100, U1000, U10000 = np.uint64(10), np.uint64(100), np.uint64(1000), np.uint64(10000)


@numba.njit(cache=True, inline="always")
def _pair(o, pos, d):
    """The two digits of 0 <= d < 100 (uint64) at o[pos:pos + 2]."""
    o[pos] = _PAIRS[d + d]
    o[pos + 1] = _PAIRS[d + d + np.uint64(1)]


@numba.njit(cache=True, **_NO_REFCOUNT, error_model="numpy")
def _put_int(o, pos, q):
    """Decimal digits of 0 <= q < 2^31 at o[pos:]; returns the new end."""
    u = np.uint64(q)
    if u < U10:
        o[pos] = 48 + u
        return pos + 1
    if u < U100:
        _pair(o, pos, u)
        return pos + 2
    n = 3
    t = u // U1000
    while t > 0:
        n += 1
        t //= U10
    p = pos + n
    while u >= U100:      # two digits per division, from the last
        p -= 2
        r = u // U100
        _pair(o, p, u - U100 * r)
        u = r
    if u >= U10:
        _pair(o, p - 2, u)
    else:
        o[p - 1] = 48 + u
    return pos + n


@numba.njit(cache=True, inline="always")
def _decimal_exponent(a):
    """e with 10^e <= a < 10^(e+1) for a float32 magnitude a > 0 (against correctly rounded
    powers: off by one at most where a is within an ulp of one; `_put_g` corrects that)."""
    if a >= 1.0:
        e = 0
        while e < 39 and a >= _POW10_UP[e + 1]:
            e += 1
        return e
    e = -1
    while e > -46 and a < _POW10_DOWN[-e]:
        e -= 1
    return e


@numba.njit(cache=True, inline="always")
def _scaled(a, p):
    """a * 10^p (a > 0): one rounding for |p| <= 22 (every fixed-notation %g value has
    0 <= p <= 9: a product by an exact power), a few beyond."""
    if 0 <= p <= 22:
        return a * _POW10[p]
    if -22 <= p < 0:
        return a / _POW10[-p]
    while p > 22:
        a *= 1e22
        p -= 22
    while p < -22:
        a /= 1e22
        p += 22
    return a * _POW10[p] if p >= 0 else a / _POW10[-p]


@numba.njit(cache=True, inline="always")
def _put_g(o, pos, f):
    """C `printf("%g", f)` of a finite double `f` at o[pos:] (o needs 13 bytes there); returns
    the new end, or -1 when the 6-digit rounding is too close to a tie to decide in double
    arithmetic."""
    if f < 0.0 or (f == 0.0 and math.copysign(1.0, f) < 0.0):
        o[pos] = 45   # '-'
        pos += 1
    a = abs(f)
    if a == 0.0:
        o[pos] = 48
        return pos + 1
    e = _decimal_exponent(a)
    q = 0
    for _ in range(3):   # e is right, or one off where rounding to 6 digits carries
        x = _scaled(a, 5 - e)
        r = math.floor(x)
        frac = x - r
        if abs(frac - 0.5) < TIE_MARGIN:
            return -1
        q = int(r) + (1 if frac > 0.5 else 0)
        if q >= 1000000:
            if q == 1000000 and x < 1000000.0:   # rounded up to the next power of ten
                q = 100000
                e += 1
                break
            e += 1
        elif q < 100000:
            e -= 1
        else:
            break
    u = np.uint64(q)          # the six digits as three pairs (unsigned: see U10)
    hi = u // U10000
    rest = u - U10000 * hi
    mid = rest // U100
    lo = rest - U100 * mid
    last = 5                  # the last digit kept (0..5): %g drops the fraction's trailing zeros
    if lo == 0:
        last = 3
        if mid == 0:
            last = 1 if hi % U10 != 0 else 0
        elif mid % U10 == 0:
            last = 2
    elif lo % U10 == 0:
        last = 4
    if 0 <= e < 6:            # fixed, a digit before the point: ddd.ddd
        if last <= e:         # an integer: its e + 1 digits only (their zeros stay)
            _pair(o, pos, hi)
            _pair(o, pos + 2, mid)
            _pair(o, pos + 4, lo)
            return pos + e + 1
        _pair(o, pos + 1, hi)         # the digits one byte on, the integer part moved back
        _pair(o, pos + 3, mid)
        _pair(o, pos + 5, lo)
        for k in range(e + 1):
            o[pos + k] = o[pos + 1 + k]
        o[pos + e + 1] = 46   # '.'
        return pos + last + 2
    if -4 <= e < 0:           # fixed, 0.000ddd
        o[pos] = 48
        o[pos + 1] = 46
        pos += 2
        for _ in range(-e - 1):
            o[pos] = 48
            pos += 1
        _pair(o, pos, hi)
        _pair(o, pos + 2, mid)
        _pair(o, pos + 4, lo)
        return pos + last + 1
    _pair(o, pos + 1, hi)     # exponent: d.ddddde+XX
    _pair(o, pos + 3, mid)
    _pair(o, pos + 5, lo)
    o[pos] = o[pos + 1]
    if last > 0:
        o[pos + 1] = 46
        pos += last + 2
    else:
        pos += 1
    o[pos] = 101   # 'e'
    o[pos + 1] = 45 if e < 0 else 43
    _pair(o, pos + 2, np.uint64(abs(e)))   # float32: |e| <= 45
    return pos + 4


@numba.njit(cache=True, inline="always")
def _same_text(v, w, int_v, int_w):
    """Values v and w print the same (same kind, equal, same sign of a zero)."""
    return v == w and int_v == int_w and (v != 0.0 or math.copysign(1.0, v) == math.copysign(1.0, w))


@numba.njit(cache=True, **_NO_REFCOUNT, error_model="numpy")
def encode_rows(rows, is_int, lit, lit_end, max_bytes, out, length):
    """State messages of every row of `rows` (N, V) in wire order into `out` (N, W) uint8.

    is_int (V,) bool: C int fields (printed `%d` of the value truncated toward zero), the others
    float32 `%g`; `lit` uint8 with `lit_end` (V + 1,): the literal text before value k is
    lit[lit_end[k-1]:lit_end[k]] (k = 0 from 0), the last segment closes the message, and a NUL
    follows. length (N,): bytes of each message including its NUL, or -1 where the row needs
    the exact Python path (see the module docstring).

    A run of values that print alike with one-byte separators (the 36 opponents at 200, the
    five focus rays at -1) is printed once and copied in doubling blocks."""
    n_values = rows.shape[1]
    for i in range(rows.shape[0]):
        o = out[i]
        row = rows[i]
        pos = np.int64(0)      # not the literal 0, for which numba would compile _put_g again
        start = 0
        ok = True
        skip = 0               # values before this one were copied with a run
        for k in range(n_values + 1):
            if k < skip:
                continue
            for j in range(start, lit_end[k]):
                o[pos] = lit[j]
                pos += 1
            start = lit_end[k]
            if k == n_values:
                break
            value_start = pos
            v = row[k]
            if is_int[k]:
                if not abs(v) < 2147483648.0:
                    ok = False
                    break
                t = int(v)
                if t < 0:
                    o[pos] = 45
                    pos += 1
                    t = -t
                pos = _put_int(o, pos, t)
            else:
                f = np.float64(np.float32(v))
                if not math.isfinite(f):
                    ok = False
                    break
                a = abs(f)
                if a < 1e6 and a == math.floor(a):   # an integer of up to 6 digits: %g prints it so
                    if math.copysign(1.0, f) < 0.0:
                        o[pos] = 45
                        pos += 1
                    pos = _put_int(o, pos, int(a))
                else:
                    pos = _put_g(o, pos, f)
            if pos < 0 or pos > max_bytes:
                ok = False
                break
            r = k + 1             # the run: values r.. after one-byte separators, printing alike
            while r < n_values and lit_end[r] - lit_end[r - 1] == 1 and lit[lit_end[r - 1]] == lit[start] \
                    and _same_text(row[r], row[k], is_int[r], is_int[k]):
                r += 1
            if r > k + 1:
                copies = r - k - 1
                unit = pos - value_start + 1           # separator + text
                o[pos] = lit[start]
                for j in range(unit - 1):
                    o[pos + 1 + j] = o[value_start + j]
                done = 1
                block_start = pos
                pos += unit
                while done < copies:                   # double the block of units written
                    m = min(done, copies - done) * unit
                    for j in range(m):
                        o[pos + j] = o[block_start + j]
                    pos += m
                    done += m // unit
                if pos > max_bytes:
                    ok = False
                    break
                skip = r
                start = lit_end[r - 1]
        if ok and pos <= max_bytes:
            o[pos] = 0
            length[i] = pos + 1
        else:
            length[i] = -1


# --- control messages ------------------------------------------------------------------------------

# The tags of the two stock layouts, in order: C++ client / pyScrcClient, and snakeoil.
CPP_ORDER = (b"accel", b"brake", b"gear", b"steer", b"clutch", b"focus", b"meta")
SNAKEOIL_ORDER = (b"accel", b"brake", b"clutch", b"gear", b"steer", b"focus", b"meta")
INT_TAGS = (b"gear", b"focus", b"meta")
OUT_SLOT = {b"steer": 0, b"accel": 1, b"brake": 2, b"gear": 3, b"clutch": 4, b"focus": 5, b"meta": 6}


def layout_table(order) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(text, ends, slots) of a layout for `decode_controls_row`: the literal `(tag ` texts
    concatenated, their end offsets, and per group its output slot (+10 for an int group)."""
    texts = [b"(" + tag + b" " for tag in order]
    ends = np.cumsum([len(t) for t in texts]).astype(np.int64)
    slots = np.array([OUT_SLOT[tag] + (10 if tag in INT_TAGS else 0) for tag in order], dtype=np.int64)
    return np.frombuffer(b"".join(texts), dtype=np.uint8), ends, slots


@numba.njit(cache=True, inline="always")
def _is_digit(c):
    return 48 <= c <= 57


@numba.njit(cache=True, inline="always")
def _sign(buf, pos, n):
    """An optional '+' or '-' at buf[pos]: (negative, position after it)."""
    if pos < n and (buf[pos] == 43 or buf[pos] == 45):
        return buf[pos] == 45, pos + 1
    return False, pos


@numba.njit(cache=True, **_NO_REFCOUNT)
def _number(buf, pos, n, out, slot, is_int):
    """Read `[+-]?(d+.?d*|.d+)([eE][+-]?d+)?` at buf[pos:n] (an int group: `[+-]?d+(.d*)?`)
    into out[slot] (a float as the C++ server stores it: double, then float32; an int as is);
    returns the end, or -1 if the token is not of that form or not exactly convertible here
    (over 15 significant digits, a large exponent, over 9 int digits, float32 overflow)."""
    neg, pos = _sign(buf, pos, n)
    mant = 0
    digits = 0
    int_digits = 0
    scale = 0               # value = mant * 10^scale
    seen = 0
    while pos < n and _is_digit(buf[pos]):
        d = buf[pos] - 48
        if digits < 15:
            digits += 1 if mant > 0 or d > 0 else 0
            mant = mant * 10 + d
        elif d == 0:
            scale += 1          # a 16th+ digit: exact only as a trailing zero
        else:
            return -1
        int_digits += 1
        seen += 1
        pos += 1
    if pos < n and buf[pos] == 46:   # '.'
        pos += 1
        while pos < n and _is_digit(buf[pos]):
            d = buf[pos] - 48
            if digits < 15:
                digits += 1 if mant > 0 or d > 0 else 0
                mant = mant * 10 + d
                scale -= 1
            elif d != 0:
                return -1
            seen += 1
            pos += 1
    if seen == 0:
        return -1
    if is_int:
        if int_digits == 0 or int_digits > 9:
            return -1
        q = mant
        for _ in range(-scale):       # the fraction digits of "1.000" drop out
            q //= 10
        for _ in range(scale):
            q *= 10
        out[slot] = -q if neg else q
        return pos
    if pos < n and (buf[pos] == 101 or buf[pos] == 69):   # 'e' / 'E'
        eneg, pos = _sign(buf, pos + 1, n)
        e = 0
        ed = 0
        while pos < n and _is_digit(buf[pos]):
            e = min(e * 10 + (buf[pos] - 48), 1000)
            ed += 1
            pos += 1
        if ed == 0:
            return -1
        scale += -e if eneg else e
    if mant == 0:
        value = 0.0
    elif -22 <= scale <= 22:      # one correctly rounded operation (Clinger's fast path)
        value = mant * _POW10[scale] if scale >= 0 else mant / _POW10[-scale]
    else:
        return -1
    v32 = np.float64(np.float32(value))
    if not math.isfinite(v32):
        return -1
    out[slot] = -v32 if neg else v32
    return pos


@numba.njit(cache=True, **_NO_REFCOUNT)
def decode_controls_row(buf, n, text, ends, slots, out):
    """A control datagram buf[:n] (uint8) in one stock layout (`layout_table`), into out (7,):
    steer, accel, brake, gear, clutch, focus, meta (floats float32-rounded). Returns True when
    the datagram is exactly that layout (one number per group, extra focus numbers allowed,
    an optional final NUL); False: out is unspecified and the exact Python parser decides."""
    if n > 0 and buf[n - 1] == 0:
        n -= 1
    pos = np.int64(0)      # not literals, for which numba would compile _number again
    start = 0
    for g in range(ends.shape[0]):
        for j in range(start, ends[g]):
            if pos >= n or buf[pos] != text[j]:
                return False
            pos += 1
        start = ends[g]
        slot = slots[g]
        pos = _number(buf, pos, n, out, slot % 10, slot >= 10)
        if pos < 0:
            return False
        if slot == 15:     # focus: snakeoil may send more directions; the first one counts
            while pos < n and buf[pos] == 32:
                pos = _number(buf, pos + 1, n, out, np.int64(7), np.bool_(False))
                if pos < 0:
                    return False
        if pos >= n or buf[pos] != 41:   # ')'
            return False
        pos += 1
    return pos == n


@numba.njit(cache=True, **_NO_REFCOUNT)
def decode_stock(buf, n, cpp, snakeoil, out):
    """A control datagram buf[:n] (uint8, n its whole length) in either stock layout (`cpp`,
    `snakeoil`: `layout_table` tuples) into out (8,) as `decode_controls_row`; False when it is
    neither, or longer than the C++ server reads (the exact Python parser decides then)."""
    if n > MAX_DATAGRAM_BYTES or (n == MAX_DATAGRAM_BYTES and buf[n - 1] != 0):
        return False
    if decode_controls_row(buf, n, cpp[0], cpp[1], cpp[2], out):
        return True
    return decode_controls_row(buf, n, snakeoil[0], snakeoil[1], snakeoil[2], out)
