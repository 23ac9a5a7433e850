#!/usr/bin/env python3
"""Writes the whole-process benchmark's input: the lobe-fit bench's RGB model (3 lobes +
Lambert, `MODEL` in benches/fit.rs) on the bench's grid (theta_i 0..80 by 5, phi_i 0,
theta_o 1..89 by 2, phi_o by 2.8125: 97 920 pairs), each value with Gaussian noise of 1%
of itself (numpy's default_rng, seed 1) and that sigma given, as a sample CSV that
`gonio fit` reads (docs/processing.md) and `scipy_fit.py` loads.

Usage: fit_data.py OUT.CSV
"""

import sys

import numpy as np

RHO = [0.3094, 0.39667, 0.70837]
LOBES = [
    ([0.870567, 0.857255, 0.670982], [0.803624, 0.774290, 0.586674], [21.820103, 18.597755, 7.472717]),
    ([-0.451218, -0.406681, -0.41], [0.023907, 0.017601, 0.018], [2.774989, 2.581280, 2.58]),
    ([-1.031545, -1.029225, -1.03], [0.706734, 0.696065, 0.70], [66.899274, 63.767356, 63.8]),
]


def main():
    out = sys.argv[1]
    ti, to, po = np.meshgrid(np.arange(0, 81, 5.0), np.arange(1, 90, 2.0), 2.8125 * np.arange(128), indexing="ij")
    ti, to, po = ti.ravel(), to.ravel(), po.ravel()
    t, o, p = np.radians(ti), np.radians(to), np.radians(po)
    a = np.sin(t) * np.sin(o) * np.cos(p)  # ux vx + uy vy with phi_i = 0
    b = np.cos(t) * np.cos(o)
    rng = np.random.default_rng(1)
    cols, sig = [], []
    for ch in range(3):
        f = np.full(a.size, RHO[ch] / np.pi)
        for cx, cz, n in LOBES:
            x = cx[ch] * a + cz[ch] * b
            f += np.where(x > 0, np.abs(x) ** n[ch], 0.0)
        s = 0.01 * f
        cols.append(f + s * rng.standard_normal(a.size))
        sig.append(s)
    with open(out, "w") as fh:
        fh.write("theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R,sigma_G,sigma_B\n")
        for i in range(a.size):
            vals = [ti[i], 0.0, to[i], po[i]] + [c[i] for c in cols] + [s[i] for s in sig]
            fh.write(",".join(repr(float(v)) for v in vals) + "\n")


if __name__ == "__main__":
    main()
