"""The pandas + numpy peer of `gonio check TABLE.csv --k 1,5,10` on a table another
tool wrote: columns in any order, units in the names, no sidecar.

    python peer_other.py TABLE.csv [GONIO_CHECK.json]

Reads the table with pandas.read_csv(path) (no arguments), finds the angle and value
columns by name (units stripped), recognises the grid from the values (the distinct
angles of each axis), orders the rows into DeYoung's A (rows (phi_i, theta_i),
columns (phi_o, theta_o)) with numpy.lexsort, takes numpy.linalg.svd(A,
compute_uv=False) and prints P_s^(k) for k = 1, 5, 10 with the times of each step.
With Gonio's `check --json` output, asserts that the two agree to 1e-9.
"""
import json
import re
import sys
import time

t0 = time.perf_counter()
import numpy as np
import pandas as pd

path = sys.argv[1]
t1 = time.perf_counter()
df = pd.read_csv(path)
t2 = time.perf_counter()


def stem(c):
    c = re.sub(r"\s*[\[(].*[\])]\s*$", "", c.strip())
    return re.sub(r"_(deg|per_sr)$", "", c)


by = {stem(c): c for c in df.columns}
ti, pi, to, po = (df[by[n]].to_numpy() for n in ("theta_i", "phi_i", "theta_o", "phi_o"))
value = [c for s, c in by.items() if s.startswith("f_r")][0]
order = np.lexsort((to, po, ti, pi))
n_pi, n_ti, n_po, n_to = (len(np.unique(x)) for x in (pi, ti, po, to))
p, q = n_pi * n_ti, n_po * n_to
assert p * q == len(df), (p, q, len(df))
a = df[value].to_numpy()[order].reshape(p, q)
t3 = time.perf_counter()
s = np.linalg.svd(a, compute_uv=False)
t4 = time.perf_counter()
n = p * q
p_s = {k: float(np.sqrt((s[k:] ** 2).sum() / n)) for k in (1, 5, 10)}
print(f"peer: import {t1 - t0:.3f} s, read_csv {t2 - t1:.3f} s, grid+order {t3 - t2:.3f} s, "
      f"svd {t4 - t3:.3f} s ({p}x{q})")
print("peer: P_s " + ", ".join(f"({k}) {v:.9e}" for k, v in p_s.items()))
if len(sys.argv) > 2:
    with open(sys.argv[2]) as f:
        report = json.load(f)
    ours = dict((int(k), v) for k, v in report["separability"][0]["p_s"])
    for k, v in p_s.items():
        assert abs(ours[k] - v) <= 1e-9 * max(abs(v), 1e-300), (k, ours[k], v)
    print("peer: agrees with gonio check to 1e-9")
