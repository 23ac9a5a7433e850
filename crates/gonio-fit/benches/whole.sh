#!/bin/sh
# Whole-process `gonio fit` against a scipy fit, as a user would time them: each run is
# a fresh process (start-up, reading the CSV, the fit, the report), timed by
# /usr/bin/time, the two alternating so that both see the same machine.
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
i=0
: >"$dir/gonio.t"
: >"$dir/scipy.t"
: >"$dir/before.t"
while [ "$i" -lt "$rounds" ]; do
    if [ -n "${GONIO_BEFORE:-}" ]; then
        /usr/bin/time -f %e -a -o "$dir/before.t" "$GONIO_BEFORE" fit "$csv" --out "$dir/before.toml" --force >"$dir/before.txt"
    fi
    /usr/bin/time -f %e -a -o "$dir/gonio.t" "$gonio" fit "$csv" --out "$dir/fit.toml" --force >"$dir/gonio.txt"
    /usr/bin/time -f %e -a -o "$dir/scipy.t" "$python" "$here/scipy_fit.py" "$csv" --mode generic --no-pieces >"$dir/scipy.txt"
    i=$((i + 1))
done
echo "load after: $(uptime | sed 's/.*load average: //')"
"$python" - "$dir/gonio.t" "$dir/scipy.t" "$dir/before.t" <<'PY'
import statistics, sys
g = [float(x) for x in open(sys.argv[1])]
s = [float(x) for x in open(sys.argv[2])]
b = [float(x) for x in open(sys.argv[3])]
if b:
    print("gonio fit BEFORE, whole process, s:", " ".join(f"{x:.3f}" for x in b), f"median {statistics.median(b):.3f}",
          f"(scipy / before: {statistics.median(s) / statistics.median(b):.1f}x)")
print("gonio fit, whole process, s:", " ".join(f"{x:.3f}" for x in g), f"median {statistics.median(g):.3f}")
print("scipy 'lm', whole process, s:", " ".join(f"{x:.3f}" for x in s), f"median {statistics.median(s):.3f}")
print(f"scipy / gonio: {statistics.median(s) / statistics.median(g):.1f}x (medians); per round:",
      " ".join(f"{b / a:.1f}" for a, b in zip(g, s)))
PY
grep -E "^[0-9]+ evaluations" "$dir/gonio.txt"
grep -E "^  [RGB]:|total" "$dir/scipy.txt"
"$python" "$here/scipy_fit.py" "$csv" --mode truth --no-pieces --chi2-of "$dir/fit.toml" | grep "chi2 of"
