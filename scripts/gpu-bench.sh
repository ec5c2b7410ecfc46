#!/usr/bin/env bash
# gpu-bench.sh: arbor's structures on one GPU in one command (docs/bench.md, "One
# command on a GPU").
#
# Usage: scripts/gpu-bench.sh [--quick] [--bin PATH] [--out DIR] [--force]
#                             [--device INDEX|NAME] [--mesh FILE]
#
# Builds arbor (cargo build --release) unless --bin PATH or the environment variable
# ARBOR_BIN names the binary to use, prints `arbor devices`, then runs a fixed grid of
# `arbor bench` steps, printing each step with the time elapsed so far:
#
#   full (default; about 8 minutes at most on a data-centre GPU, 3 timed rounds):
#     1. every structure, camera/diffuse/path rays, 1024x1024: blobs of 100k and 1M
#        triangles and a scanned mesh
#     2. every structure, camera/diffuse/path rays, 4096x4096: the 100k blob
#     3. lbvh and trbvh built on the CPU and on the GPU (--build cpu,gpu), camera rays,
#        1024x1024: the 100k and 1M blobs and the mesh
#   --quick (under a minute on lavapipe; what CI runs, one round):
#     1. kdtree, bvh-sah, cwbvh, camera/diffuse/path rays, 128x128: a 1k blob
#     2. lbvh and trbvh built on the CPU and on the GPU, camera rays, 128x128: the mesh
#
# Every structure means every `--accel` kind this arbor knows. `rayquery` (the
# driver's own structure, through VK_KHR_ray_query) joins steps 1 and 2 only when the
# `arbor devices` line of the device used says `ray query yes` (and this arbor knows
# the kind); otherwise one line says it is left out and why.
#
# The mesh: --mesh FILE (any mesh arbor reads, e.g. the Stanford bunny as PLY). Debian
# 12's assimp-testmodels has no scanned triangle mesh (its one scan, PLY/pond.0.ply, is
# a point cloud without faces, and truncated), so the default is its PLY/Wuson.ply
# (3,732 triangles, modelled), and the run says so.
#
# Output, all in one folder (--out DIR, default gpu-bench-YYYYmmdd-HHMMSS; a folder
# that is not empty is refused unless --force, which replaces what this script wrote
# there before):
#   devices.txt           `arbor devices`
#   calibration.txt       `arbor calibrate`: `--accel auto`'s costs on this device (its
#                         cache file goes to ARBOR_CACHE_DIR, default DIR/cache); not
#                         with --quick
#   NN-STEP/              per step: bench.csv, bench.json, plots/ (as `bench --out`
#                         writes them) and table.txt (the printed table)
#   summary.md            Mrays/s per structure and ray kind; GPU build Mtris/s against
#                         the CPU's; rayquery against the best software structure
#
# Options:
#   --quick          the small grid above
#   --bin PATH       the arbor binary to run (default: $ARBOR_BIN, else build it)
#   --out DIR        the output folder
#   --force          write into a non-empty --out folder
#   --device D       the Vulkan device (index or name substring, as `arbor --device`;
#                    default: arbor's choice, a discrete GPU if there is one)
#   --mesh FILE      the scanned mesh to use
#   -h, --help       this text
#
# Exit status: 0 when every step ran, 1 when a step (or arbor) failed, 2 for a bad
# option. The environment reaches arbor (VK_DRIVER_FILES, ARBOR_VALIDATION, ...).
set -euo pipefail

PROG=gpu-bench
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
ASSIMP=/usr/share/assimp/models
# Used when the binary's list of structures cannot be read.
KNOWN_ACCEL=none,kdtree,bsp-course,bvh-sah,lbvh,trbvh,bvh4,bvh8,cwbvh,grid,octree

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d' | sed 's/^# \{0,1\}//'; }
bad_option() {
  echo "$PROG: error: $1 (see scripts/gpu-bench.sh --help)" >&2
  exit 2
}
fail() {
  echo "$PROG: error: $1" >&2
  exit 1
}
say() { echo "$PROG: $*" >&2; }

QUICK=0
FORCE=0
BIN=${ARBOR_BIN:-}
OUT=""
DEVICE=""
MESH=""
while [ $# -gt 0 ]; do
  opt=$1
  case "$opt" in
    --quick) QUICK=1 ;;
    --force) FORCE=1 ;;
    -h | --help)
      usage
      exit 0
      ;;
    --bin=* | --out=* | --device=* | --mesh=*)
      value=${opt#*=}
      opt=${opt%%=*}
      ;;
    --bin | --out | --device | --mesh)
      [ $# -ge 2 ] || bad_option "$opt needs a value"
      value=$2
      shift
      ;;
    *) bad_option "unknown option '$opt'" ;;
  esac
  case "$opt" in
    --bin | --out | --device | --mesh)
      [ -n "$value" ] || bad_option "$opt needs a value"
      case "$opt" in
        --bin) BIN=$value ;;
        --out) OUT=$value ;;
        --device) DEVICE=$value ;;
        --mesh) MESH=$value ;;
      esac
      ;;
  esac
  shift
done

if [ -n "$MESH" ] && [ ! -f "$MESH" ]; then
  bad_option "--mesh $MESH: no such file"
fi
if [ -n "$BIN" ] && { [ ! -f "$BIN" ] || [ ! -x "$BIN" ]; }; then
  bad_option "--bin $BIN: not an executable file"
fi
OUT=${OUT:-gpu-bench-$(date +%Y%m%d-%H%M%S)}
if [ -e "$OUT" ] && [ ! -d "$OUT" ]; then
  bad_option "--out $OUT: exists and is not a folder"
fi
if [ -d "$OUT" ] && [ -n "$(ls -A "$OUT")" ] && [ "$FORCE" = 0 ]; then
  bad_option "--out $OUT is not empty; pass --force to write into it"
fi

START=$SECONDS
elapsed() {
  local s=$((SECONDS - START))
  printf '%dm%02ds' $((s / 60)) $((s % 60))
}

if [ -z "$BIN" ]; then
  say "building arbor (cargo build --release) in $ROOT"
  (cd "$ROOT" && cargo build --release) || fail "cargo build --release failed"
  BIN=${CARGO_TARGET_DIR:-$ROOT/target}/release/arbor
  [ -x "$BIN" ] || fail "the build wrote no $BIN"
fi

DEVICE_ARGS=()
if [ -n "$DEVICE" ]; then DEVICE_ARGS=(--device "$DEVICE"); fi

# --- the device -----------------------------------------------------------------------
if ! DEVICES=$("$BIN" devices); then
  fail "'arbor devices' failed: no Vulkan device to benchmark"
fi
echo "arbor devices:" >&2
printf '%s\n' "$DEVICES" | sed 's/^/  /' >&2
# The line of the device bench opens: --device as an index or a name substring, else
# the first discrete GPU, else the first device (arbor's own rule).
DEVICE_LINE=$(awk -v sel="$DEVICE" '
  BEGIN { s = tolower(sel) }
  /^[0-9]+: / {
    i = $1; sub(":", "", i); name = substr($0, length($1) + 2)
    if (sel != "" && sel ~ /^[0-9]+$/) { if (i == sel) { print; exit } }
    else if (sel != "") { if (index(tolower(name), s)) { print; exit } }
    else { if (first == "") first = $0; if (disc == "" && index($0, "(discrete_gpu,")) disc = $0 }
  }
  END { if (sel == "") print (disc != "" ? disc : first) }' <<<"$DEVICES")
[ -n "$DEVICE_LINE" ] || bad_option "--device $DEVICE: no device of 'arbor devices' matches it"

# --- the structures -------------------------------------------------------------------
# Every --accel kind this arbor knows: its own list, from the message for an unknown one.
probe=$("$BIN" bench --accel '?' --help 2>&1 || true)
ACCEL=$(printf '%s\n' "$probe" | sed -n 's/.*available: \(.*\)$/\1/p' | sed 's/ (see .*//; s/, or auto$//; s/, /,/g' | head -1)
if ! printf '%s' "$ACCEL" | grep -Eq '^[a-z0-9-]+(,[a-z0-9-]+)*$'; then
  say "cannot read this arbor's list of structures; using $KNOWN_ACCEL"
  ACCEL=$KNOWN_ACCEL
fi
ACCEL=$(printf '%s' "$ACCEL" | tr ',' '\n' | grep -vx rayquery | paste -sd, -)
RAYQUERY=""
if printf '%s' "$DEVICE_LINE" | grep -q 'ray query yes'; then
  if "$BIN" bench --accel rayquery --help >/dev/null 2>&1; then
    RAYQUERY=rayquery
    RQ_NOTE="rayquery: included (the device has ray queries)"
  else
    RQ_NOTE="rayquery: left out: the device has ray queries, but this arbor has no --accel rayquery"
  fi
else
  why=$(printf '%s' "$DEVICE_LINE" | sed -n 's/.*ray query no (\(.*\))$/\1/p')
  RQ_NOTE="rayquery: left out: the device has no ray queries (${why:-its devices line does not say it has})"
fi
say "$RQ_NOTE"

# --- the mesh -------------------------------------------------------------------------
readable() { "$BIN" info --accel none "$1" >/dev/null 2>&1; }
MESH_NOTE=""
if [ -n "$MESH" ]; then
  readable "$MESH" || bad_option "--mesh $MESH: arbor cannot read it: $("$BIN" info --accel none "$MESH" 2>&1 | tail -1 | sed "s/^arbor: error: //")"
  MESH_NOTE="mesh: $MESH (--mesh)"
elif readable "$ASSIMP/PLY/Wuson.ply"; then
  MESH=$ASSIMP/PLY/Wuson.ply
  MESH_NOTE="mesh: $MESH (modelled, not scanned: assimp-testmodels has no scanned triangle mesh; pass --mesh FILE for a scan such as the Stanford bunny)"
else
  MESH_NOTE="mesh: left out: no readable mesh under $ASSIMP (apt install assimp-testmodels, or pass --mesh FILE)"
fi
say "$MESH_NOTE"
MESH_ARGS=()
if [ -n "$MESH" ]; then MESH_ARGS=(--scene "$MESH"); fi

mkdir -p "$OUT"
# --force: what an earlier run wrote goes; anything else in the folder stays.
rm -rf "$OUT"/[0-9][0-9]-*/ "$OUT/summary.md" "$OUT/devices.txt" "$OUT/calibration.txt"
printf '%s\n' "$DEVICES" >"$OUT/devices.txt"

# --- the cost model of --accel auto, measured first -----------------------------------
# --quick leaves it out: it is the same on a small grid (10-20 s on lavapipe, as long
# as the rest of the quick run), and `arbor calibrate` has a test of its own.
if [ "$QUICK" = 1 ]; then
  say "arbor calibrate: left out with --quick"
  echo "calibration: left out with --quick (run without it, or \`arbor calibrate\`)" >"$OUT/calibration.txt"
else
  say "arbor calibrate ${DEVICE_ARGS[*]}"
  if ! ARBOR_CACHE_DIR=${ARBOR_CACHE_DIR:-$OUT/cache} "$BIN" calibrate "${DEVICE_ARGS[@]}" >"$OUT/calibration.txt"; then
    fail "'arbor calibrate' failed"
  fi
fi

# --- the grid -------------------------------------------------------------------------
ALL=$ACCEL${RAYQUERY:+,$RAYQUERY}
STEP_NAMES=()
STEP_TITLES=()
STEP_ARGS=()
add_step() {
  STEP_NAMES+=("$1")
  STEP_TITLES+=("$2")
  shift 2
  local joined="" a
  for a in "$@"; do
    if [[ $a =~ ^[A-Za-z0-9_./,:=+@-]+$ ]]; then
      joined+="${joined:+ }$a"
    else
      joined+="${joined:+ }$(printf '%q' "$a")"
    fi
  done
  STEP_ARGS+=("$joined")
}
if [ "$QUICK" = 1 ]; then
  MODE="quick"
  add_step 01-structures "kdtree, bvh-sah, cwbvh${RAYQUERY:+, rayquery}; camera/diffuse/path rays; 1k blob; 128x128" \
    --tris 1000 --accel "kdtree,bvh-sah,cwbvh${RAYQUERY:+,$RAYQUERY}" --rays primary,diffuse,path --size 128x128 --repeat 1
  if [ -n "$MESH" ]; then
    add_step 02-build "lbvh, trbvh built on the CPU and the GPU; camera rays; the mesh; 128x128" \
      "${MESH_ARGS[@]}" --accel lbvh,trbvh --build cpu,gpu --rays primary --size 128x128 --repeat 1
  else
    add_step 02-build "lbvh, trbvh built on the CPU and the GPU; camera rays; 4k blob (no mesh); 128x128" \
      --tris 4000 --accel lbvh,trbvh --build cpu,gpu --rays primary --size 128x128 --repeat 1
  fi
else
  MODE="full"
  add_step 01-structures-1024 "every structure; camera/diffuse/path rays; 100k and 1M blobs${MESH:+ and the mesh}; 1024x1024" \
    --tris 100000,1000000 "${MESH_ARGS[@]}" --accel "$ALL" --rays primary,diffuse,path --size 1024x1024 --repeat 3
  add_step 02-structures-4096 "every structure; camera/diffuse/path rays; 100k blob; 4096x4096" \
    --tris 100000 --accel "$ALL" --rays primary,diffuse,path --size 4096x4096 --repeat 3
  add_step 03-build "lbvh, trbvh built on the CPU and the GPU; camera rays; 100k and 1M blobs${MESH:+ and the mesh}; 1024x1024" \
    --tris 100000,1000000 "${MESH_ARGS[@]}" --accel lbvh,trbvh --build cpu,gpu --rays primary --size 1024x1024 --repeat 3
fi

STEP_SECONDS=()
n=${#STEP_NAMES[@]}
for i in "${!STEP_NAMES[@]}"; do
  name=${STEP_NAMES[$i]}
  eval "args=(${STEP_ARGS[$i]})"
  echo >&2
  say "[$((i + 1))/$n] $name: ${STEP_TITLES[$i]} (elapsed $(elapsed))"
  say "    arbor bench ${STEP_ARGS[$i]}"
  t0=$SECONDS
  mkdir -p "$OUT/$name"
  if ! "$BIN" bench "${args[@]}" "${DEVICE_ARGS[@]}" --out "$OUT/$name" >"$OUT/$name/table.txt"; then
    fail "step $name failed (see the messages above; its table so far: $OUT/$name/table.txt)"
  fi
  STEP_SECONDS+=($((SECONDS - t0)))
  rows=$(($(wc -l <"$OUT/$name/bench.csv") - 1))
  say "    done in $((SECONDS - t0)) s: $rows rows in $OUT/$name"
done

# --- summary.md -----------------------------------------------------------------------
# The tables, from every step's bench.csv (columns: docs/bench.md).
SUMMARY_AWK=$(
  cat <<'AWK'
# CSV fields, quotes and doubled quotes included (mawk has no FPAT).
function split_csv(line, f,    n, i, c, q, cur) {
  n = 0; cur = ""; q = 0
  for (i = 1; i <= length(line); i++) {
    c = substr(line, i, 1)
    if (q) {
      if (c == "\"") { if (substr(line, i + 1, 1) == "\"") { cur = cur "\""; i++ } else q = 0 }
      else cur = cur c
    } else if (c == "\"") q = 1
    else if (c == ",") { f[++n] = cur; cur = "" }
    else cur = cur c
  }
  f[++n] = cur
  return n
}
function num(x) {
  if (x >= 100) return sprintf("%.0f", x)
  if (x >= 10) return sprintf("%.1f", x)
  if (x >= 1) return sprintf("%.2f", x)
  return sprintf("%.3f", x)
}
function thousands(n,    s, out) {
  s = sprintf("%d", n); out = ""
  while (length(s) > 3) { out = "," substr(s, length(s) - 2) out; s = substr(s, 1, length(s) - 3) }
  return s out
}
FNR == 1 {
  delete col
  for (i = 1; i <= split_csv($0, h); i++) col[h[i]] = i
  step = FILENAME; sub(/\/bench\.csv$/, "", step); sub(/.*\//, "", step)
  next
}
{
  split_csv($0, f)
  scene = f[col["scene"]]; rays = f[col["rays"]]; accel = f[col["accel"]]
  s = accel; if (index(f[col["label"]], "@gpu")) s = accel "@gpu"
  g = step SUBSEP scene
  if (!(g in gseen)) {
    gseen[g] = 1; groups[++ng] = g; gstep[g] = step; gtris[g] = f[col["triangles"]]
    gscene[g] = scene; sub(/.*\//, "", gscene[g])
  }
  w = f[col["width"]] + 0; hh = f[col["height"]] + 0
  if (w * hh > gpix[g]) { gpix[g] = w * hh; gsize[g] = w "x" hh }
  if (!((g, s) in sseen)) { sseen[g, s] = 1; gs[g, ++gns[g]] = s }
  if (!((g, rays) in rseen)) { rseen[g, rays] = 1; gr[g, ++gnr[g]] = rays }
  err = f[col["error"]]
  if (err != "") { cell[g, s, rays] = "failed"; errors[++nerr] = step ": " scene ", " s ", " rays ": " err }
  else {
    m = f[col["mrays_per_s"]] + 0
    cell[g, s, rays] = num(m); mr[g, s, rays] = m
    build[g, s, rays] = f[col["build_ms"]] + 0
  }
}
END {
  print ""
  print "## Mrays/s per structure and ray kind"
  print ""
  print "Million rays per second (all rays traced: camera, bounce and shadow rays). `@gpu`: built"
  print "on the GPU. Brute force (`none`) traces a smaller image of the same view."
  for (k = 1; k <= ng; k++) {
    g = groups[k]
    print ""
    print "### " gscene[g] " (" thousands(gtris[g]) " triangles), " gsize[g] ", step " gstep[g]
    print ""
    line = "| structure |"; sep = "|---|"
    for (j = 1; j <= gnr[g]; j++) { line = line " " gr[g, j] " |"; sep = sep "---:|" }
    print line; print sep
    for (i = 1; i <= gns[g]; i++) {
      s = gs[g, i]; line = "| " s " |"
      for (j = 1; j <= gnr[g]; j++) line = line " " (((g, s, gr[g, j]) in cell) ? cell[g, s, gr[g, j]] : "") " |"
      print line
    }
  }

  print ""
  print "## GPU build against CPU build"
  print ""
  print "Build throughput, million triangles per second: triangles over `build_ms` (the"
  print "median first build of a round, uploads and readback included for the GPU). GPU"
  print "speed-up: CPU ms over GPU ms."
  print ""
  print "| scene | triangles | structure | CPU ms | CPU Mtris/s | GPU ms | GPU Mtris/s | GPU speed-up |"
  print "|---|---:|---|---:|---:|---:|---:|---:|"
  rows = 0
  for (k = 1; k <= ng; k++) {
    g = groups[k]
    for (i = 1; i <= gns[g]; i++) {
      s = gs[g, i]
      if (s !~ /@gpu$/) continue
      c = substr(s, 1, length(s) - 4)
      for (j = 1; j <= gnr[g]; j++) {
        r = gr[g, j]
        if (!((g, s, r) in build) || !((g, c, r) in build)) continue
        bg = build[g, s, r]; bc = build[g, c, r]
        if (bg <= 0 || bc <= 0) continue
        t = gtris[g] + 0
        print "| " gscene[g] " | " thousands(t) " | " c " | " num(bc) " | " num(t / bc / 1000) " | " num(bg) " | " num(t / bg / 1000) " | " sprintf("%.2f", bc / bg) " |"
        rows++
        break
      }
    }
  }
  if (rows == 0) print "| (no structure was built on both) | | | | | | | |"

  print ""
  print "## rayquery against the best software structure"
  print ""
  rows = 0
  for (k = 1; k <= ng; k++) {
    g = groups[k]
    for (j = 1; j <= gnr[g]; j++) {
      r = gr[g, j]
      if (!((g, "rayquery", r) in mr)) continue
      best = ""; bm = 0
      for (i = 1; i <= gns[g]; i++) {
        s = gs[g, i]
        if (s == "rayquery" || !((g, s, r) in mr)) continue
        if (mr[g, s, r] > bm) { bm = mr[g, s, r]; best = s }
      }
      if (rows == 0) {
        print "Mrays/s of the driver's structure (VK_KHR_ray_query) and of the fastest of arbor's own."
        print ""
        print "| scene | size | rays | rayquery | best software | its Mrays/s | rayquery / best |"
        print "|---|---|---|---:|---|---:|---:|"
      }
      q = mr[g, "rayquery", r]
      print "| " gscene[g] " | " gsize[g] " | " r " | " num(q) " | " (best == "" ? "-" : best) " | " (best == "" ? "-" : num(bm)) " | " (bm > 0 ? sprintf("%.2f", q / bm) : "-") " |"
      rows++
    }
  }
  if (rows == 0 && rq_note ~ /included/) print "rayquery: every rayquery row failed (see \"Rows that failed\")."
  else if (rows == 0) print rq_note

  if (nerr > 0) {
    print ""
    print "## Rows that failed"
    print ""
    for (i = 1; i <= nerr; i++) print "- " errors[i]
  }
}
AWK
)
csvs=()
for name in "${STEP_NAMES[@]}"; do csvs+=("$OUT/$name/bench.csv"); done
{
  echo "# arbor GPU benchmark"
  echo
  echo "- date: $(date '+%Y-%m-%d %H:%M:%S %z')"
  echo "- arbor: $("$BIN" --version 2>/dev/null || echo unknown) ($BIN)"
  echo "- device: \`$DEVICE_LINE\`"
  echo "- mode: $MODE; figures are medians of the timed rounds (bench.csv in each step's folder)"
  echo "- $RQ_NOTE"
  echo "- $MESH_NOTE"
  echo "- total time: $(elapsed)"
  echo
  echo "## Steps"
  echo
  echo "| step | what | command | seconds |"
  echo "|---|---|---|---|"
  for i in "${!STEP_NAMES[@]}"; do
    echo "| ${STEP_NAMES[$i]} | ${STEP_TITLES[$i]} | \`arbor bench ${STEP_ARGS[$i]//|/\\|}\` | ${STEP_SECONDS[$i]} |"
  done
  awk -v rq_note="$RQ_NOTE" "$SUMMARY_AWK" "${csvs[@]}"
} >"$OUT/summary.md"

echo >&2
say "finished in $(elapsed): $OUT/summary.md"
