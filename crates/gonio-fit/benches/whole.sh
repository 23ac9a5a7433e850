#!/bin/sh
# Whole-process `gonio fit` against a scipy fit, as a user would time them: each run is
# a fresh process (start-up, reading the CSV, the fit, the report), timed from its
# parent, the two alternating so that both see the same machine.
#
#   crates/gonio-fit/benches/whole.sh [ROUNDS]        (default 7)
#
# The input is benches/fit_data.py's CSV (97 920 RGB pairs with σ, 3 lobes + Lambert).
# Gonio: `gonio fit DATA.csv --out FIT.toml` (release build, its own start search,
# default objective: χ² as every sample has σ). scipy: `scipy_fit.py DATA.csv --mode
# generic --no-pieces` (least_squares, method 'lm', the analytic vectorised Jacobian,
# one channel at a time, from a generic start). PYTHON names an interpreter with
# numpy and scipy (default /tmp/scipyenv/bin/python). GONIO_BEFORE names another gonio
# binary (an earlier build) to time in the same rounds. Last, each side's χ² per
# channel (Gonio's from its model file, computed by scipy_fit.py).
set -eu

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
target=${CARGO_TARGET_DIR:-$root/target}
python=${PYTHON:-/tmp/scipyenv/bin/python}
rounds=${1:-7}
dir=$target/tmp/whole
mkdir -p "$dir"
csv=$dir/data.csv

cd "$root"
cargo build --release -p gonio-cli >&2
[ -f "$csv" ] || "$python" "$here/fit_data.py" "$csv"
gonio=$target/release/gonio
echo "load before: $(uptime | sed 's/.*load average: //')"
# Each process is timed by the parent's clock (time.perf_counter around the child's
# whole life, to the millisecond; /usr/bin/time rounds to 10 ms).
"$python" - "$rounds" "$gonio" "${GONIO_BEFORE:-}" "$python" "$here/scipy_fit.py" "$csv" "$dir" <<'PY'
import statistics, subprocess, sys, time
rounds, gonio, before, python, script, csv, d = sys.argv[1:]
runs = {"before": [], "gonio": [], "scipy": []}
cmds = {
    "before": [before, "fit", csv, "--out", f"{d}/before.toml", "--force"],
    "gonio": [gonio, "fit", csv, "--out", f"{d}/fit.toml", "--force"],
    "scipy": [python, script, csv, "--mode", "generic", "--no-pieces"],
}
for _ in range(int(rounds)):
    for name in ("before", "gonio", "scipy"):
        if name == "before" and not before:
            continue
        with open(f"{d}/{name}.txt", "w") as out:
            t0 = time.perf_counter()
            subprocess.run(cmds[name], stdout=out, check=True)
            runs[name].append(time.perf_counter() - t0)
med = {k: statistics.median(v) for k, v in runs.items() if v}
for k, label in [("before", "gonio fit BEFORE"), ("gonio", "gonio fit"), ("scipy", "scipy 'lm'")]:
    if runs[k]:
        print(f"{label}, whole process, s:", " ".join(f"{x:.3f}" for x in runs[k]), f"median {med[k]:.3f}")
if runs["before"]:
    print(f"scipy / before: {med['scipy'] / med['before']:.1f}x (medians)")
print(f"scipy / gonio: {med['scipy'] / med['gonio']:.1f}x (medians); per round:",
      " ".join(f"{b / a:.1f}" for a, b in zip(runs["gonio"], runs["scipy"])))
PY
echo "load after: $(uptime | sed 's/.*load average: //')"
grep -E "^[0-9]+ evaluations" "$dir/gonio.txt"
grep -E "^  [RGB]:|total" "$dir/scipy.txt"
"$python" "$here/scipy_fit.py" "$csv" --mode truth --no-pieces --chi2-of "$dir/fit.toml" | grep "chi2 of"
