"""Optimisers of one call's parameters, all on [0, 1]-scaled parameters: CMA-ES, Torczon's parallel
direct search (the paper's, through OPT++), Nelder-Mead and simulated annealing (scipy), and a
batched Levenberg-Marquardt polish (DiLorenzo et al. 2008, 6.2, Fig. 7).  See :mod:`laughlab.hill.fit`.
"""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from laughlab.hill.problem import CallProblem, FitParams


def _lhs(n: int, d: int, rng) -> np.ndarray:
    cut = (np.arange(n)[:, None] + rng.uniform(size=(n, d))) / n
    for j in range(d):
        cut[:, j] = cut[rng.permutation(n), j]
    return cut


def pds(problem: CallProblem, u0, fit: FitParams) -> tuple[np.ndarray, float]:
    """Torczon's multidirectional search, batched, from several starts at once; returns ``(u, cost)``.

    One batch evaluates the warm start ``u0`` and ``init_points`` Latin-hypercube
    points; the ``starts`` best seed simplices (edge 0.15) that then move
    together: each iteration evaluates the reflection, expansion and
    contraction of every simplex (``3 * 7 * starts`` parameter sets, one batch).
    """
    rng = np.random.default_rng(fit.seed)
    d = len(u0)
    t_start = time.perf_counter()
    pts = np.vstack([np.clip(u0, 0, 1)[None, :], _lhs(fit.init_points, d, rng)])
    f0 = problem.errors(pts)
    order = np.argsort(f0)[:max(1, fit.starts)]
    step = 0.15
    simplices, values = [], []
    for i in order:
        b = pts[i]
        simplices.append(np.vstack([b, b + step * np.eye(d) * np.where(b + step <= 1.0, 1.0, -1.0)[None, :]]))
    fv = problem.errors(np.vstack([sx[1:] for sx in simplices])).reshape(len(order), d)
    values = [np.concatenate([[f0[i]], fv[j]]) for j, i in enumerate(order)]
    active = list(range(len(order)))
    while active and problem.evals + 3 * d * len(active) <= fit.max_evals:
        if fit.time_budget_s is not None and time.perf_counter() - t_start > fit.time_budget_s:
            break
        trial, keep = [], []
        for j in active:
            sx, fs = simplices[j], values[j]
            ib = int(np.argmin(fs))
            vb = sx[ib]
            others = np.delete(sx, ib, axis=0)
            if np.max(np.abs(others - vb)) < fit.tol:
                continue
            keep.append((j, vb, fs[ib]))
            trial += [np.clip(2.0 * vb - others, 0.0, 1.0), np.clip(3.0 * vb - 2.0 * others, 0.0, 1.0),
                      0.5 * (vb + others)]
        if not keep:
            break
        f = problem.errors(np.vstack(trial)).reshape(len(keep), 3, d)
        pts_all = np.stack(trial).reshape(len(keep), 3, d, d)
        active = []
        for (j, vb, fb), fj, pj in zip(keep, f, pts_all):
            fr, fe, fc = fj
            if fr.min() < fb:
                k = 1 if fe.min() < fr.min() else 0
            else:
                k = 2
            simplices[j] = np.vstack([vb[None, :], pj[k]])
            values[j] = np.concatenate([[fb], fj[k]])
            active.append(j)
    best = min(range(len(simplices)), key=lambda j: values[j].min())
    ib = int(np.argmin(values[best]))
    return simplices[best][ib], float(values[best][ib])


def cmaes(problem: CallProblem, u0, fit: FitParams) -> tuple[np.ndarray, float]:
    """CMA-ES (Hansen's (mu/mu_w, lambda) evolution strategy), one generation per batch.

    Starts at the best of the warm start and ``init_points`` Latin-hypercube
    points (one batch), step size ``sigma0`` (0.3); samples outside [0, 1] are clipped and
    the clipped step is used in the update.  Returns ``(u, cost)``.
    """
    rng = np.random.default_rng(fit.seed)
    n = len(u0)
    t_start = time.perf_counter()
    pts = np.vstack([np.clip(u0, 0, 1)[None, :], _lhs(fit.init_points, n, rng)])
    f0 = problem.errors(pts)
    ib = int(np.argmin(f0))
    best_u, best_f = pts[ib].copy(), float(f0[ib])
    lam = max(4, fit.popsize)
    mu = lam // 2
    w = np.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mueff = 1.0 / np.sum(w ** 2)
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = (mueff + 2) / (n + mueff + 5)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    damps = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    chi_n = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))
    m, sigma = best_u.copy(), fit.sigma0
    c = np.eye(n)
    b, d = np.eye(n), np.ones(n)
    pc, ps = np.zeros(n), np.zeros(n)
    g = 0
    while problem.evals + lam <= fit.max_evals:
        if fit.time_budget_s is not None and time.perf_counter() - t_start > fit.time_budget_s:
            break
        g += 1
        y = rng.standard_normal((lam, n)) @ (b * d).T
        x = np.clip(m + sigma * y, 0.0, 1.0)
        y = (x - m) / sigma
        f = problem.errors(x)
        k = int(np.argmin(f))
        if f[k] < best_f:
            best_u, best_f = x[k].copy(), float(f[k])
        idx = np.argsort(f)[:mu]
        yw = w @ y[idx]
        m = m + sigma * yw
        inv_sqrt = b @ np.diag(1.0 / d) @ b.T
        ps = (1 - cs) * ps + math.sqrt(cs * (2 - cs) * mueff) * (inv_sqrt @ yw)
        hsig = np.linalg.norm(ps) / math.sqrt(1 - (1 - cs) ** (2 * g)) / chi_n < 1.4 + 2 / (n + 1)
        pc = (1 - cc) * pc + hsig * math.sqrt(cc * (2 - cc) * mueff) * yw
        yi = y[idx]
        c = ((1 - c1 - cmu) * c + c1 * (np.outer(pc, pc) + (1 - hsig) * cc * (2 - cc) * c)
             + cmu * (yi.T * w) @ yi)
        sigma *= math.exp((cs / damps) * (np.linalg.norm(ps) / chi_n - 1))
        sigma = min(sigma, 1.0)
        c = np.triu(c) + np.triu(c, 1).T
        ev, b = np.linalg.eigh(c)
        d = np.sqrt(np.maximum(ev, 1e-20))
        if sigma * d.max() < fit.tol:
            break
    return best_u, best_f


def polish(problem: CallProblem, u, f, fit: FitParams, iterations: int = 6, h: float = 1e-3):
    """Levenberg-Marquardt steps on the residuals, batched: each iteration simulates the Jacobian's
    finite differences at four damped trial steps (4 x 8 parameter sets, one batch) and keeps the best."""
    d = len(u)
    lams = np.array([1e-3, 1e-2, 1e-1, 1.0])
    r, _ = problem.residuals(np.vstack([u, u + h * np.eye(d)]))
    jac = ((r[1:] - r[0]) / h).T
    r0 = r[0]
    for _ in range(iterations):
        if problem.evals + 4 * (d + 1) > fit.max_evals + fit.polish_evals:
            break
        jtj, g = jac.T @ jac, jac.T @ r0
        trials = []
        for lam in lams:
            step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-9), -g)
            trials.append(np.clip(u + step, 0.0, 1.0))
        pts = np.vstack([np.vstack([t, t + h * np.eye(d)]) for t in trials])
        res, cost = problem.residuals(pts)
        cost = cost.reshape(4, d + 1)[:, 0]
        k = int(np.argmin(cost))
        if not cost[k] < f:
            break
        u, f = trials[k], float(cost[k])
        rk = res.reshape(4, d + 1, -1)[k]
        jac, r0 = ((rk[1:] - rk[0]) / h).T, rk[0]
    return u, f


def nelder_mead(problem: CallProblem, u0, fit: FitParams) -> tuple[np.ndarray, float]:
    from scipy.optimize import minimize

    res = minimize(problem.error, np.clip(u0, 0, 1), method="Nelder-Mead", bounds=[(0.0, 1.0)] * len(u0),
                   options={"maxfev": fit.max_evals, "xatol": fit.tol, "fatol": 1e-4, "adaptive": True})
    return np.clip(res.x, 0, 1), float(res.fun)


class _Spent(Exception):
    """The evaluation budget is spent (:func:`annealing`)."""


def annealing(problem: CallProblem, u0, fit: FitParams) -> tuple[np.ndarray, float]:
    """scipy's ``dual_annealing``, stopped at ``fit.max_evals`` evaluations, its best so far kept.

    Its ``maxfun`` is a soft limit (a local search under way runs to its end): with 100 it took 1311 evaluations
    where Nelder-Mead, CMA-ES and PDS took 100-109, and Fig. 7 compared unequal budgets (a new-user review)."""
    from scipy.optimize import dual_annealing

    best, spent = [np.clip(u0, 0, 1), math.inf], problem.evals + fit.max_evals   # the problem counts evaluations

    def error(u):
        if problem.evals >= spent:
            raise _Spent
        f = problem.error(u)
        if f < best[1]:
            best[0], best[1] = np.clip(np.asarray(u, float), 0, 1), float(f)
        return f

    try:
        res = dual_annealing(error, [(0.0, 1.0)] * len(u0), maxfun=fit.max_evals, seed=fit.seed, x0=np.clip(u0, 0, 1))
        return np.clip(res.x, 0, 1), float(res.fun)
    except _Spent:
        return best[0], best[1]


def optimise(problem: CallProblem, u0, fit: FitParams, method: str | None = None) -> tuple[np.ndarray, float]:
    """Minimise the call's error with ``method`` (default ``fit.method``); returns scaled ``(u, error)``."""
    method = method or fit.method
    fn = {"pds": pds, "cma": cmaes, "nelder-mead": nelder_mead, "annealing": annealing}[method]
    u, f = fn(problem, u0, fit)
    if fit.polish_evals > 0 and method in ("pds", "cma"):
        u, f = polish(problem, u, f, fit)
    return u, f


# --- fitting a whole recording -------------------------------------------------------------------
