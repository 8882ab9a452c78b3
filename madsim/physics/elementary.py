"""atan, sin, cos and exp in plain arithmetic, and a four-lane stack buffer: what lets the compiler
evaluate the four tyres of a car side by side in SIMD lanes.

A call into libm cannot be vectorised (numba has no vector math library here), so the tyre
loop of `kernel.advance_car` would run one wheel at a time through ~6 ns `atan`/`sin` calls.
These functions are only multiplications, additions, one division, `floor`, `sqrt`-free
selects and `copysign`: LLVM vectorises a loop of them over the four wheels. They are ordinary
IEEE double arithmetic (no fastmath), so a result does not depend on which lane or how many
cars are computed at once, and with NUMBA_DISABLE_JIT=1 Python gives the same numbers.

Accuracy (tests/physics/test_elementary.py, against mpmath at 40 digits): `atan` and `sin`,
`cos` of the magic formula's angles, `exp` within 2 ulp of the correctly rounded value over the
whole input range tested (atan: all x; sin/cos: |x| <= 100; exp: [-708, 709]).

Derivations (each constant is reproducible from its description):
- atan: x -> |x|; above tan(3 pi / 8) t = -1/|x| and atan = pi/2 + atan(t), above tan(pi / 8)
  t = (|x| - 1) / (|x| + 1) and atan = pi/4 + atan(t), else t = |x|; then
  atan(t) = t + t^3 R(t^2) on |t| <= tan(pi/8), R a degree-10 polynomial fitted by least squares
  in relative error on 200 Chebyshev nodes of t^2 in [0, tan(pi/8)^2] (mpmath, 50 digits),
  coefficients rounded to double; pi/2 and pi/4 as a double plus its rounding error.
- sin, cos: k = round(2 x / pi), r = x - k pi/2 with pi/2 split into two 33-bit parts and a
  remainder (each k pi/2 part exact for |k| < 2^20), then the Taylor series of sin r (to r^17)
  and cos r (to r^18) on |r| <= pi/4 (truncation < 3e-18), quadrant k mod 4.
- exp: k = round(x / ln 2), r = x - k ln 2 with ln 2 split into a 42-bit part and the rest
  (k ln2_hi exact for |k| < 2^11), the Taylor series of e^r to r^13 on |r| <= ln(2)/2
  (truncation < 5e-18), times 2^k built from its bits.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

_JIT = {"cache": True, "error_model": "numpy"}

# atan(t) = t + t^3 R(t^2), |t| <= tan(pi/8) (module docstring)
_R0, _R1, _R2, _R3 = -0.3333333333333333, 0.1999999999999548, -0.14285714284658702, 0.11111111014675351
_R4, _R5, _R6 = -0.09090904556239807, 0.07692182716993239, -0.06664505197596049
_R7, _R8, _R9, _R10 = 0.05858097866643959, -0.050851976770859765, 0.03922476493475609, -0.019168872538341205
_TAN_3PI_8 = 2.414213562373095
_TAN_PI_8 = 0.41421356237309503
_PI_2_HI, _PI_2_LO = 1.5707963267948966, 6.123233995736766e-17
_PI_4_HI, _PI_4_LO = 0.7853981633974483, 3.061616997868383e-17

# sin/cos argument reduction: pi/2 = _P1 + _P2 + _P3 (_P1, _P2: 33 significant bits)
_TWO_OVER_PI = 0.6366197723675814
_P1, _P2, _P3 = 1.5707963267341256, 6.077100506303966e-11, 2.0222662487959506e-21
# Taylor coefficients (-1)^n / (2n+1)! and (-1)^n / (2n)!
_S3, _S5, _S7, _S9 = -0.16666666666666666, 0.008333333333333333, -0.0001984126984126984, 2.7557319223985893e-06
_S11, _S13, _S15, _S17 = -2.505210838544172e-08, 1.6059043836821613e-10, -7.647163731819816e-13, 2.8114572543455206e-15
_C4, _C6, _C8, _C10 = 0.041666666666666664, -0.001388888888888889, 2.48015873015873e-05, -2.755731922398589e-07
_C12, _C14, _C16, _C18 = 2.08767569878681e-09, -1.1470745597729725e-11, 4.779477332387385e-14, -1.5619206968586225e-16

# exp: ln 2 = _LN2_HI (42 significant bits) + _LN2_LO; Taylor coefficients 1 / n!
_INV_LN2 = 1.4426950408889634
_LN2_HI, _LN2_LO = 0.6931471805598903, 5.497923018708371e-14
_E2, _E3, _E4, _E5 = 0.5, 0.16666666666666666, 0.041666666666666664, 0.008333333333333333
_E6, _E7, _E8, _E9 = 0.001388888888888889, 0.0001984126984126984, 2.48015873015873e-05, 2.7557319223985893e-06
_E10, _E11, _E12, _E13 = 2.755731922398589e-07, 2.505210838544172e-08, 2.08767569878681e-09, 1.6059043836821613e-10
EXP_MIN, EXP_MAX = -708.0, 709.0
"""`exp`'s argument range: outside it the argument is clamped (e^-708 ~ 3e-308 stands for 0)."""


@intrinsic
def _pow2(typingctx, k):
    """2.0 ** k for an integral float64 k in [-1022, 1023], from its bits (vectorisable)."""
    def codegen(context, builder, signature, args):
        i64 = ir.IntType(64)
        bits = builder.shl(builder.add(builder.fptosi(args[0], i64), i64(1023)), i64(52))
        return builder.bitcast(bits, ir.DoubleType())
    return types.float64(types.float64), codegen


@numba.njit(inline="always", **_JIT)
def exp(x):
    """e^x for finite x, within 2 ulp on [EXP_MIN, EXP_MAX]; x clamped to that range."""
    x = min(max(x, EXP_MIN), EXP_MAX)
    k = np.floor(x * _INV_LN2 + 0.5)          # a float: no round trip through an integer
    r = (x - k * _LN2_HI) - k * _LN2_LO
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    q = (((_E2 + _E3 * r) + (_E4 + _E5 * r) * r2) + ((_E6 + _E7 * r) + (_E8 + _E9 * r) * r2) * r4
         + (((_E10 + _E11 * r) + (_E12 + _E13 * r) * r2) * r8))
    return (1.0 + (r + r2 * q)) * _pow2(k)


@numba.njit(inline="always", **_JIT)
def atan(x):
    """arctan(x), rad, for any finite or infinite x (NaN gives NaN); within 2 ulp."""
    a = abs(x)
    big = a > _TAN_3PI_8
    mid = a > _TAN_PI_8
    num = -1.0 if big else (a - 1.0 if mid else a)
    den = a if big else (a + 1.0 if mid else 1.0)
    t = num / den
    hi = _PI_2_HI if big else (_PI_4_HI if mid else 0.0)
    lo = _PI_2_LO if big else (_PI_4_LO if mid else 0.0)
    z = t * t
    z2 = z * z
    z4 = z2 * z2
    p = ((_R0 + _R1 * z) + (_R2 + _R3 * z) * z2) + (((_R4 + _R5 * z) + (_R6 + _R7 * z) * z2)
                                                    + ((_R8 + _R9 * z) + _R10 * z2) * z4) * z4
    return math.copysign(hi + (t + (t * z * p + lo)), x)


@numba.njit(inline="always", **_JIT)
def sincos(x):
    """(sin x, cos x) for |x| up to ~1e5 rad (the reduction's k pi/2 is exact below 2^20 pi/2);
    within 2 ulp for |x| <= 100."""
    k = np.floor(x * _TWO_OVER_PI + 0.5)      # a float: no round trip through an integer
    r = ((x - k * _P1) - k * _P2) - k * _P3
    z = r * r
    z2 = z * z
    z4 = z2 * z2
    ps = ((_S3 + _S5 * z) + (_S7 + _S9 * z) * z2) + ((_S11 + _S13 * z) + (_S15 + _S17 * z) * z2) * z4
    s = r + r * z * ps
    pc = ((_C4 + _C6 * z) + (_C8 + _C10 * z) * z2) + (((_C12 + _C14 * z) + (_C16 + _C18 * z) * z2) * z4)
    c = 1.0 - (0.5 * z - z2 * pc)
    q = k - 4.0 * np.floor(0.25 * k)          # quadrant 0..3
    odd = q == 1.0 or q == 3.0
    s_q, c_q = (c, s) if odd else (s, c)
    return (-s_q if q >= 2.0 else s_q), (-c_q if q == 1.0 or q == 2.0 else c_q)


@intrinsic
def _stack_f8x4(typingctx):
    """A pointer to four float64 on the calling function's stack (uninitialised)."""
    def codegen(context, builder, signature, args):
        return cgutils.alloca_once(builder, ir.DoubleType(), size=4)
    return types.CPointer(types.float64)(), codegen


if numba.config.DISABLE_JIT:      # plain Python: the same numbers without the intrinsics

    def lanes4():
        """Four float64 of scratch (Python: an array)."""
        return np.empty(4)

    def _pow2(k):  # noqa: F811 - the Python twin of the intrinsic above
        return math.ldexp(1.0, int(k))
else:
    @numba.njit(inline="always", **_JIT)
    def lanes4():
        """Four float64 of scratch on the stack of the kernel that inlines this (a pointer:
        index it 0..3). No allocation, no reference count: usable without numba's runtime."""
        return _stack_f8x4()
