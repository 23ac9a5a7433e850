#!/bin/sh
# `gonio check TABLE.csv --k 1,5,10` on a 5° x 2.5° table (A is 2592 x 2592, 6.7 M
# values) against its pandas + numpy peer (benches/peer_ps.py: read_csv with no
# arguments, numpy.linalg.svd(A, compute_uv=False)), both timed as whole processes by
# /usr/bin/time -v in the same run (wall time and peak RSS), three times each. The
# peer also checks that the CSV loads with no arguments and that both give the same
# P_s^(k).
#
#   crates/gonio-process/benches/large_tables.sh [BEFORE_BINARY]
#
# BEFORE_BINARY (optional): an older `gonio` to time on the same table in format 1
# (written by it), for a before/after figure. PYTHON names an interpreter with numpy
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

load_before=$(uptime | sed 's/.*load average: //')
for i in 1 2 3; do
    echo "gonio check --k 1,5,10 (run $i): $(timed "$gonio" check "$table" --k 1,5,10 --json) s MB"
    cp "$tmp/out" "$tmp/gonio.json"
    echo "pandas + numpy peer   (run $i): $(timed "$python" "$here/peer_ps.py" "$table" "$tmp/gonio.json") s MB"
    sed 's/^/  /' "$tmp/out"
done
if [ -n "$before" ]; then
    old=$tmp/phong-5x2.5-format1.csv
    [ -f "$old" ] || "$before" correct config/models/phong-shading.toml --grid 5,2.5 \
        --reciprocity 0 --out "$old" >/dev/null
    for i in 1 2; do
        echo "before: $before check (format 1) (run $i): $(timed "$before" check "$old" --k 1,5,10) s MB"
    done
    echo "after: this gonio on the same format-1 file: $(timed "$gonio" check "$old" --k 1,5,10) s MB"
    echo "after: this gonio, format 2 without the sidecar: $(
        cp "$table" "$tmp/nosidecar.csv"; timed "$gonio" check "$tmp/nosidecar.csv" --k 1,5,10) s MB"
fi
for i in 1 2; do
    echo "pandas + numpy peer, OPENBLAS_NUM_THREADS=1 (run $i): $(OPENBLAS_NUM_THREADS=1 timed "$python" "$here/peer_ps.py" "$table" "$tmp/gonio.json") s MB"
done
echo "load average before: $load_before; after: $(uptime | sed 's/.*load average: //') (nproc $(nproc))"
