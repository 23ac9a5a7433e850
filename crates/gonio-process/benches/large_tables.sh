#!/bin/sh
# `gonio check TABLE.csv --k 1,5,10` on a 5° x 2.5° table (A is 2592 x 2592, 6.7 M
# values) against its pandas + numpy peer, both timed as whole processes by
# /usr/bin/time -v in the same run (wall time and peak RSS), three times each: the
# table as another tool would write it (columns shuffled, units in the names, no
# sidecar; peer benches/peer_other.py: read_csv, the grid from the values, lexsort,
# numpy.linalg.svd(A, compute_uv=False)) and Gonio's own with its sidecar (peer
# benches/peer_ps.py). The peers check that both give the same P_s^(k). Then 1 and 2
# rayon threads (RAYON_NUM_THREADS): the same output bytes, the speed-up, and the
# serial fraction it implies (Amdahl).
#
#   crates/gonio-process/benches/large_tables.sh [BEFORE_BINARY]
#
# BEFORE_BINARY (optional): an older `gonio` to time on the same table, with and
# without its sidecar, for a before/after figure. PYTHON names an interpreter with numpy
# and pandas (default /tmp/scipyenv/bin/python); the project does not depend on
# Python. To make one: python3 -m venv /tmp/scipyenv && /tmp/scipyenv/bin/pip install
# numpy scipy pandas
set -eu

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
target=${CARGO_TARGET_DIR:-$root/target}
python=${PYTHON:-/tmp/scipyenv/bin/python}
tmp=$target/tmp/large-tables
before=${1:-}

if ! "$python" -c 'import numpy, pandas' 2>/dev/null; then
    echo "large_tables.sh: $python has no numpy/pandas; see the header of this script" >&2
    exit 2
fi
cd "$root"
cargo build --release -p gonio-cli >&2
gonio=$target/release/gonio
mkdir -p "$tmp"
table=$tmp/phong-5x2.5.csv
if [ ! -f "$table" ] || [ ! -f "$table.json" ]; then
    rm -f "$table" "$table.json"
    "$gonio" correct config/models/phong-shading.toml --grid 5,2.5 --reciprocity 0 \
        --out "$table" >/dev/null
fi
echo "table: $table ($(wc -c <"$table") bytes), sidecar $table.json"

# One whole-process run: prints "WALL_S PEAK_MB".
timed() {
    /usr/bin/time -v "$@" >"$tmp/out" 2>"$tmp/time" || { cat "$tmp/time" >&2; exit 1; }
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$tmp/time" |
        awk -F: '{ if (NF == 3) print $1 * 3600 + $2 * 60 + $3; else print $1 * 60 + $2 }')
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$tmp/time")
    echo "$wall $((rss / 1024))"
}

# The same table as another tool might write it: the columns shuffled, units in
# brackets or none, no sidecar, no `# grid:` line (gonio reads the grid from the values).
other=$tmp/other-5x2.5.csv
[ -f "$other" ] || awk -F, 'NR == 1 { print "f_r [1/sr],phi_o (deg),theta_i [deg],theta_o,phi_i_deg"; next }
    { print $5 "," $4 "," $1 "," $3 "," $2 }' "$table" >"$other"
nosidecar=$tmp/nosidecar.csv
[ -f "$nosidecar" ] || cp "$table" "$nosidecar"

load_before=$(uptime | sed 's/.*load average: //')
for i in 1 2 3; do
    echo "gonio check --k 1,5,10, another tool's table (run $i): $(timed "$gonio" check "$other" --k 1,5,10 --json) s MB"
    cp "$tmp/out" "$tmp/gonio-other.json"
    echo "pandas + numpy peer, another tool's table (run $i): $(timed "$python" "$here/peer_other.py" "$other" "$tmp/gonio-other.json") s MB"
    sed 's/^/  /' "$tmp/out"
    echo "gonio check --k 1,5,10, with its sidecar (run $i): $(timed "$gonio" check "$table" --k 1,5,10 --json) s MB"
    cp "$tmp/out" "$tmp/gonio.json"
    echo "pandas + numpy peer, with the sidecar (run $i): $(timed "$python" "$here/peer_ps.py" "$table" "$tmp/gonio.json") s MB"
    sed 's/^/  /' "$tmp/out"
done
# 1 and 2 threads: the same bytes, and the speed-up; the serial fraction f from
# Amdahl's law (S2 = 1 / (f + (1 - f) / 2)) predicts S16 = 1 / (f + (1 - f) / 16).
for input in "$other" "$table"; do
    for t in 1 2 1 2; do
        r=$(RAYON_NUM_THREADS=$t timed "$gonio" check "$input" --k 1,5,10 --json)
        cp "$tmp/out" "$tmp/threads-$t.json"
        echo "RAYON_NUM_THREADS=$t gonio check $(basename "$input"): $r s MB"
        eval "wall$t=\${r%% *}"
    done
    cmp -s "$tmp/threads-1.json" "$tmp/threads-2.json" && same=identical || same=DIFFERENT
    awk -v a="$wall1" -v b="$wall2" -v s="$same" 'BEGIN { s2 = a / b; f = 2 / s2 - 1;
        printf "  1 -> 2 threads: %.2fx (last runs), output %s; serial fraction %.2f, Amdahl at 16 threads %.2fx\n",
        s2, s, f, 1 / (f + (1 - f) / 16) }'
done
if [ -n "$before" ]; then
    for i in 1 2; do
        echo "before: $before check, with the sidecar (run $i): $(timed "$before" check "$table" --k 1,5,10) s MB"
        echo "before: $before check, no sidecar (run $i): $(timed "$before" check "$nosidecar" --k 1,5,10) s MB"
    done
    echo "after: this gonio, no sidecar: $(timed "$gonio" check "$nosidecar" --k 1,5,10) s MB"
fi
for i in 1 2; do
    echo "pandas + numpy peer, OPENBLAS_NUM_THREADS=1 (run $i): $(OPENBLAS_NUM_THREADS=1 timed "$python" "$here/peer_other.py" "$other" "$tmp/gonio-other.json") s MB"
done
echo "load average before: $load_before; after: $(uptime | sed 's/.*load average: //') (nproc $(nproc))"
