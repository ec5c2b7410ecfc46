#!/usr/bin/env bash
# auto-check.sh: how close `--accel auto` comes to the fastest structure (docs/auto.md).
#
#   bash scripts/auto-check.sh [--bin PATH] [--size WxH] [--no-calibrate]
#
# Calibrates the device first (`arbor calibrate`, into a scratch ARBOR_CACHE_DIR,
# unless --no-calibrate: then the built-in costs), then, for each case (a blob of N
# triangles at S samples per pixel, Whitted, --size, default 128x128), renders with
# every structure and with `--accel auto`, and prints a table: each case's fastest
# structure and its build + trace ms, auto's pick and its build + trace ms, and their
# ratio. Build + trace is `build_ms + trace_ms` of `--stats` (GPU time of the trace).
# A benchmark, not a test: figures move with the machine's load.
set -euo pipefail
PROG=auto-check.sh
BIN=${ARBOR_BIN:-}
SIZE=128x128
CALIBRATE=1
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --size) SIZE=$2; shift 2 ;;
    --no-calibrate) CALIBRATE=0; shift ;;
    -h|--help) sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "$PROG: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN=${BIN:-$ROOT/target/release/arbor}
[ -x "$BIN" ] || { echo "$PROG: no arbor binary at $BIN (build it, or --bin PATH)" >&2; exit 1; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
export ARBOR_CACHE_DIR=$WORK/cache
if [ "$CALIBRATE" = 1 ]; then
  "$BIN" calibrate >"$WORK/calibration.txt"
  cat "$WORK/calibration.txt" >&2
fi
# Brute force is left out: over 100k triangles it takes minutes a case, and auto
# never picks it there.
KINDS=(kdtree bvh-sah lbvh trbvh bvh4 bvh8 cwbvh grid octree)
CASES=("100000 1" "100000 16" "100000 256" "1000000 1" "1000000 64" "4000000 1")
: >"$WORK/rows.tsv"
for c in "${CASES[@]}"; do
  read -r n spp <<<"$c"
  for k in "${KINDS[@]}" auto; do
    stats=$WORK/s.json
    if ! "$BIN" render "builtin:blob:$n" --integrator whitted --size "$SIZE" --spp "$spp" --accel "$k" \
        -o "$WORK/x.png" --stats "$stats" -q 2>"$WORK/err.txt"; then
      echo "$PROG: blob:$n $spp spp $k failed: $(tail -1 "$WORK/err.txt")" >&2
      continue
    fi
    python3 - "$stats" "$n" "$spp" "$k" >>"$WORK/rows.tsv" <<'EOF'
import json, sys
d = json.load(open(sys.argv[1]))
trace = d.get("trace_ms") or d["loop_ms"]
print("\t".join([sys.argv[2], sys.argv[3], sys.argv[4], d["accel"], f'{d["build_ms"] + trace:.1f}']))
EOF
    echo "$PROG: blob:$n $spp spp $k done" >&2
  done
done
python3 - "$WORK/rows.tsv" <<'EOF'
import sys
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1]) if l.strip()]
cases = []
for n, spp, k, picked, ms in rows:
    if (n, spp) not in cases:
        cases.append((n, spp))
print(f"{'case':<22} {'fastest':<10} {'ms':>9} {'auto picks':<10} {'ms':>9} {'auto/fastest':>12}")
for n, spp in cases:
    mine = [r for r in rows if (r[0], r[1]) == (n, spp)]
    kinds = [r for r in mine if r[2] != "auto"]
    auto = [r for r in mine if r[2] == "auto"]
    best = min(kinds, key=lambda r: float(r[4]))
    a = auto[0] if auto else None
    ratio = f"{float(a[4]) / float(best[4]):.2f}" if a else "-"
    print(f"{'blob:' + n + ' ' + spp + ' spp':<22} {best[2]:<10} {float(best[4]):>9.1f} {(a[3] if a else '-'):<10} {(float(a[4]) if a else 0):>9.1f} {ratio:>12}")
EOF
