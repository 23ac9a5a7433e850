"""The pandas + numpy peer of `gonio check TABLE.csv --k 1,5,10` (P_s^(k), DeYoung
Eq. 4.16-4.20), and a check that Gonio's CSV loads with pandas.read_csv(path) and no
arguments.

    python peer_ps.py TABLE.csv [GONIO_CHECK.json]

Reads the table with pandas.read_csv(path) (no arguments), checks the column names
and the sidecar TABLE.csv.json, reshapes the values into DeYoung's A (rows (phi_i,
theta_i), columns (phi_o, theta_o): Gonio writes the rows in that order), takes
numpy.linalg.svd(A, compute_uv=False) and prints P_s^(k) for k = 1, 5, 10 with the
times of each step. With Gonio's `check --json` output, asserts that the two agree.
"""
import json
import sys
import time

t0 = time.perf_counter()
import numpy as np
import pandas as pd

path = sys.argv[1]
t1 = time.perf_counter()
df = pd.read_csv(path)
t2 = time.perf_counter()
cols = list(df.columns)
assert cols[:4] == ["theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"], cols
assert all(np.issubdtype(df[c].dtype, np.number) for c in cols), df.dtypes
with open(path + ".json") as f:
    meta = json.load(f)
assert meta["columns"] == cols, (meta["columns"], cols)
g = meta["grid"]
p = g["phi_i"]["n"] * g["theta_i"]["n"]
q = g["phi_o"]["n"] * g["theta_o"]["n"]
assert len(df) == p * q, (len(df), p, q)
# Gonio writes the nodes in grid order: the first row's angles are the first nodes.
assert df["theta_i_deg"].iloc[0] == g["theta_i"]["start_deg"]
assert df["theta_o_deg"].iloc[1] == g["theta_o"]["start_deg"] + g["theta_o"]["step_deg"]
value_cols = [c for c in cols if c.startswith("f_r_")]
a = df[value_cols[0]].to_numpy().reshape(p, q)
t3 = time.perf_counter()
s = np.linalg.svd(a, compute_uv=False)
t4 = time.perf_counter()
n = p * q
p_s = {k: float(np.sqrt((s[k:] ** 2).sum() / n)) for k in (1, 5, 10)}
print(f"peer: import {t1 - t0:.3f} s, read_csv {t2 - t1:.3f} s, reshape {t3 - t2:.3f} s, "
      f"svd {t4 - t3:.3f} s ({p}x{q})")
print("peer: P_s " + ", ".join(f"({k}) {v:.9e}" for k, v in p_s.items()))
if len(sys.argv) > 2:
    with open(sys.argv[2]) as f:
        report = json.load(f)
    got = dict(report["separability"][0]["p_s"])
    for k, v in p_s.items():
        g = got[str(k)] if str(k) in got else got[k]
        assert abs(g - v) <= 1e-9 * v, (k, g, v)
    print("peer: Gonio's P_s agrees to 1e-9")
