#!/bin/sh
# Gonio's lobe fit against scipy.optimize.least_squares on the same data, in one run:
# the criterion bench (which checks the fit, then writes the data to
# target/tmp/fit-bench-data.csv), then benches/scipy_fit.py on that file, then both
# times and their ratio.
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

if ! "$python" -c 'import numpy, scipy' 2>/dev/null; then
    echo "compare.sh: $python has no numpy/scipy; see the header of this script" >&2
    exit 2
fi

cd "$root"
cargo bench -p gonio-fit --bench fit -- "$@"

estimates=$target/criterion/lobe_fit/fit_lobes/new/estimates.json
if [ ! -f "$estimates" ]; then
    echo "compare.sh: no criterion result at $estimates (filtered out?)" >&2
    exit 1
fi
gonio=$("$python" -c 'import json, sys; print(json.load(open(sys.argv[1]))["median"]["point_estimate"] / 1e9)' "$estimates")

echo
"$python" "$here/scipy_fit.py" "$csv" | tee "$target/tmp/scipy-fit.log"
scipy=$(sed -n 's/^scipy total: \([0-9.]*\) s$/\1/p' "$target/tmp/scipy-fit.log")

echo
printf 'Gonio fit_lobes (criterion median, no start given): %.3f s\n' "$gonio"
printf 'scipy least_squares (from the truth +-10%%):         %.3f s\n' "$scipy"
"$python" -c 'import sys; g, s = map(float, sys.argv[1:]); print(f"scipy / Gonio: {s / g:.2f}x" + (" (Gonio faster)" if s > g else " (Gonio slower)"))' "$gonio" "$scipy"
