#!/usr/bin/env bash
# Renders SCENE over N Slurm array tasks and merges the parts into IMAGE:
#
#   examples/slurm/submit.sh SCENE N IMAGE [render options...]
#
# for example `submit.sh scene.toml 8 frame.exr --spp 256 --size 1920x1080`. The merge
# job depends on the array (afterok) and this script waits for it (sbatch --wait), so
# its exit status is the merge's. The parts go to IMAGE's directory, in
# IMAGE.parts/. ARBOR names the binary (default: arbor on PATH).
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 SCENE N IMAGE [render options...]" >&2
  exit 2
fi
scene=$1 n=$2 image=$3
shift 3
here=$(cd "$(dirname "$0")" && pwd)
out="$image.parts"
export SCENE="$scene" OUT="$out" SHARDS="$n" IMAGE="$image" ARBOR="${ARBOR:-arbor}" ARBOR_ARGS="$*"
array=$(sbatch --parsable --array="0-$((n - 1))" --export=ALL "$here/render.sbatch")
array=${array%%;*}
echo "submit: render array $array ($n tasks), parts in $out" >&2
sbatch --wait --dependency="afterok:$array" --kill-on-invalid-dep=yes --export=ALL "$here/merge.sbatch"
