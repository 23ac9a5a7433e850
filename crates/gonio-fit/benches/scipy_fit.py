#!/usr/bin/env python3
"""The scipy reference for the lobe-fit benchmark (`benches/fit.rs`).

The same problem as the Rust bench: per channel, three isotropic generalized cosine
lobes plus a Lambertian term (Lafortune et al. 1997, Eq. 8),

    f(u, v) = rho_d / pi + sum_j max(0, C_j (ux vx + uy vy) + Cz_j uz vz) ** n_j,

fitted to the bench's 97 920 noisy samples by minimising sum(((f - y) / sigma) ** 2)
with scipy.optimize.least_squares: vectorised numpy, the analytic Jacobian, the
lobe powers computed once per parameter vector and shared by `fun` and `jac`, the
three channels one after another. All ten parameters a channel (rho_d, then C, Cz, n
per lobe) are searched; nothing is projected out.

Head start: scipy starts from the true parameters perturbed by 10% (each multiplied
by 1.1 or 0.9 in turn); Gonio's `fit_lobes` is given no start at all and searches for
one. The timing covers the three `least_squares` calls only (not reading the CSV).

Usage: scipy_fit.py DATA.CSV [--method trf|lm|dogbox]   (default: the CSV the Rust
bench writes, target/tmp/fit-bench-data.csv, and method 'lm', MINPACK's
Levenberg-Marquardt, the fastest of the three here). Needs numpy and scipy,
which the project does not depend on:

    python3 -m venv /tmp/scipyenv && /tmp/scipyenv/bin/pip install numpy scipy
    /tmp/scipyenv/bin/python crates/gonio-fit/benches/scipy_fit.py
"""

import argparse
import os
import sys
import time

import numpy as np
import scipy
from scipy.optimize import least_squares

# The bench's model (`MODEL` in benches/fit.rs): rho_d per channel, and per lobe
# (Cx = Cy, Cz, n) per channel.
RHO = [0.3094, 0.39667, 0.70837]
LOBES = [
    ([0.870567, 0.857255, 0.670982], [0.803624, 0.774290, 0.586674], [21.820103, 18.597755, 7.472717]),
    ([-0.451218, -0.406681, -0.41], [0.023907, 0.017601, 0.018], [2.774989, 2.581280, 2.58]),
    ([-1.031545, -1.029225, -1.03], [0.706734, 0.696065, 0.70], [66.899274, 63.767356, 63.8]),
]
NLOBES = len(LOBES)


def truth(ch):
    """The true parameter vector of channel ch: rho_d, then (C, Cz, n) per lobe."""
    p = [RHO[ch]]
    for cx, cz, n in LOBES:
        p += [cx[ch], cz[ch], n[ch]]
    return np.array(p)


class Problem:
    """One channel: residuals (f - y) / sigma and their analytic Jacobian."""

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
        for j in range(NLOBES):
            c, cz, n = p[1 + 3 * j : 4 + 3 * j]
            x = c * self.a + cz * self.b
            pos = x > 0.0
            lnx = np.log(np.where(pos, x, 1.0))
            h = np.where(pos, np.exp(n * lnx), 0.0)
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
        jm = np.empty((m, 1 + 3 * NLOBES))
        jm[:, 0] = self.w / np.pi
        for j in range(NLOBES):
            hxw = self.hx[j] * self.w
            jm[:, 1 + 3 * j] = hxw * self.a
            jm[:, 2 + 3 * j] = hxw * self.b
            jm[:, 3 + 3 * j] = self.hn[j] * self.w
        return jm


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
    args = ap.parse_args()
    names, a, b, ys, sigmas = load(args.csv)
    print(
        f"scipy {scipy.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}; "
        f"{a.size} pairs, {len(names)} channels, method '{args.method}', analytic Jacobian"
    )
    xs = args.x_scale if args.x_scale == "jac" else float(args.x_scale)
    # Trial steps can overflow x ** n (n of a sharp lobe times a large ln x): the
    # residuals are then infinite and least_squares rejects the step, as it should.
    np.seterr(over="ignore", invalid="ignore")
    total = 0.0
    for ch, name in enumerate(names):
        t = truth(ch)
        start = t * np.where(np.arange(t.size) % 2 == 0, 1.1, 0.9)
        prob = Problem(a, b, ys[ch], sigmas[ch])
        t0 = time.perf_counter()
        res = least_squares(prob.fun, start, jac=prob.jac, method=args.method, x_scale=xs)
        dt = time.perf_counter() - t0
        total += dt
        chi2 = float(np.sum(res.fun**2))
        chi2_true = float(np.sum(prob.fun(t) ** 2))
        print(
            f"  {name}: {dt:.3f} s, chi2 {chi2:.3f} (true model: {chi2_true:.3f}; "
            f"least_squares cost = chi2/2 = {res.cost:.3f}), nfev {res.nfev}, "
            f"njev {res.njev}, status {res.status}"
        )
        print("     fitted (rho_d, then C, Cz, n a lobe):", np.array2string(res.x, precision=6, max_line_width=200))
    print(f"scipy total: {total:.3f} s")
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
