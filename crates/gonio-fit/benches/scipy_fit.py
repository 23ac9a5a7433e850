#!/usr/bin/env python3
"""The scipy reference for the lobe-fit benchmark (`benches/fit.rs`).

The same problem as the Rust bench: per channel, three isotropic generalized cosine
lobes plus a Lambertian term (Lafortune et al. 1997, Eq. 8),

    f(u, v) = rho_d / pi + sum_j max(0, C_j (ux vx + uy vy) + Cz_j uz vz) ** n_j,

fitted to the bench's 97 920 noisy samples by minimising sum(((f - y) / sigma) ** 2)
with scipy.optimize.least_squares: vectorised numpy, the analytic Jacobian, the
lobe powers computed once per parameter vector and shared by `fun` and `jac`, the
three channels one after another. All of a model's parameters (rho_d, then C, Cz, n
per lobe) are searched by least_squares; nothing is projected out (no variable
projection).

Two modes, both timed with time.perf_counter (reading the CSV excluded):

* **no start** (the default, Gonio's problem): no start values, the same greedy
  multi-start search as Gonio's `fit_lobes` (`search` in src/fit/search.rs). Lobes are added
  one at a time; for each new lobe the same 56 seeds (beta in {1.3, 0.9, 0.5, -0.2,
  -0.5, -0.8, -1.1, -1.4} x n in {1.5, 3, 6, 12, 25, 50, 100}, the lobe's unit
  direction (sin beta / sqrt 2, sin beta / sqrt 2, cos beta)), the lobes already
  placed kept, each seed scored by the cost with the linear coefficients (rho_d and
  every lobe's strength) solved exactly by scipy.optimize.nnls on the weighted
  columns; the best four turned into full parameters (C = s^(1/n) c) and refined by
  least_squares (at most 15 (p + 1) function evaluations, p = 1 + 3 lobes, as Gonio's
  15 (p + 1) with its own p; never reached on the bench's data, where every
  refinement stops on ftol after 6-24), all on the every-k-th-pair subset of at
  most 2 000 pairs that Gonio searches on; the best of the four is kept. Then
  least_squares on all pairs from the best model.
* **from the truth** (a head start Gonio does not get): least_squares on all pairs
  from the true parameters perturbed by 10% (each multiplied by 1.1 or 0.9 in turn).

The 'lm' default tolerances (ftol = xtol = gtol = 1e-8) throughout. Standard errors
and Gonio's albedo check are not computed (Gonio's timed `fit_lobes` includes both).

Usage: scipy_fit.py [DATA.CSV] [--method trf|lm|dogbox] [--mode both|no-start|truth]
(defaults: the CSV the Rust bench writes, target/tmp/fit-bench-data.csv; method
'lm', MINPACK's Levenberg-Marquardt, the fastest of the three here — 'trf' took
1.7 s without a start where 'lm' took 0.7 s; both modes).
Needs numpy and scipy, which the project does not depend on:

    python3 -m venv /tmp/scipyenv && /tmp/scipyenv/bin/pip install numpy scipy
    /tmp/scipyenv/bin/python crates/gonio-fit/benches/scipy_fit.py
"""

import argparse
import math
import os
import sys
import time

# One BLAS thread unless the environment asks otherwise (set before numpy loads
# OpenBLAS): the matrices are small (the search's 1 999 x 4 nnls) or tall and thin
# (97 920 x 10), and on the 2-core bench machine OpenBLAS's default of two threads
# was no faster (no start, alternating runs: 0.54-0.80 s against 0.46-0.72 s) and
# burnt twice the CPU; one thread also makes scipy the one-core reference.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy.optimize import least_squares, nnls  # noqa: E402

# The bench's model (`MODEL` in benches/fit.rs): rho_d per channel, and per lobe
# (Cx = Cy, Cz, n) per channel.
RHO = [0.3094, 0.39667, 0.70837]
LOBES = [
    ([0.870567, 0.857255, 0.670982], [0.803624, 0.774290, 0.586674], [21.820103, 18.597755, 7.472717]),
    ([-0.451218, -0.406681, -0.41], [0.023907, 0.017601, 0.018], [2.774989, 2.581280, 2.58]),
    ([-1.031545, -1.029225, -1.03], [0.706734, 0.696065, 0.70], [66.899274, 63.767356, 63.8]),
]
NLOBES = len(LOBES)

# Gonio's start search (`seeds` and `search` in src/fit/search.rs, `FitOptions::default`).
SEED_BETAS = [1.3, 0.9, 0.5, -0.2, -0.5, -0.8, -1.1, -1.4]
SEED_NS = [1.5, 3.0, 6.0, 12.0, 25.0, 50.0, 100.0]
SEARCH_SAMPLES = 2000
REFINED = 4
PATIENCE = 15


def truth(ch):
    """The true parameter vector of channel ch: rho_d, then (C, Cz, n) per lobe."""
    p = [RHO[ch]]
    for cx, cz, n in LOBES:
        p += [cx[ch], cz[ch], n[ch]]
    return np.array(p)


def powers(c, cz, n, a, b):
    """max(0, c a + cz b) ** n (broadcasting), and the mask and ln of the base."""
    x = c * a + cz * b
    pos = x > 0.0
    lnx = np.log(np.where(pos, x, 1.0))
    return np.where(pos, np.exp(n * lnx), 0.0), x, pos, lnx


class Problem:
    """One channel, any number of lobes (from len(p)): residuals (f - y) / sigma and
    their analytic Jacobian."""

    def __init__(self, a, b, y, sigma):
        self.a = a  # ux vx + uy vy
        self.b = b  # uz vz
        self.y = y
        self.w = 1.0 / sigma
        self.p = None
        self.f = None
        self.h = []  # per lobe: x ** n (0 where x <= 0)
        self.hx = []  # per lobe: n x ** (n - 1)
        self.hn = []  # per lobe: x ** n ln x

    def _update(self, p):
        if self.p is not None and np.array_equal(p, self.p):
            return
        f = np.full_like(self.a, p[0] / np.pi)
        self.h, self.hx, self.hn = [], [], []
        for j in range((p.size - 1) // 3):
            c, cz, n = p[1 + 3 * j : 4 + 3 * j]
            h, x, pos, lnx = powers(c, cz, n, self.a, self.b)
            f += h
            self.h.append(h)
            self.hx.append(np.where(pos, n * h / np.where(pos, x, 1.0), 0.0))
            self.hn.append(h * lnx)
        self.f = f
        self.p = p.copy()

    def fun(self, p):
        self._update(p)
        return (self.f - self.y) * self.w

    def jac(self, p):
        self._update(p)
        m = self.a.size
        jm = np.empty((m, p.size))
        jm[:, 0] = self.w / np.pi
        for j in range((p.size - 1) // 3):
            hxw = self.hx[j] * self.w
            jm[:, 1 + 3 * j] = hxw * self.a
            jm[:, 2 + 3 * j] = hxw * self.b
            jm[:, 3 + 3 * j] = self.hn[j] * self.w
        return jm


def solve(prob, p0, method, x_scale, max_nfev=None):
    return least_squares(prob.fun, p0, jac=prob.jac, method=method, x_scale=x_scale, max_nfev=max_nfev)


def search(prob, nlobes, method, x_scale, log):
    """Gonio's greedy multi-start search (module docs) on `prob` (the thinned pairs):
    the full parameter vector of the best nlobes-lobe model found."""
    a, b, w = prob.a, prob.b, prob.w
    wy = prob.y * w
    seeds = [(beta, n) for beta in SEED_BETAS for n in SEED_NS]  # Gonio's order
    sc = np.array([math.sin(beta) * math.sqrt(0.5) for beta, _ in seeds])[:, None]
    scz = np.array([math.cos(beta) for beta, _ in seeds])[:, None]
    sn = np.array([n for _, n in seeds])[:, None]
    # The seeds' columns of unit strength do not depend on the lobes placed: once.
    seed_cols = powers(sc, scz, sn, a, b)[0] * w  # 56 x m
    best = np.array([0.0])  # rho_d alone: no lobe placed yet
    evals = 0
    for l in range(1, nlobes + 1):
        placed = [best[1 + 3 * j : 4 + 3 * j] for j in range(l - 1)]
        cols = np.empty((a.size, l + 1))
        cols[:, 0] = w / np.pi
        for j, (c, cz, n) in enumerate(placed):
            cols[:, 1 + j] = powers(c, cz, n, a, b)[0] * w
        scored = []
        for k in range(len(seeds)):
            cols[:, l] = seed_cols[k]
            coef, rnorm = nnls(cols, wy)
            scored.append((rnorm * rnorm, k, coef))
        scored.sort(key=lambda s: s[0])  # stable, as Gonio's sort_by
        results = []
        for cost0, k, coef in scored[:REFINED]:
            # Full parameters from (direction, exponent, strength): C = s^(1/n) c. A lobe
            # the projection switched off (s = 0) gets a tiny strength instead, so that
            # its derivatives do not vanish.
            p0 = [coef[0]]
            for j, (c, cz, n) in enumerate(placed + [(sc[k, 0], scz[k, 0], sn[k, 0])]):
                r = max(coef[1 + j], 1e-12) ** (1.0 / n)
                p0 += [r * c, r * cz, n]
            p0 = np.array(p0)
            res = solve(prob, p0, method, x_scale, max_nfev=PATIENCE * (p0.size + 1))
            evals += res.nfev
            results.append((2.0 * res.cost, res.x))
        chi2, best = min(results, key=lambda r: r[0])
        log.append(f"{l} lobe(s): chi2 {chi2:.3f} on the subset")
    return best, evals


def load(path):
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    ti, pi_, to, po = (np.radians(data[:, k]) for k in range(4))
    nc = (len(header) - 4) // 2
    names = header[4 : 4 + nc]
    u = np.stack([np.sin(ti) * np.cos(pi_), np.sin(ti) * np.sin(pi_), np.cos(ti)])
    v = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)])
    a = u[0] * v[0] + u[1] * v[1]
    b = u[2] * v[2]
    y = [data[:, 4 + k] for k in range(nc)]
    sigma = [data[:, 4 + nc + k] for k in range(nc)]
    return names, a, b, y, sigma


def fmt(x):
    return np.array2string(x, precision=6, max_line_width=200)


def no_start(names, a, b, ys, sigmas, method, xs):
    print(
        f"no start: Gonio's greedy search ({len(SEED_BETAS) * len(SEED_NS)} seeds a lobe scored "
        f"by nnls, the best {REFINED} refined) on every k-th pair, then all pairs"
    )
    step = -(-a.size // SEARCH_SAMPLES)  # every k-th pair, so that at most 2 000 remain
    keep = np.arange(0, a.size, step)
    total = 0.0
    cpu0 = time.process_time()
    for ch, name in enumerate(names):
        t0 = time.perf_counter()
        sub = Problem(a[keep], b[keep], ys[ch][keep], sigmas[ch][keep])
        log = []
        p0, sevals = search(sub, NLOBES, method, xs, log)
        t1 = time.perf_counter()
        prob = Problem(a, b, ys[ch], sigmas[ch])
        res = solve(prob, p0, method, xs)
        dt = time.perf_counter() - t0
        total += dt
        chi2 = float(np.sum(res.fun**2))
        chi2_true = float(np.sum(prob.fun(truth(ch)) ** 2))
        print(
            f"  {name}: {dt:.3f} s (search on {keep.size} pairs {t1 - t0:.3f} s, {sevals} evaluations; "
            f"final {dt - (t1 - t0):.3f} s, nfev {res.nfev}, njev {res.njev}, status {res.status}), "
            f"chi2 {chi2:.3f} (true model: {chi2_true:.3f})"
        )
        print("     search:", "; ".join(log))
        order = np.argsort(res.x[3::3])  # lobes by exponent, as the truth's columns are not
        x = np.concatenate([res.x[:1]] + [res.x[1 + 3 * j : 4 + 3 * j] for j in order])
        print("     fitted (rho_d, then C, Cz, n a lobe, by n):", fmt(x))
    cpu = time.process_time() - cpu0
    print(f"scipy total (no start): {total:.3f} s ({cpu:.2f} s of CPU, all threads)")


def from_truth(names, a, b, ys, sigmas, method, xs):
    print("from the truth +-10%: least_squares on all pairs")
    total = 0.0
    cpu0 = time.process_time()
    for ch, name in enumerate(names):
        t = truth(ch)
        start = t * np.where(np.arange(t.size) % 2 == 0, 1.1, 0.9)
        prob = Problem(a, b, ys[ch], sigmas[ch])
        t0 = time.perf_counter()
        res = solve(prob, start, method, xs)
        dt = time.perf_counter() - t0
        total += dt
        chi2 = float(np.sum(res.fun**2))
        chi2_true = float(np.sum(prob.fun(t) ** 2))
        print(
            f"  {name}: {dt:.3f} s, chi2 {chi2:.3f} (true model: {chi2_true:.3f}; "
            f"least_squares cost = chi2/2 = {res.cost:.3f}), nfev {res.nfev}, "
            f"njev {res.njev}, status {res.status}"
        )
        print("     fitted (rho_d, then C, Cz, n a lobe):", fmt(res.x))
    cpu = time.process_time() - cpu0
    print(f"scipy total (from the truth +-10%): {total:.3f} s ({cpu:.2f} s of CPU, all threads)")


# A generic start, the same for every channel, that knows nothing of the data: a
# Lambertian term and three lobes — a broad and a sharp forward lobe about the mirror
# direction (Cx = Cy = -1.0 or -1.02, Cz = 1 or 0.7) and a retro-reflective one.
GENERIC = [0.5, -1.0, 1.0, 3.0, -1.02, 0.7, 50.0, 0.8, 0.8, 10.0]


def generic(names, a, b, ys, sigmas, method, xs):
    print("generic start: least_squares on all pairs from", GENERIC)
    total = 0.0
    for ch, name in enumerate(names):
        prob = Problem(a, b, ys[ch], sigmas[ch])
        t0 = time.perf_counter()
        res = solve(prob, np.array(GENERIC), method, xs)
        dt = time.perf_counter() - t0
        total += dt
        chi2 = float(np.sum(res.fun**2))
        chi2_true = float(np.sum(prob.fun(truth(ch)) ** 2))
        print(
            f"  {name}: {dt:.3f} s, chi2 {chi2:.3f} (true model: {chi2_true:.3f}), "
            f"nfev {res.nfev}, njev {res.njev}, status {res.status}"
        )
        order = np.argsort(res.x[3::3])
        x = np.concatenate([res.x[:1]] + [res.x[1 + 3 * j : 4 + 3 * j] for j in order])
        print("     fitted (rho_d, then C, Cz, n a lobe, by n):", fmt(x))
    print(f"scipy total (generic start): {total:.3f} s")


def chi2_of(path, names, a, b, ys, sigmas):
    """chi2 per channel of an isotropic lafortune model file (Cx = Cy) on the data."""
    import tomllib

    with open(path, "rb") as fh:
        m = tomllib.load(fh)
    for ch, name in enumerate(names):
        p = [m["diffuse"]["rho"][ch]]
        for lobe in m["lobes"]:
            p += [lobe["cx"][ch], lobe["cz"][ch], lobe["n"][ch]]
        chi2 = float(np.sum(Problem(a, b, ys[ch], sigmas[ch]).fun(np.array(p)) ** 2))
        print(f"  {name}: chi2 of {os.path.basename(path)} {chi2:.3f}")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default = os.path.join(
        os.environ.get("CARGO_TARGET_DIR", os.path.join(here, "..", "..", "..", "target")),
        "tmp",
        "fit-bench-data.csv",
    )
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("csv", nargs="?", default=default)
    ap.add_argument("--method", default="lm", choices=["trf", "lm", "dogbox"])
    ap.add_argument("--x-scale", default="jac", help="'jac' or 1.0 (least_squares' x_scale)")
    ap.add_argument("--mode", default="both", choices=["both", "no-start", "truth", "generic"])
    ap.add_argument("--no-pieces", action="store_true", help="skip the fun / fun + jac timings")
    ap.add_argument("--chi2-of", metavar="FIT.TOML", help="also print chi2 per channel of a Gonio model file")
    args = ap.parse_args()
    names, a, b, ys, sigmas = load(args.csv)
    print(
        f"scipy {scipy.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}; "
        f"{a.size} pairs, {len(names)} channels, method '{args.method}', analytic Jacobian, "
        f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}"
    )
    xs = args.x_scale if args.x_scale == "jac" else float(args.x_scale)
    # Trial steps can overflow x ** n (n of a sharp lobe times a large ln x): the
    # residuals are then infinite and least_squares rejects the step, as it should.
    np.seterr(over="ignore", invalid="ignore", divide="ignore")
    if args.mode in ("both", "no-start"):
        no_start(names, a, b, ys, sigmas, args.method, xs)
    if args.mode in ("both", "truth"):
        from_truth(names, a, b, ys, sigmas, args.method, xs)
    if args.mode == "generic":
        generic(names, a, b, ys, sigmas, args.method, xs)
    if args.chi2_of:
        chi2_of(args.chi2_of, names, a, b, ys, sigmas)
    if args.no_pieces:
        return
    # The pieces, as in the Rust bench: one residual evaluation and one evaluation of
    # residuals + Jacobian (the shared powers recomputed), channel 0 at its optimum.
    prob = Problem(a, b, ys[0], sigmas[0])
    x = least_squares(prob.fun, truth(0), jac=prob.jac, method="lm").x
    for label, call in [("fun", lambda: prob.fun(x)), ("fun + jac", lambda: (prob.fun(x), prob.jac(x)))]:
        times = []
        for _ in range(21):
            prob.p = None
            t0 = time.perf_counter()
            call()
            times.append(time.perf_counter() - t0)
        print(f"one channel, {label}: {1e3 * float(np.median(times)):.2f} ms (median of 21)")


if __name__ == "__main__":
    main()
