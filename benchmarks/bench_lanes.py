"""Would SIMD lanes across cars pay? A component figure: one stage of the car sub-step written for
1 car per loop body (its 4 wheels in 4 lanes, as `kernel.advance_car` runs them today) and for
G = 2, 4, 8 cars interleaved in one loop body (4 G lanes: wheel k of car c in lane 4 c + k).

The stage is the sub-step's dependent chain around the tyres, with the kernel's own tyre code
(`kernel._tyre` / `tyre_shape` with `elementary`'s atan, sincos and exp): per car and sub-step,
the yaw's sin and cos, body-frame velocities, each wheel's contact-point velocity, load scale
K = Fz mu (lf0 + lfd exp(lfk Fz / Fz0)), tyre force and slope, the implicit spin step, then the
force and moment sums and the integration of velocities, yaw rate, yaw and position, which the
next sub-step reads (so one car's sub-steps form one latency chain, as in `advance_car`). Every
variant does the same scalar operations in the same order on each car (no fastmath): the final
states are compared bit for bit. The yaw's sin and cos come from libm (`math.sin`, `math.cos`,
what `advance_car` calls; a call LLVM cannot put in lanes) or from `elementary.sincos` (lane-
friendly, other bits: a rounding change the kernel would have to take).

Prints ns per car sub-step (CPU time, best of --repeats runs over --cars cars x --substeps
sub-steps; compiled before timing: a warm component figure) and the speed-up over G = 1.
Run: python benchmarks/bench_lanes.py [--cars 1024] [--substeps 10] [--repeats 7]
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from madsim.physics import elementary as el
from madsim.physics.kernel import _tyre

GROUPS = (1, 2, 4, 8)
# per-car constants (columns of `cars`)
(K_A, K_B, K_HALF_T, K_MASS, K_IZZ, K_RAD, K_IW, K_BF, K_CF, K_EF, K_BR, K_CR, K_ER, K_SKID, K_MU,
 K_LF0, K_LFD, K_LFK, K_OPL, K_FZF, K_FZR, K_STEER, K_TQ) = range(23)
N_CONST = 23
# per-car state (columns of `st`)
S_X, S_Y, S_YAW, S_VXG, S_VYG, S_R, S_W = 0, 1, 2, 3, 4, 5, 6      # S_W .. S_W + 3: spins
N_STATE = 10


def _stack(n: int):
    """An intrinsic: a pointer to n float64 on the calling function's stack."""
    @intrinsic
    def stack(typingctx):
        def codegen(context, builder, signature, args):
            return cgutils.alloca_once(builder, ir.DoubleType(), size=n)
        return types.CPointer(types.float64)(), codegen
    return stack


@numba.njit(inline="always", error_model="numpy")
def _libm_sincos(x):
    return math.sin(x), math.cos(x)


@numba.njit(inline="always", error_model="numpy")
def _el_sincos(x):
    return el.sincos(x)


@numba.njit(inline="always", error_model="numpy")
def _lane(q, r, vx, vy, dt, l_px, l_py, l_fz, l_mu, l_lf0, l_lfd, l_lfk, l_opl, l_cd, l_sd, l_w,
          l_rad, l_b, l_c, l_e, l_skid, l_tq, l_iw, l_fx, l_fy):
    """Lane q: one wheel's contact velocity, load scale, tyre, force in the body frame and
    implicit spin step (the car's yaw rate r and body velocity vx, vy)."""
    vwx = vx - l_py[q] * r
    vwy = vy + l_px[q] * r
    fz = l_fz[q]
    kk = fz * l_mu[q] * (l_lf0[q] + l_lfd[q] * el.exp(l_lfk[q] * fz / l_opl[q]))
    ft, fn, dft = _tyre(vwx, vwy, l_cd[q], l_sd[q], l_w[q] * l_rad[q], l_b[q], l_c[q], l_e[q],
                        l_skid[q])
    gt, gn = ft * kk, fn * kk
    l_fx[q] = gt * l_cd[q] - gn * l_sd[q]
    l_fy[q] = gt * l_sd[q] + gn * l_cd[q]
    rad = l_rad[q]
    l_w[q] += dt * (l_tq[q] - gt * rad) / (l_iw[q] + dt * dft * kk * rad * rad)


def make_stage(g: int, sincos, car_major: bool = False):
    """The stage for `g` cars per loop body, the yaw's sin and cos from `sincos`; lanes
    wheel-major (wheel k of car c in lane 4 c + k: one loop over 4 g lanes) or car-major (lane
    k g + c: per wheel one loop over the g cars, whose per-car values are then contiguous)."""
    nl = 4 * g
    lanes, per_car = _stack(nl), _stack(g)

    @numba.njit(error_model="numpy", _nrt=False)
    def stage(cars, st, nsub, dt, lane_cap):
        n_l = min(nl, lane_cap)                  # a trip count LLVM cannot fold: it vectorises
        n_g = min(g, lane_cap)                   # (the same for the car-major loop)
        l_cd, l_sd, l_w = lanes(), lanes(), lanes()
        l_px, l_py, l_rad, l_b, l_c = lanes(), lanes(), lanes(), lanes(), lanes()
        l_e, l_skid, l_fz, l_mu, l_lf0 = lanes(), lanes(), lanes(), lanes(), lanes()
        l_lfd, l_lfk, l_opl, l_tq, l_iw = lanes(), lanes(), lanes(), lanes(), lanes()
        l_fx, l_fy = lanes(), lanes()
        c_vx, c_vy, c_cy, c_sy, c_r = per_car(), per_car(), per_car(), per_car(), per_car()
        for g0 in range(0, st.shape[0] - g + 1, g):
            for c in range(g):                   # constants into lanes
                i = g0 + c
                for k in range(4):
                    q = k * g + c if car_major else 4 * c + k
                    front = k < 2
                    l_px[q] = cars[i, K_A] if front else -cars[i, K_B]
                    l_py[q] = cars[i, K_HALF_T] if k % 2 == 0 else -cars[i, K_HALF_T]
                    l_b[q] = cars[i, K_BF] if front else cars[i, K_BR]
                    l_c[q] = cars[i, K_CF] if front else cars[i, K_CR]
                    l_e[q] = cars[i, K_EF] if front else cars[i, K_ER]
                    l_fz[q] = cars[i, K_FZF] if front else cars[i, K_FZR]
                    l_cd[q] = math.cos(cars[i, K_STEER]) if front else 1.0
                    l_sd[q] = math.sin(cars[i, K_STEER]) if front else 0.0
                    l_tq[q] = 0.0 if front else cars[i, K_TQ]
                    l_rad[q], l_iw[q], l_skid[q] = cars[i, K_RAD], cars[i, K_IW], cars[i, K_SKID]
                    l_mu[q], l_lf0[q], l_lfd[q] = cars[i, K_MU], cars[i, K_LF0], cars[i, K_LFD]
                    l_lfk[q], l_opl[q] = cars[i, K_LFK], cars[i, K_OPL]
                    l_w[q] = st[i, S_W + k]
            for _ in range(nsub):
                for c in range(g):               # per car: body-frame velocities
                    i = g0 + c
                    s, co = sincos(st[i, S_YAW])
                    vxg, vyg = st[i, S_VXG], st[i, S_VYG]
                    c_cy[c], c_sy[c], c_r[c] = co, s, st[i, S_R]
                    c_vx[c] = vxg * co + vyg * s
                    c_vy[c] = vyg * co - vxg * s
                if car_major:                    # per wheel, the g cars in lanes
                    for k in range(4):
                        for c in range(n_g):
                            _lane(k * g + c, c_r[c], c_vx[c], c_vy[c], dt, l_px, l_py, l_fz,
                                  l_mu, l_lf0, l_lfd, l_lfk, l_opl, l_cd, l_sd, l_w, l_rad, l_b,
                                  l_c, l_e, l_skid, l_tq, l_iw, l_fx, l_fy)
                else:                            # the 4 g wheels in lanes
                    for q in range(n_l):
                        c = q // 4
                        _lane(q, c_r[c], c_vx[c], c_vy[c], dt, l_px, l_py, l_fz, l_mu, l_lf0,
                              l_lfd, l_lfk, l_opl, l_cd, l_sd, l_w, l_rad, l_b, l_c, l_e, l_skid,
                              l_tq, l_iw, l_fx, l_fy)
                for c in range(g):               # per car: sums and integration
                    i = g0 + c
                    q0, q1, q2, q3 = ((c, g + c, 2 * g + c, 3 * g + c) if car_major
                                      else (4 * c, 4 * c + 1, 4 * c + 2, 4 * c + 3))
                    fx = ((l_fx[q0] + l_fx[q1]) + l_fx[q2]) + l_fx[q3]
                    fy = ((l_fy[q0] + l_fy[q1]) + l_fy[q2]) + l_fy[q3]
                    mz = 0.0
                    for q in (q0, q1, q2, q3):
                        mz += l_px[q] * l_fy[q] - l_py[q] * l_fx[q]
                    ax, ay = fx / cars[i, K_MASS], fy / cars[i, K_MASS]
                    co, s = c_cy[c], c_sy[c]
                    st[i, S_VXG] += (ax * co - ay * s) * dt
                    st[i, S_VYG] += (ax * s + ay * co) * dt
                    r = st[i, S_R] + mz / cars[i, K_IZZ] * dt
                    st[i, S_R] = r
                    st[i, S_YAW] += r * dt
                    st[i, S_X] += st[i, S_VXG] * dt
                    st[i, S_Y] += st[i, S_VYG] * dt
            for c in range(g):
                for k in range(4):
                    st[g0 + c, S_W + k] = l_w[k * g + c if car_major else 4 * c + k]
    return stage


def cars_and_states(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """n cars near a sedan (constants jittered by a few %) at 20-35 m/s, steered a little."""
    base = np.array([1.2, 1.4, 0.8, 1150.0, 1500.0, 0.31, 1.2, 12.0, 1.6, 0.1, 12.0, 1.6, 0.1,
                     0.3, 1.1, 0.8, 0.4, -0.5, 3000.0, 3100.0, 2600.0, 0.02, 250.0])
    cars = base * rng.uniform(0.97, 1.03, (n, N_CONST))
    cars[:, K_STEER] = rng.uniform(-0.05, 0.05, n)
    st = np.zeros((n, N_STATE))
    st[:, S_YAW] = rng.uniform(-math.pi, math.pi, n)
    v = rng.uniform(20.0, 35.0, n)
    st[:, S_VXG], st[:, S_VYG] = v * np.cos(st[:, S_YAW]), v * np.sin(st[:, S_YAW])
    st[:, S_W:S_W + 4] = (v / cars[:, K_RAD])[:, None] * rng.uniform(0.99, 1.02, (n, 4))
    return cars, st


def time_stage(stage, cars, st0, nsub, repeats) -> tuple[float, np.ndarray]:
    """Best CPU ns per car sub-step over `repeats` runs from st0; the final state of one."""
    best = math.inf
    for _ in range(repeats):
        st = st0.copy()
        t0 = time.process_time()
        stage(cars, st, nsub, 0.002, 1 << 20)
        best = min(best, time.process_time() - t0)
    return best * 1e9 / (cars.shape[0] * nsub), st


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cars", type=int, default=1024, help="a multiple of 8")
    ap.add_argument("--substeps", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    if args.cars % max(GROUPS):
        ap.error(f"--cars must be a multiple of {max(GROUPS)}")
    cars, st0 = cars_and_states(args.cars, np.random.default_rng(0))
    ref = None               # libm's final states: every libm variant must give these bits
    for name, sincos, major in (
            ("wheel-major lanes, libm sin/cos of the yaw", _libm_sincos, False),
            ("car-major lanes, libm sin/cos of the yaw", _libm_sincos, True),
            ("car-major lanes, elementary.sincos of the yaw", _el_sincos, True)):
        stages = {g: make_stage(g, sincos, major) for g in GROUPS}
        for g, stage in stages.items():
            stage(cars, st0.copy(), 1, 0.002, 1 << 20)   # compile
        results = {}
        for g, stage in stages.items():
            results[g] = time_stage(stage, cars, st0, args.substeps, args.repeats)
        if ref is None:
            ref = results[1][1]
        print(f"{name}: {args.cars} cars x {args.substeps} sub-steps, best of {args.repeats} "
              "(CPU, component figure)")
        for g, (ns, st) in results.items():
            same = st.view(np.int64).tolist() == ref.view(np.int64).tolist()
            verdict = "bit-identical" if same else "DIFFER"
            print(f"  {g} car(s) per loop body, {4 * g:2d} lanes: {ns:6.1f} ns per car sub-step "
                  f"({results[1][0] / ns:4.2f}x; final states {verdict} to wheel-major, 1 car, "
                  "libm)")


if __name__ == "__main__":
    main()
