"""The Hill torso's step for a batch of torsos, compiled with numba (the optimiser's inner loop).

:meth:`laughlab.hill.torso.Torso._step` does one linearly implicit Euler step of a
batch with some sixty numpy operations on arrays of a few dozen numbers, so
numpy's per-call overhead (about 0.17 ms a step) is most of its cost, whatever
the batch.  :func:`step_batch` is the same arithmetic, torso by torso, in one
compiled loop: the muscles (:func:`laughlab.hill.muscle._hill`), the implicit matrix
and right side, the chest wall's pleural and stop pressures at the predicted
volume (:meth:`laughlab.hill.lung.Lung.predict`), the 9 x 9 solve (Gaussian
elimination with partial pivoting instead of LAPACK: the same solution to
rounding) and the lungs' two-loop update with its Newton step
(:meth:`laughlab.hill.lung.Lung.step`, implicit scheme).  The equations and units
are documented there; nothing here is new physics.  Results agree with the
numpy step to rounding (``tests/test_hill.py``); the per-call fit runs about
three times faster (``benchmarks/bench_hill.py``).

When numba is missing (or ``LAUGHLAB_NUMBA=0``), :data:`AVAILABLE` is False
and the torso keeps its numpy step.
"""
from __future__ import annotations

import math
import os

import numpy as np

try:  # pragma: no cover - import guard
    if os.environ.get("LAUGHLAB_NUMBA", "1") == "0":
        raise ImportError("disabled by LAUGHLAB_NUMBA=0")
    from numba import njit

    AVAILABLE = True
    WHY = ""
except ImportError as _exc:  # pragma: no cover - numba missing
    AVAILABLE = False
    WHY = str(_exc)   # why the numpy step runs (metrics.json's hill_kernel)

    def njit(*args, **kwargs):
        def wrap(fn):
            return fn
        return wrap


@njit(cache=True, fastmath=False, nogil=True)
def _solve_inplace(w, r, n):
    """Solve ``w x = r`` (n x n) by Gaussian elimination with partial pivoting; ``r`` becomes ``x``."""
    for c in range(n):
        piv = c
        best = abs(w[c, c])
        for i in range(c + 1, n):
            v = abs(w[i, c])
            if v > best:
                best, piv = v, i
        if piv != c:
            for j in range(n):
                w[c, j], w[piv, j] = w[piv, j], w[c, j]
            r[c], r[piv] = r[piv], r[c]
        inv = 1.0 / w[c, c]
        for i in range(c + 1, n):
            f = w[i, c] * inv
            if f != 0.0:
                for j in range(c + 1, n):
                    w[i, j] -= f * w[c, j]
                r[i] -= f * r[c]
    for c in range(n - 1, -1, -1):
        acc = r[c]
        for j in range(c + 1, n):
            acc -= w[c, j] * r[j]
        r[c] = acc / w[c, c]


@njit(cache=True, fastmath=False, nogil=True)
def step_batch(q, qd, a, spine, dt, jt_over_l, gj, k_lin, d_lin, f_pre, kp, isp, jmat, gain, g_over_l,
               w_lin, k_pe, b_pe, inv_v_max, f_max, w_fl, a_fv, b_fv, pe_cap, inv_r, v0, a_di, irc, idi,
               v_lo, inv_sw, stop_c, stop_p, c_p,
               v_lung, v_pl_s, p_pl_s, ptm_s, p_lung_s, q_flow, v_pl_min, p_pl0, ptm_a, ptm_b,
               c_atm, k_air, p_atm, cmh2o_per_atm, v_cw_out):
    """One step of every torso of the batch, in place (the arguments are :class:`laughlab.hill.torso.Torso`'s
    arrays and constants; ``spine`` is the spine target per torso, rad)."""
    b, nq = q.shape
    nm = a.shape[1]
    dl = np.empty(nm)
    s = np.empty(nm)
    f = np.empty(nm)
    kim = np.empty(nm)
    dim = np.empty(nm)
    w = np.empty((nq, nq))
    rhs = np.empty(nq)
    inv_c = 1.0 / c_atm
    dt2 = dt * dt
    for t in range(b):
        # muscles: stretch l~ - 1 and strain rate, Hill forces and implicit weights (hill._hill)
        for m in range(nm):
            x1 = 0.0
            x2 = 0.0
            for i in range(nq):
                x1 += q[t, i] * jt_over_l[i, m]
                x2 += qd[t, i] * jt_over_l[i, m]
            dl[m] = x1
            s[m] = x2
            d = x1 / w_fl
            fl = 1.0 - d * d
            if fl < 0.0:
                fl = 0.0
            den = b_fv + abs(x2 * inv_v_max[m])
            fv = (b_fv + a_fv * b_fv) / den - a_fv
            if fv < 0.0:
                fv = 0.0
            ex = 10.0 * x1 - 5.0
            if ex > pe_cap:
                ex = pe_cap
            ee = k_pe[m] * math.exp(ex)
            af = a[t, m] * f_max[m]
            afv = af * fv
            pas = ee + b_pe[m] * x2
            if pas < 0.0:
                pas = 0.0
            f[m] = pas + afv * fl
            kk = (-2.0 / w_fl) * d
            if kk < 0.0:
                kk = 0.0
            kim[m] = 10.0 * ee + afv * kk
            dim[m] = b_pe[m] + af * fl * (b_fv * (1.0 + a_fv) * inv_v_max[m]) / (den * den)
        # generalised forces and the right side dt (F - dt K v)
        for i in range(nq):
            acc = f_pre[i]
            for m in range(nm):
                acc -= f[m] * gj[m, i]
            for j in range(nq):
                acc -= q[t, j] * k_lin[j, i] + qd[t, j] * d_lin[j, i]
            if i == isp:
                acc += kp * spine[t]
            corr = 0.0
            for m in range(nm):
                corr += kim[m] * s[m] * gain[m] * jmat[m, i]
            for j in range(nq):
                corr += qd[t, j] * k_lin[j, i]
            rhs[i] = acc - dt * corr
        # implicit matrix M + dt D + dt^2 K, muscles included
        for i in range(nq):
            for j in range(nq):
                w[i, j] = w_lin[i, j]
        for m in range(nm):
            c = (dt * dim[m] + dt2 * kim[m]) * g_over_l[m]
            if c != 0.0:
                for i in range(nq):
                    ji = jmat[m, i]
                    if ji != 0.0:
                        for j in range(nq):
                            w[i, j] += c * ji * jmat[m, j]
        # chest wall: pleural pressure and volume stops at the predicted volume, with their slope
        rho = 1.0 + q[t, irc] * inv_r
        base = v0 + a_di * q[t, idi]
        a20 = (2.0 * inv_r) * base * rho
        a21 = a_di * rho * rho
        rp = 1.0 + (q[t, irc] + dt * qd[t, irc]) * inv_r
        v_pred = (v0 + a_di * (q[t, idi] + dt * qd[t, idi])) * rp * rp
        e = (v_lo - v_pred) * inv_sw
        e = min(max(e, -50.0), 50.0)
        lo = math.exp(e)
        hi = stop_c / lo
        p_stop = stop_p * (lo - hi)
        dstop = -(stop_p * inv_sw) * (lo + hi)
        # the lungs' predicted pleural pressure and its slope (lung.Lung.predict, implicit scheme)
        vp = max(v_pred - v_lung[t], v_pl_min[t])
        pp = v_pl_s[t] / vp * p_pl_s[t]
        dp = pp + ptm_s[t] - p_atm
        s_pl = pp / vp
        beta = dt2 * (s_pl + inv_c) / k_air
        cc = dt2 * abs(dp) / k_air
        x = 2.0 * cc / (beta + math.sqrt(beta * beta + 4.0 * cc))
        if dp < 0.0:
            x = -x
        elif dp == 0.0:
            x = 0.0
        vpn = vp + x
        ppn = vp / vpn * pp
        r_dt = 2.0 * k_air * abs(x) / dt2
        slope = -s_pl * (inv_c + r_dt) / (s_pl + inv_c + r_dt) * cmh2o_per_atm
        p_pl = (ppn - p_pl0[t]) * cmh2o_per_atm
        g = c_p * (p_pl + p_stop)
        rhs[0] += g * a20
        rhs[1] += g * a21
        h = dt2 * c_p * (slope + dstop)
        w[0, 0] -= h * a20 * a20
        w[0, 1] -= h * a20 * a21
        w[1, 0] -= h * a21 * a20
        w[1, 1] -= h * a21 * a21
        for i in range(nq):
            rhs[i] *= dt
        _solve_inplace(w, rhs, nq)
        for i in range(nq):
            qd[t, i] += rhs[i]
            q[t, i] += dt * qd[t, i]
        rho = 1.0 + q[t, irc] * inv_r
        v_cw = (v0 + a_di * q[t, idi]) * rho * rho
        v_cw_out[t] = v_cw
        # the lungs' two-loop update with one Newton step (lung.Lung.step, implicit scheme)
        vp = max(v_cw - v_lung[t], v_pl_min[t])
        pp = v_pl_s[t] / vp * p_pl_s[t]
        ptm = ptm_s[t]
        dp = pp + ptm - p_atm
        s_pl = pp / vp
        beta = dt2 * (s_pl + inv_c) / k_air
        cc = dt2 * abs(dp) / k_air
        x = 2.0 * cc / (beta + math.sqrt(beta * beta + 4.0 * cc))
        if dp < 0.0:
            x = -x
        elif dp == 0.0:
            x = 0.0
        cn = k_air / dt2
        vx = vp + x
        ax = abs(x)
        fn = cn * x * ax - (pp * vp / vx + ptm - x * inv_c - p_atm)
        x = x - fn / (2.0 * cn * ax + pp * vp / (vx * vx) + inv_c)
        vpn = vp + x
        ppn = vp / vpn * pp
        vl = v_lung[t] - x
        ptm = ptm_a[t] + ptm_b * vl
        v_pl_s[t] = vpn
        p_pl_s[t] = ppn
        v_lung[t] = vl
        ptm_s[t] = ptm
        p_lung_s[t] = ppn + ptm
        q_flow[t] = x / dt
