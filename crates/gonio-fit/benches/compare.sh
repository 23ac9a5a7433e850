#!/bin/sh
# Gonio's lobe fit against scipy.optimize.least_squares on the same data, in one run:
# the criterion bench (which checks the fit, prints its chi2 per channel, then writes
# the data to target/tmp/fit-bench-data.csv), then benches/scipy_fit.py on that file
# in both of its modes — no start (Gonio's greedy multi-start search, the same
# problem) and from the true parameters +-10% (a head start) — then the three times,
# both ratios, each side's chi2 and the load average before and after.
#
#   crates/gonio-fit/benches/compare.sh [criterion filter, e.g. '^lobe_fit/fit_lobes$']
#
# PYTHON names an interpreter with numpy and scipy (default /tmp/scipyenv/bin/python);
# the project does not depend on Python. To make one:
#   python3 -m venv /tmp/scipyenv && /tmp/scipyenv/bin/pip install numpy scipy
set -eu

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
target=${CARGO_TARGET_DIR:-$root/target}
python=${PYTHON:-/tmp/scipyenv/bin/python}
csv=$target/tmp/fit-bench-data.csv
benchlog=$target/tmp/fit-bench.log
scipylog=$target/tmp/scipy-fit.log

if ! "$python" -c 'import numpy, scipy' 2>/dev/null; then
    echo "compare.sh: $python has no numpy/scipy; see the header of this script" >&2
    exit 2
fi

cd "$root"
mkdir -p "$target/tmp"
load_before=$(uptime | sed 's/.*load average: //')
# The bench's output is kept for its chi2 lines (no pipefail in sh: the status is
# carried through a file).
{ cargo bench -p gonio-fit --bench fit -- "$@" 2>&1; echo $? >"$benchlog.rc"; } | tee "$benchlog"
rc=$(cat "$benchlog.rc")
rm -f "$benchlog.rc"
if [ "$rc" != 0 ]; then
    echo "compare.sh: cargo bench failed ($rc)" >&2
    exit "$rc"
fi

estimates=$target/criterion/lobe_fit/fit_lobes/new/estimates.json
if [ ! -f "$estimates" ]; then
    echo "compare.sh: no criterion result at $estimates (filtered out?)" >&2
    exit 1
fi
gonio=$("$python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["median"]["point_estimate"] / 1e9)' "$estimates")

echo
"$python" "$here/scipy_fit.py" "$csv" | tee "$scipylog"
nostart=$(sed -n 's/^scipy total (no start): \([0-9.]*\) s.*$/\1/p' "$scipylog")
truth=$(sed -n 's/^scipy total (from the truth +-10%): \([0-9.]*\) s.*$/\1/p' "$scipylog")
load_after=$(uptime | sed 's/.*load average: //')

echo
echo "chi2 per channel:"
sed -n 's/^  \([A-Za-z]*\): chi2 \([0-9.]*\) (true model: \([0-9.]*\)).*$/  Gonio            \1: \2 (true model: \3)/p' "$benchlog"
awk '/^no start:/ { m = "scipy no start" } /^from the truth/ { m = "scipy truth+-10%" }
     /^  [A-Za-z]+: .*chi2 / { sub(/^  /, ""); ch = $1; sub(/^.*, chi2 /, ""); sub(/[;)].*$/, ")");
                               printf "  %-16s %s %s\n", m, ch, $0 }' "$scipylog"
echo
printf 'Gonio fit_lobes (criterion median, no start given):   %.3f s\n' "$gonio"
printf 'scipy, no start (the same greedy multi-start search): %.3f s\n' "$nostart"
printf 'scipy, from the truth +-10%% (a head start):           %.3f s\n' "$truth"
"$python" -c '
import sys
g, n, t = map(float, sys.argv[1:])
for label, s in [("no start, the same problem", n), ("from the truth +-10%", t)]:
    print(f"scipy / Gonio, {label}: {s / g:.2f}x" + (" (Gonio faster)" if s > g else " (Gonio slower)"))
' "$gonio" "$nostart" "$truth"
echo "load average before: $load_before; after: $load_after (nproc $(nproc 2>/dev/null || echo ?))"
