"""physics/elementary.py's atan, sincos and exp against mpmath (40 digits, correctly rounded), in ulp
of the true value, over their whole input ranges; and the same numbers from a vectorised loop
and from scalar calls (lanes do not change results)."""

from __future__ import annotations

import math

import mpmath
import numba
import numpy as np
import pytest

from madsim.physics import elementary as el

mpmath.mp.dps = 40


@numba.njit(cache=True)
def _atan_all(x, out):
    for i in range(x.shape[0]):
        out[i] = el.atan(x[i])


@numba.njit(cache=True)
def _sincos_all(x, s, c):
    for i in range(x.shape[0]):
        s[i], c[i] = el.sincos(x[i])


def _ulp_error(y, ref):
    """|y - ref| in units of the last place of the correctly rounded ref."""
    r = np.array([float(v) for v in ref])
    return np.abs(np.array([float((mpmath.mpf(a) - b) / mpmath.mpf(np.spacing(abs(c))))
                            for a, b, c in zip(y, ref, r)]))


def _points(rng, lo, hi, n):
    return np.concatenate([rng.uniform(lo, hi, n), np.linspace(lo, hi, n)])


def test_atan_within_2_ulp_over_every_finite_range():
    """Every branch of the reduction (|x| < tan(pi/8), < tan(3 pi/8), above), its edges, tiny
    and huge |x| and both signs: within 2 ulp of the correctly rounded arctan (measured 1.6)."""
    rng = np.random.default_rng(0)
    x = np.concatenate([_points(rng, -40.0, 40.0, 1500), np.geomspace(1e-300, 1e300, 600),
                        -np.geomspace(1e-12, 1e12, 300),
                        np.nextafter(el._TAN_PI_8, [0.0, 9.0]), np.nextafter(el._TAN_3PI_8, [0.0, 9.0]),
                        [0.0, -0.0, 1.0, -1.0]])
    y = np.empty_like(x)
    _atan_all(x, y)
    ulp = _ulp_error(y, [mpmath.atan(mpmath.mpf(v)) for v in x])
    assert ulp.max() <= 2.0, (ulp.max(), x[ulp.argmax()])
    assert math.copysign(1.0, y[x == -0.0][-1]) == -1.0 and y[x == 0.0][0] == 0.0
    _atan_all(np.array([np.inf, -np.inf, np.nan]), y[:3])
    assert y[0] == math.pi / 2 and y[1] == -math.pi / 2 and np.isnan(y[2])


def test_sincos_within_2_ulp_up_to_100_rad():
    """sin and cos over [-100, 100] rad (the magic formula needs [0, C pi/2], C < 2; yaw
    [-pi, pi]) and near the quadrant edges: within 2 ulp where |value| > 1e-3, and within
    2e-16 absolute near the zeros (relative error there is the reduction's, bounded by the
    k pi/2 remainder's ~1e-21 x k)."""
    rng = np.random.default_rng(1)
    edges = np.pi / 4 * np.arange(-12, 13)
    x = np.concatenate([_points(rng, -100.0, 100.0, 1000), _points(rng, 0.0, 3.2, 500),
                        np.nextafter(edges, 10.0), np.nextafter(edges, -10.0), [0.0, 1e-300]])
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos_all(x, s, c)
    for y, f in ((s, mpmath.sin), (c, mpmath.cos)):
        ref = [f(mpmath.mpf(v)) for v in x]
        big = np.abs(np.array([float(v) for v in ref])) > 1e-3
        ulp = _ulp_error(y, ref)
        assert ulp[big].max() <= 2.0, (ulp[big].max(), x[big][ulp[big].argmax()])
        err = np.array([abs(float(mpmath.mpf(a) - b)) for a, b in zip(y, ref)])
        assert err.max() <= 2e-16


def test_sin_within_2_ulp_up_to_1e5_rad():
    """The road relief's arguments (`suspension.relief`: wave number up to ~80 rad/m times the
    distance along a piece, hundreds of metres): sin over [100, 1e5] rad and the quadrant
    edges there, within 2 ulp where |sin| > 1e-3 and within 2e-16 absolute everywhere."""
    rng = np.random.default_rng(3)
    edges = np.pi / 2 * np.array([64.0, 1001.0, 20001.0, 63661.0])
    x = np.concatenate([rng.uniform(100.0, 1e5, 1500), -rng.uniform(100.0, 1e5, 300),
                        np.nextafter(edges, 0.0), np.nextafter(edges, 1e6)])
    s, c = np.empty_like(x), np.empty_like(x)
    _sincos_all(x, s, c)
    ref = [mpmath.sin(mpmath.mpf(v)) for v in x]
    big = np.abs(np.array([float(v) for v in ref])) > 1e-3
    ulp = _ulp_error(s, ref)
    assert ulp[big].max() <= 2.0, (ulp[big].max(), x[big][ulp[big].argmax()])
    err = np.array([abs(float(mpmath.mpf(a) - b)) for a, b in zip(s, ref)])
    assert err.max() <= 2e-16


@pytest.mark.parametrize("n", [3, 4, 64])
def test_lanes_give_the_scalar_numbers(n):
    """The vectorised array loop (LLVM packs it into SIMD lanes) and one scalar call per value
    agree bit for bit: no fastmath, so lanes never change a result."""
    x = np.random.default_rng(n).uniform(-12.0, 12.0, n)
    y = np.empty(n)
    _atan_all(x, y)
    s, c, e = np.empty(n), np.empty(n), np.empty(n)
    _sincos_all(x, s, c)
    _exp_all(x, e)
    for i in range(n):
        assert y[i] == el.atan(x[i])
        assert (s[i], c[i]) == el.sincos(x[i])
        assert e[i] == el.exp(x[i])


@numba.njit(cache=True)
def _exp_all(x, out):
    for i in range(x.shape[0]):
        out[i] = el.exp(x[i])


def test_exp_within_2_ulp_over_its_range():
    """e^x on [-708, 709] (the load sensitivity's arguments are in [-15, 0]), dense on [-20, 1]
    and at the reduction's edges: within 2 ulp; clamped outside (e^-708 stands for 0)."""
    rng = np.random.default_rng(2)
    half = math.log(2) / 2 * np.arange(-41, 4, 2)
    x = np.concatenate([_points(rng, -20.0, 1.0, 1500), _points(rng, -708.0, 709.0, 400),
                        np.nextafter(half, 9.0), np.nextafter(half, -9.0), [0.0, -1e-300, 1e-300]])
    y = np.empty_like(x)
    _exp_all(x, y)
    ulp = _ulp_error(y, [mpmath.exp(mpmath.mpf(v)) for v in x])
    assert ulp.max() <= 2.0, (ulp.max(), x[ulp.argmax()])
    _exp_all(np.array([-1e4, 1e4]), y[:2])
    assert y[0] == el.exp(-708.0) and y[1] == el.exp(709.0)


_DRIVE = """
import sys
import numpy as np
from madsim.cars import load_car
from madsim.physics.world import World
from madsim.tracks import load_track
w = World(load_track("madsim-road"), [load_car("madsim-sedan"), load_car("madsim-gt")],
          np.random.default_rng(0), contact=False)
w.reset(np.array([[10.0, 0.0, 2.0], [40.0, 1.0, 30.0]]), gears=1)
u = np.array([[0.3, 1.0, 0.0, 1.0, 0.0], [-0.2, 0.6, 0.0, 3.0, 0.0]])
for _ in range(30):
    u[:, 0] *= -1
    w.step(u)
sys.stdout.write(w.state.tobytes().hex())
"""


def test_compiled_kernel_equals_plain_python():
    """The car kernel with its tyres in SIMD lanes gives bit for bit what the same code gives as
    plain Python (NUMBA_DISABLE_JIT=1: one wheel at a time, Python floats): 30 ticks of a car
    launching from 2 m/s in first gear (the implicit spin step) and one at 30 m/s, weaving."""
    import os
    import subprocess
    import sys

    runs = []
    for jit_off in ("0", "1"):
        env = dict(os.environ, NUMBA_DISABLE_JIT=jit_off)
        out = subprocess.run([sys.executable, "-c", _DRIVE], env=env, capture_output=True, text=True,
                             timeout=120, check=True)
        runs.append(out.stdout)
    assert runs[0] == runs[1] and len(runs[0]) > 1000
