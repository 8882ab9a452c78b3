"""The SCR (scr_server) wire format: pure functions, bytes in and bytes out.

The contract is the shared spec `spec/scr-protocol.md`; section numbers below (§) refer to it.

Server side: `encode_sensors` (one car's state message), `decode_controls` (a client's action,
parsed the way the C++ server parses it, never raising), `parse_init` (identification),
`identified_reply`, `RESTART_MESSAGE`, `SHUTDOWN_MESSAGE`.
Client side: `encode_init`, `parse_identified`, `decode_sensors`, `encode_controls`.

Units are SCR units throughout (the wire's): angles in rad for `angle`, degrees for rangefinder
and focus directions, km/h for speeds, rad/s x 10 for `rpm`, metres for distances.

Faithfulness notes (C/C++ behaviour reproduced here):
* Floats are rounded to float32 and printed like C `printf("%g")` (6 significant digits);
  non-finite values print as glibc does: `inf`, `-inf`, `nan`, `-nan` (NaN with the sign bit).
* Controls are read like `istream >>` from libstdc++ (C++11 and later): a number is the longest
  prefix of sign, digits, one decimal point and an exponent; a prefix that strtod would not
  consume entirely (`1e`, `.`, `-`) or a non-number reads as 0; float overflow reads as
  +-FLT_MAX; int overflow as INT_MAX/INT_MIN. `(gear)` with no value is undefined in the C++
  server (the member stays uninitialised); here it reads as 0, like a non-numeric value.
"""

from __future__ import annotations

import math
import operator
import re
import struct
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from madsim import facts as F
from madsim.net import codec_kernels as K

__all__ = [
    "ProtocolError",
    "SensorField",
    "SENSOR_FIELDS",
    "VISION_SENSOR_FIELDS",
    "SENSOR_VALUE_COUNT",
    "MAX_DATAGRAM_BYTES",
    "MAX_STATE_BYTES",
    "DEFAULT_ANGLES_DEG",
    "CPP_CLIENT_ANGLES_DEG",
    "SNAKEOIL_ANGLES_DEG",
    "IDENTIFIED",
    "RESTART",
    "SHUTDOWN",
    "RESTART_MESSAGE",
    "SHUTDOWN_MESSAGE",
    "Identified",
    "InitRequest",
    "Controls",
    "SensorEncoder",
    "encode_sensors",
    "encode_sensors_flat",
    "encode_sensor_rows",
    "decode_sensors",
    "encode_controls",
    "decode_controls",
    "decode_controls_into",
    "encode_init",
    "parse_init",
    "identified_reply",
    "parse_identified",
]


class ProtocolError(ValueError):
    """A message cannot be built or read; `field` names the SCR field at fault, if any."""

    def __init__(self, message: str, *, field: str | None = None):
        self.field = field
        super().__init__(message)


# --- constants ------------------------------------------------------------------------------

MAX_DATAGRAM_BYTES = K.MAX_DATAGRAM_BYTES
"""Receive buffer of the C++ server, the C++ client and pyScrcClient (`UDP_MSGLEN`)."""
MAX_STATE_BYTES = MAX_DATAGRAM_BYTES - 1
"""Longest state text (NUL excluded) that fits those buffers (§2 Size)."""

FLT_MAX = 3.4028234663852886e38
INT_MIN, INT_MAX = -(2**31), 2**31 - 1


class SensorField(NamedTuple):
    """One field of the state message: SCR name, number of values, 'float' or 'int'."""

    name: str
    width: int
    kind: str


SENSOR_FIELDS = tuple(SensorField(f.name, f.width, f.kind) for f in F.SCR_FIELDS)
"""Fields of the SRV13 state message in wire order (§5, `madsim.facts.SCR_FIELDS`); gear,
racePos, damage are C ints."""

VISION_SENSOR_FIELDS = (
    SENSOR_FIELDS[:4] + (SensorField("totalDistFromStart", 1, "float"),) + SENSOR_FIELDS[4:]
)
"""gym_torcs' vtorcs variant (SRVVIS): `totalDistFromStart` after `distFromStart` (§5)."""

SENSOR_VALUE_COUNT = F.SCR_VALUE_COUNT  # 79 numbers per state message

DEFAULT_ANGLES_DEG = F.SCR_SERVER_DEFAULT_ANGLES_DEG
"""Rangefinder angles the server uses when `(init ...)` is missing or short (§3.3)."""
CPP_CLIENT_ANGLES_DEG = F.SCR_CPP_CLIENT_ANGLES_DEG
SNAKEOIL_ANGLES_DEG = F.SNAKEOIL_ANGLES_DEG

IDENTIFIED = b"***identified***"
RESTART = b"***restart***"
SHUTDOWN = b"***shutdown***"
RESTART_MESSAGE = RESTART + b"\0"
SHUTDOWN_MESSAGE = SHUTDOWN + b"\0"

_F32 = struct.Struct("<f")


def _f32(x: float) -> float:
    """Round a finite double to float32 like a C `(float)` cast (overflow gives +-inf)."""
    try:
        return _F32.unpack(_F32.pack(x))[0]
    except OverflowError:
        return math.copysign(math.inf, x)


def _c_string(data: bytes) -> bytes:
    """The text a C program sees in a datagram buffer: everything before the first NUL."""
    nul = data.find(b"\0")
    return data if nul < 0 else data[:nul]


# --- identification (§3) --------------------------------------------------------------------


class Identified(NamedTuple):
    """A server's identification reply; `pid` is set only by the MADRaS variant (§12.1)."""

    pid: int | None


def identified_reply(pid: int | None = None) -> bytes:
    """`***identified***` + NUL, or `***identified***:<pid>` + NUL for MADRaS' snakeoil."""
    if pid is None:
        return IDENTIFIED + b"\0"
    return b"%s:%d\0" % (IDENTIFIED, operator.index(pid))


_IDENTIFIED_PID = re.compile(rb"\*\*\*identified\*\*\*:(\d{1,10})")


def parse_identified(data: bytes) -> Identified | None:
    """Read an identification reply of either variant; None if `data` is something else."""
    text = _c_string(bytes(data))
    if text == IDENTIFIED:
        return Identified(None)
    m = _IDENTIFIED_PID.fullmatch(text)
    return Identified(int(m.group(1))) if m else None


class InitRequest(NamedTuple):
    """A client's identification: its id text, 19 rangefinder angles (deg, float32 values),
    and whether those angles came from the datagram (False: the server default list)."""

    client_id: str
    angles_deg: tuple[float, ...]
    angles_given: bool


def encode_init(name: str = "SCR", angles_deg: Sequence[float] | None = None) -> bytes:
    """`<name>(init a0 ... a18)` as the C++ client sends it (no NUL); default angles §3.3."""
    if not isinstance(name, str) or not name.startswith("SCR"):
        raise ProtocolError(f"client id {name!r} must start with 'SCR' or no server answers it")
    if not name.isascii() or not name.isprintable() or any(c in name for c in "()"):
        raise ProtocolError(f"client id {name!r} must be printable ASCII without parentheses")
    angles = DEFAULT_ANGLES_DEG if angles_deg is None else list(angles_deg)
    if len(angles) != 19:
        raise ProtocolError(f"init needs 19 rangefinder angles, got {len(angles)}", field="init")
    texts = [_format_float(a, "init") for a in angles]
    if any(t.endswith(("inf", "nan")) for t in texts):
        raise ProtocolError(f"init angles must be finite, got {angles}", field="init")
    return ("%s(init %s)" % (name, " ".join(texts))).encode("ascii")


def parse_init(data: bytes) -> InitRequest | None:
    """Parse an identification datagram like the C++ server; None unless it starts with `SCR`.

    Angles: the first `(init ...)` group must yield 19 numbers read in sequence like
    `istream >> float`, otherwise the default list -90..90 step 10 is used (§3.3).
    Never raises on arbitrary bytes.
    """
    data = bytes(data[:MAX_DATAGRAM_BYTES])
    if data[:3] != b"SCR":
        return None
    text = _c_string(data)
    paren = text.find(b"(")
    client_id = (text if paren < 0 else text[:paren]).decode("ascii", "replace")
    for m in _GROUP.finditer(text):
        if m.group(1) == b"init":
            angles = _read_floats(m.group(2), 19)
            if angles is not None:
                return InitRequest(client_id, angles, True)
            break
    return InitRequest(client_id, DEFAULT_ANGLES_DEG, False)


# --- state message, server side (§2, §5) ----------------------------------------------------


def _format_float(x: Any, name: str) -> str:
    """One float value as the C++ server prints a C float: float32, then `%g` (glibc spelling)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ProtocolError(f"field {name!r}: {x!r} is not a number", field=name) from None
    if v != v:
        return "-nan" if math.copysign(1.0, v) < 0 else "nan"
    return "%g" % _f32(v)  # Python spells +-inf like glibc


def _format_int(x: Any, name: str) -> str:
    """One C int value (truncated toward zero like a C cast if given a float)."""
    try:
        return "%d" % x
    except (TypeError, ValueError, OverflowError):
        raise ProtocolError(f"field {name!r}: {x!r} is not a finite integer", field=name) from None


_BYTE_TEXT = tuple(b"%d" % i for i in range(256))


def _img_field(img: Any) -> bytes:
    """`(img v0 v1 ...)`, one int 0-255 per byte: the vtorcs vision field (§11)."""
    try:
        pixels = bytes(img)
    except (TypeError, ValueError):
        raise ProtocolError("field 'img' needs bytes or ints 0-255", field="img") from None
    return b"(img " + b" ".join([_BYTE_TEXT[p] for p in pixels]) + b")"


class SensorEncoder:
    """Formats state messages for one field list with a precompiled `%` template.

    `encode(values)` takes a mapping SCR name -> number (width 1) or sequence of `width`
    numbers, e.g. one car's row of a SensorFrame. `encode_flat(row)` takes the values already
    flattened in wire order (SENSOR_VALUE_COUNT numbers for SENSOR_FIELDS); a float32 numpy
    row is the cheapest input. Both return the message with its one trailing NUL.

    A message longer than `max_bytes` (NUL excluded) raises ProtocolError: the C++ server would
    overrun its 1000-byte buffer and stock clients would cut it. Realistic states stay below
    ~850 bytes; only pathological values (many 12-character numbers like -1.23457e-05) get
    there. `img` (vision) is appended after the size check, as vtorcs does.
    """

    def __init__(self, fields: Sequence[SensorField] = SENSOR_FIELDS,
                 max_bytes: int = MAX_STATE_BYTES):
        self.fields = tuple(SensorField(*f) for f in fields)
        for f in self.fields:
            if f.kind not in ("float", "int") or f.width < 1:
                raise ProtocolError(f"bad field definition {f}", field=f.name)
        self.max_bytes = max_bytes
        self.value_count = sum(f.width for f in self.fields)
        self._get = operator.itemgetter(*[f.name for f in self.fields])
        self._widths = tuple(f.width for f in self.fields)
        # ints travel as doubles so '%d' sees the caller's value; floats are float32-rounded
        self._struct = struct.Struct(
            "<" + "".join(("f" if f.kind == "float" else "d") * f.width for f in self.fields))
        self._template = "".join(
            "(" + f.name + (" %g" if f.kind == "float" else " %d") * f.width + ")"
            for f in self.fields).encode("ascii") + b"\0"
        # the compiled path: literal text around each value, int flags, an output buffer
        pieces = self._template[:-1].split(b"%")
        literals = [pieces[0]] + [p[1:] for p in pieces[1:]]
        self._lit = np.frombuffer(b"".join(literals), dtype=np.uint8)
        self._lit_end = np.cumsum([len(x) for x in literals]).astype(np.int64)
        self._is_int = np.array([f.kind == "int" for f in self.fields for _ in range(f.width)])
        self._width = len(self._lit) + self.value_count * K.MAX_VALUE_CHARS + 7
        self._out = np.zeros((1, self._width), dtype=np.uint8)
        self._length = np.zeros(1, dtype=np.int64)

    @property
    def message_width(self) -> int:
        """Bytes per row of the output buffer `codec_kernels.encode_rows` needs."""
        return self._width

    def kernel_args(self) -> tuple:
        """`codec_kernels.encode_rows`'s arguments after the rows: (is_int, lit, lit_end,
        max_bytes), for a compiled caller such as the SCR server's tick."""
        return self._is_int, self._lit, self._lit_end, self.max_bytes

    def encode(self, values: Mapping[str, Any], img: Any = None) -> bytes:
        """One car's state message from a mapping of SCR name -> value(s); ends with NUL."""
        try:
            flat: list = []
            for value, width in zip(self._get(values), self._widths):
                if width == 1:
                    flat.append(value)
                elif len(value) == width:
                    flat.extend(value.tolist() if hasattr(value, "tolist") else value)
                else:
                    raise ValueError
            rounded = self._struct.unpack(self._struct.pack(*flat))
        except Exception:  # anything odd: the checked path names the field at fault
            return self._encode_checked(values, img)
        if not math.isfinite(sum(rounded)):
            return self._encode_checked(values, img)  # C spelling of nan sign
        return self._finish(self._template % rounded, img)

    def encode_rows(self, rows: np.ndarray) -> list[bytes]:
        """State messages (each ending with NUL) of every row of `rows` (N, value_count), float32
        or float64, values in wire order: one compiled call; a row it cannot do exactly (see
        `madsim.net.codec_kernels`) goes through `encode_flat`'s exact path."""
        n = rows.shape[0]
        if self._out.shape[0] < n:
            self._out = np.zeros((n, self._width), dtype=np.uint8)
            self._length = np.zeros(n, dtype=np.int64)
        out, length = self._out, self._length
        K.encode_rows(rows, self._is_int, self._lit, self._lit_end, self.max_bytes, out, length)
        return [out[i, :length[i]].tobytes() if length[i] > 0 else self._encode_flat_exact(rows[i], None)
                for i in range(n)]

    def encode_flat(self, row: Any, img: Any = None) -> bytes:
        """One car's state message from all values flattened in wire order; ends with NUL."""
        if isinstance(row, np.ndarray) and row.shape == (self.value_count,) \
                and row.dtype in (np.float32, np.float64):
            msg = self.encode_rows(row[None, :])[0]
            return msg if img is None else self._finish(msg, img)
        return self._encode_flat_exact(row, img)

    def _encode_flat_exact(self, row: Any, img: Any) -> bytes:
        """encode_flat value by value in Python (any sequence; exact C spelling always)."""
        dtype = getattr(row, "dtype", None)
        try:
            flat = row.tolist() if hasattr(row, "tolist") else list(row)
            if not isinstance(flat, list):
                raise TypeError
        except TypeError:
            raise ProtocolError(f"state row must be a sequence of {self.value_count} numbers, "
                                f"got {type(row).__name__}") from None
        if len(flat) != self.value_count:
            return self._encode_checked(self._unflatten(flat), img)
        if dtype is None or dtype.char != "f" or getattr(row, "ndim", 1) != 1:
            try:
                flat = self._struct.unpack(self._struct.pack(*flat))
            except (OverflowError, struct.error):
                return self._encode_checked(self._unflatten(flat), img)
        if not math.isfinite(sum(flat)):
            return self._encode_checked(self._unflatten(flat), img)
        return self._finish(self._template % tuple(flat), img)

    def _unflatten(self, flat: list) -> dict:
        if len(flat) != self.value_count:
            raise ProtocolError(f"state needs {self.value_count} values in wire order, "
                                f"got {len(flat)}")
        out, i = {}, 0
        for f in self.fields:
            out[f.name] = flat[i] if f.width == 1 else flat[i:i + f.width]
            i += f.width
        return out

    def _encode_checked(self, values: Mapping[str, Any], img: Any) -> bytes:
        """Slow path, value by value: exact C spelling of non-finite values, named errors."""
        parts = []
        for f in self.fields:
            try:
                value = values[f.name]
            except (KeyError, IndexError, TypeError):
                raise ProtocolError(f"state is missing field {f.name!r}", field=f.name) from None
            if f.width == 1:
                items = [value]
            else:
                try:
                    items = list(value.tolist() if hasattr(value, "tolist") else value)
                except TypeError:
                    items = [value]
                if len(items) != f.width or isinstance(value, (str, bytes)):
                    raise ProtocolError(f"field {f.name!r} needs {f.width} values, got "
                                        f"{value!r}", field=f.name)
            fmt = _format_float if f.kind == "float" else _format_int
            parts.append("(%s %s)" % (f.name, " ".join([fmt(x, f.name) for x in items])))
        return self._finish(("".join(parts) + "\0").encode("ascii"), img)

    def _finish(self, msg: bytes, img: Any) -> bytes:
        if len(msg) > self.max_bytes + 1:
            raise ProtocolError(f"state message is {len(msg) - 1} bytes, over the "
                                f"{self.max_bytes}-byte limit of SCR receive buffers")
        if img is not None:
            msg = msg[:-1] + _img_field(img) + b"\0"
        return msg


STATE_ENCODER = SensorEncoder()
"""The SRV13 state encoder the module functions use."""


def encode_sensors(values: Mapping[str, Any], img: Any = None) -> bytes:
    """SRV13 state message (SENSOR_FIELDS) for one car; see SensorEncoder.encode."""
    return STATE_ENCODER.encode(values, img)


def encode_sensors_flat(row: Any, img: Any = None) -> bytes:
    """SRV13 state message from 79 values in wire order; see SensorEncoder.encode_flat."""
    return STATE_ENCODER.encode_flat(row, img)


def encode_sensor_rows(rows: np.ndarray) -> list[bytes]:
    """SRV13 state messages of N cars from an (N, 79) array in wire order (one compiled call);
    see SensorEncoder.encode_rows."""
    return STATE_ENCODER.encode_rows(rows)


# --- state message, client side -------------------------------------------------------------

_SENSOR_SHAPES = {f.name: (f.width, f.kind) for f in VISION_SENSOR_FIELDS}
# Fast path: the exact SRV13 layout, one capture per field (tokens checked by float()/int()).
_SRV13_LAYOUT = re.compile("".join(
    r"\(%s ([^ ()]+%s)\)" % (f.name, r"(?: [^ ()]+)" + "{%d}" % (f.width - 1) if f.width > 1
                              else "") for f in SENSOR_FIELDS))
_SRV13_CONVERT = tuple(
    (f.name, int if f.kind == "int" else float if f.width == 1 else None) for f in SENSOR_FIELDS)


def decode_sensors(data: bytes) -> dict[str, Any]:
    """Parse a server state message into {SCR name: value}.

    Scalars become float (int for gear, racePos, damage), vectors lists of float, `img` a list
    of ints; unknown fields are kept (float, or list if several values). Text after the first
    NUL is ignored. Raises ProtocolError, and only that, on anything malformed.
    """
    try:
        text = _c_string(bytes(data)).decode("ascii")
    except (UnicodeDecodeError, TypeError, ValueError):
        raise ProtocolError("state message is not ASCII bytes") from None
    m = _SRV13_LAYOUT.fullmatch(text)
    if m is not None and "_" not in text:
        try:
            return {name: convert(value) if convert is not None
                    else list(map(float, value.split(" ")))
                    for (name, convert), value in zip(_SRV13_CONVERT, m.groups())}
        except ValueError:
            pass  # the general path below names the field at fault
    parts = text[1:-1].split(")(")
    if len(text) < 2 or text[0] != "(" or text[-1] != ")" or "_" in text \
            or text.count("(") != len(parts) or text.count(")") != len(parts):
        raise ProtocolError(f"not a state message: {text[:60]!r}")
    out: dict[str, Any] = {}
    for part in parts:
        name, _, rest = part.partition(" ")
        values = rest.split()
        if not values or not name.isalnum() or not name[0].isalpha():
            raise ProtocolError(f"malformed field ({part[:40]})", field=name or None)
        if name in out:
            raise ProtocolError(f"field {name!r} appears twice", field=name)
        width, kind = _SENSOR_SHAPES.get(name, (0, "float"))
        if width and len(values) != width:
            raise ProtocolError(f"field {name!r} has {len(values)} values, expected {width}",
                                field=name)
        try:
            if name == "img":
                parsed: Any = list(map(int, values))
                if min(parsed) < 0 or max(parsed) > 255:
                    raise ValueError
            elif kind == "int":
                parsed = _parse_int_token(values[0])
            elif len(values) == 1 and width <= 1:
                parsed = float(values[0])
            else:
                parsed = list(map(float, values))
        except (ValueError, OverflowError):
            raise ProtocolError(f"field {name!r} has a bad value: {part[:60]!r}",
                                field=name) from None
        out[name] = parsed
    return out


def _parse_int_token(token: str) -> int:
    try:
        return int(token)
    except ValueError:
        value = float(token)  # tolerate "1.0" from non-C servers; "1.5" is an error
        if not value.is_integer():
            raise
        return int(value)


# --- control message (§6) -------------------------------------------------------------------


class Controls(NamedTuple):
    """A decoded control message. Pedals and steer are float32 values as the C++ server
    stores them; `focus` is None when out of [-90, 90] (the server's 360 "no focus");
    `well_formed` is False for anything a stock client would not send (see decode_controls)."""

    accel: float = 0.0
    brake: float = 0.0
    gear: int = 1
    steer: float = 0.0
    clutch: float = 0.0
    focus: int | None = 0
    meta: int = 0
    well_formed: bool = False


# One "(...)" pair as the C++ SimpleParser finds them: '(' up to the first ')' after it.
# Groups: 1 tag (first whitespace-delimited token), 2 the rest; 3 the first value when it is a
# complete number token (the fast path), 4 what follows it.
_NUM = rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_GROUP = re.compile(rb"\(\s*([^\s)]*)((?:\s+(" + _NUM + rb")(?=[\s)]))?([^)]*))\)")
# What libstdc++'s num_get collects for a float after skipping whitespace; valid only when
# the exponent part, if any, has digits.
_FLOAT_HEAD = re.compile(rb"\s*([+-]?(?:\d+\.?\d*|\.\d+))([eE][+-]?\d*)?")
_INT_HEAD = re.compile(rb"\s*([+-]?\d+)")
_NUMBER_LIST = re.compile(rb"(?:\s+" + _NUM + rb")+\s*")
_INIT_FAST = re.compile(rb"(?:\s+" + _NUM + rb"(?=\s|$)){19}")
# Whole-message fast paths for the two stock layouts (C++/pyScrcClient order; snakeoil order).
_F = rb"(" + _NUM + rb")"
_I = rb"([+-]?\d+)(?:\.\d*)?"
_CPP_FAST = re.compile(rb"\(accel %s\)\(brake %s\)\(gear %s\)\(steer %s\)\(clutch %s\)"
                       rb"\(focus %s\)\(meta %s\)\x00?" % (_F, _F, _I, _F, _F, _I, _I))
_SNAKEOIL_FAST = re.compile(rb"\(accel %s\)\(brake %s\)\(clutch %s\)\(gear %s\)\(steer %s\)"
                            rb"\(focus %s(?: %s)*\)\(meta %s\)\x00?"
                            % (_F, _F, _F, _I, _F, _I, _NUM, _I))
_FLOAT_TAGS = (b"accel", b"brake", b"steer", b"clutch")
_CONTROL_TAGS = frozenset(_FLOAT_TAGS + (b"gear", b"focus", b"meta"))
_F32X4 = struct.Struct("<4f")
_F32X19 = struct.Struct("<19f")


def _scan_float(rest: bytes, pos: int = 0) -> tuple[float, bool, int]:
    """`istream >> float` at `pos`: (float32 value as stored, True unless failbit, end).

    Failure stores 0 (no number, or an exponent without digits such as `1e`) or +-FLT_MAX
    (overflow), as libstdc++ does."""
    m = _FLOAT_HEAD.match(rest, pos)
    if m is None:
        return 0.0, False, pos
    exponent = m.group(2) or b""
    if exponent and not exponent[-1:].isdigit():
        return 0.0, False, m.end()
    value = _f32(float(m.group(1) + exponent))
    if math.isinf(value):
        return math.copysign(FLT_MAX, value), False, m.end()
    return value, True, m.end()


def _read_floats(rest: bytes, count: int) -> tuple[float, ...] | None:
    """`count` floats read one after another from a stream; None as soon as one fails."""
    if count == 19 and _INIT_FAST.match(rest):  # 19 clean number tokens: one conversion
        try:
            values = _F32X19.unpack(_F32X19.pack(*map(float, rest.split()[:19])))
        except OverflowError:
            values = (math.inf,)
        if math.isfinite(sum(values)):
            return values
    out, pos = [], 0
    for _ in range(count):
        value, ok, pos = _scan_float(rest, pos)
        if not ok:
            return None
        out.append(value)
    return tuple(out)


def _int_control(m: re.Match | None, default: int) -> int:
    """`istream >> int` on a group's value: leading integer prefix, 0 on failure, clamped."""
    if m is None:
        return default
    head = _INT_HEAD.match(m.group(2))
    if head is None:
        return 0
    return min(max(int(head.group(1)), INT_MIN), INT_MAX)


def decode_controls(data: bytes) -> Controls:
    """Parse a client's control datagram exactly like the C++ scr_server; never raises.

    Rules (§2, §6): only the first 1000 bytes and only the text before the first NUL count;
    a group is '(' up to the next ')'; its tag is the first whitespace-delimited token; for
    each control the first group with that tag wins and its first number is read like
    `istream >>` (integer prefix for gear/focus/meta); order is free; defaults for missing
    tags: accel 0, brake 0, gear 1, steer 0, clutch 0, focus 0, meta 0. A tag present with a
    non-number reads as 0 (so `(gear x)` is gear 0, not 1).

    `well_formed` is True iff the datagram is at most 999 bytes plus an optional final NUL and
    consists of whitespace and at least one group, each a known tag followed by one or more
    complete numbers, no tag twice. Stock C++, snakeoil and pyScrcClient messages qualify.
    """
    if len(data) <= MAX_STATE_BYTES or len(data) == MAX_DATAGRAM_BYTES and data[-1] == 0:
        m = _CPP_FAST.fullmatch(data)
        if m is not None:
            a, b, g, s, c, f, meta = m.groups()
        else:
            m = _SNAKEOIL_FAST.fullmatch(data)
            if m is not None:
                a, b, c, g, s, f, meta = m.groups()
        if m is not None:
            try:
                values = _F32X4.unpack(_F32X4.pack(float(a), float(b), float(s), float(c)))
            except OverflowError:
                values = (math.inf,)
            if math.isfinite(sum(values)) and len(g) < 10 and len(f) < 10 and len(meta) < 10:
                focus = int(f)
                return Controls(values[0], values[1], int(g), values[2], values[3],
                                focus if -90 <= focus <= 90 else None, int(meta), True)
    return _decode_controls_general(data)


STOCK_LAYOUTS = (K.layout_table(K.CPP_ORDER), K.layout_table(K.SNAKEOIL_ORDER))
"""The two stock control layouts as `codec_kernels.decode_stock` takes them."""


def decode_controls_into(data: bytes, out: np.ndarray) -> bool:
    """The compiled fast path of decode_controls for the two stock layouts: fills out (8,)
    float64 with steer, accel, brake, gear, clutch, focus (any value), meta and returns True
    (the datagram is well formed), or returns False (out unspecified): use decode_controls."""
    buf = np.frombuffer(data, dtype=np.uint8)
    return K.decode_stock(buf, buf.shape[0], *STOCK_LAYOUTS, out)


def _decode_controls_general(data: bytes) -> Controls:
    """decode_controls for any input: the C++ parser's scan, group by group."""
    raw = bytes(data[:MAX_DATAGRAM_BYTES])
    text = _c_string(raw)
    ok = len(text) <= MAX_STATE_BYTES and len(data) - len(text) <= 1
    found: dict[bytes, re.Match] = {}
    pos = 0
    for m in _GROUP.finditer(text):
        start = m.start()
        if start != pos and not text[pos:start].isspace():
            ok = False
        pos = m.end()
        tag = m.group(1)
        if tag in found or tag not in _CONTROL_TAGS:
            ok = False
            continue
        found[tag] = m
        if ok:
            tail = m.group(4)
            if m.group(3) is None or tail and not tail.isspace() \
                    and _NUMBER_LIST.fullmatch(tail) is None:
                ok = False
    if not found or (pos != len(text) and not text[pos:].isspace()):
        ok = False
    pedals = []
    for tag in _FLOAT_TAGS:
        m = found.get(tag)
        if m is None:
            pedals.append(0.0)
        elif m.group(3) is not None:
            pedals.append(float(m.group(3)))
        else:
            pedals.append(_scan_float(m.group(2))[0])
    try:
        values = _F32X4.unpack(_F32X4.pack(*pedals))
    except OverflowError:
        values = tuple(map(_f32, pedals))
    if not math.isfinite(sum(values)):  # float overflow: libstdc++ stores +-FLT_MAX
        values = tuple(math.copysign(FLT_MAX, v) if math.isinf(v) else v for v in values)
    accel, brake, steer, clutch = values
    gear = _int_control(found.get(b"gear"), 1)
    focus = _int_control(found.get(b"focus"), 0)
    meta = _int_control(found.get(b"meta"), 0)
    return Controls(accel, brake, gear, steer, clutch,
                    focus if -90 <= focus <= 90 else None, meta, ok)


def _control_int(x: Any, name: str) -> int:
    try:
        value = float(x)
        if not value.is_integer():
            raise ValueError
        return int(value)
    except (TypeError, ValueError, OverflowError):
        raise ProtocolError(f"control {name!r} must be an integer, got {x!r}",
                            field=name) from None


def _control_float(x: Any, name: str) -> float:
    try:
        value = float(x)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise ProtocolError(f"control {name!r} must be a finite number, got {x!r}", field=name)
    return value


def encode_controls(accel: float = 0.0, brake: float = 0.0, gear: int = 1, steer: float = 0.0,
                    clutch: float = 0.0, focus: int | Sequence[int] | None = 0, meta: int = 0,
                    *, style: str = "cpp") -> bytes:
    """A control message as a stock client sends it.

    style 'cpp' (C++ client): `(accel 1)(brake 0)(gear 2)(steer -0.0123457)(clutch 0)(focus 0)
    (meta 0)` + NUL, floats as float32 `%g`, focus one int. style 'snakeoil': every scalar `%.3f`
    in the order accel, brake, clutch, gear, steer, focus, meta, no NUL; focus may be a list
    (the server uses its first element). focus None asks for no focus reading (sends 360).
    Values are not clipped (the simulator clamps, §6). Raises ProtocolError on NaN/inf or a
    non-integral gear/focus/meta.
    """
    a, b, s, c = (_control_float(v, n) for v, n in
                  ((accel, "accel"), (brake, "brake"), (steer, "steer"), (clutch, "clutch")))
    g, m = _control_int(gear, "gear"), _control_int(meta, "meta")
    if focus is None:
        focus_list = [360]
    elif isinstance(focus, (list, tuple)) or hasattr(focus, "tolist"):
        focus_list = [_control_int(f, "focus") for f in (
            focus.tolist() if hasattr(focus, "tolist") else focus)]
        if not focus_list or isinstance(focus_list[0], list):
            raise ProtocolError(f"control 'focus' list must hold ints, got {focus!r}",
                                field="focus")
    else:
        focus_list = [_control_int(focus, "focus")]
    if style == "cpp":
        if len(focus_list) != 1:
            raise ProtocolError("style 'cpp' sends one focus direction; use style='snakeoil' "
                                "for a list", field="focus")
        return b"(accel %s)(brake %s)(gear %d)(steer %s)(clutch %s)(focus %d)(meta %d)\0" % (
            _format_float(a, "accel").encode(), _format_float(b, "brake").encode(), g,
            _format_float(s, "steer").encode(), _format_float(c, "clutch").encode(),
            focus_list[0], m)
    if style == "snakeoil":
        if len(focus_list) == 1 and not isinstance(focus, (list, tuple)) \
                and not hasattr(focus, "tolist"):
            focus_text = b"%.3f" % focus_list[0]
        else:
            focus_text = b" ".join(b"%d" % f for f in focus_list)
        return b"(accel %.3f)(brake %.3f)(clutch %.3f)(gear %.3f)(steer %.3f)(focus %s)" \
               b"(meta %.3f)" % (a, b, c, g, s, focus_text, m)
    raise ProtocolError(f"unknown control style {style!r}; use 'cpp' or 'snakeoil'")
