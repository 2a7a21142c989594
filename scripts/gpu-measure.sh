#!/usr/bin/env bash
# The GPU measurements issues 10 and 15 still need, for a session lent a GPU machine (device
# tools: `run`). Run from the checkout root after ../shared/device/pack.sh, with carry
# [".device"]. Two parts, each under the 10-minute limit of one call:
#   bash scripts/gpu-measure.sh a   (about 5 min on an H200) the blunt fin side scene (every
#       shells sampler, raycast), the walk's stage timings, the 10M grid static and deforming
#       (walk, compute, raycast), the 35M and 100M grids (walk, raycast);
#   bash scripts/gpu-measure.sh b   (about 5-6 min) the standard check for shells and raycast
#       (.device/gpu.sh), the 11.7M brain's first frame with the walk, the 35M grid with the
#       raster sampler, the tuner.
# Writes $OUT/log-<part>.txt and $OUT/gpu-<part>.tgz (bench CSVs, plots, PNGs).
set -u
PART=${1:-a}
case $PART in a|b) ;; *) echo "usage: bash scripts/gpu-measure.sh a|b" >&2; exit 2;; esac
OUT=${OUT:-/tmp/gpu-out}; mkdir -p "$OUT"
source .device/env.sh
W=/tmp/gpu-$PART; mkdir -p $W
T0=$(date +%s)
step() { echo; echo "=== [$(( $(date +%s) - T0 ))s] $*"; }
grid() { # tets, name: generate once
  [ -f $W/$2.vtu ] || timeout 60 tetvr generate grid --tets $1 -o $W/$2.vtu 2>&1 | tail -1
}
big() { # file, mode args...: 4 frames at 1024x1024 with timings
  local f=$1; shift
  local t=$(date +%s%N)
  timed timeout 150 tetvr render $f --max-memory 40G \
    --size 1024x1024 --frames 4 --timings -o $W/$(basename $f .vtu)_$(echo "$*" | tr -cd 'a-z').png "$@" 2>&1 | tail -24
  echo "  wall $(( ($(date +%s%N) - t) / 1000000 )) ms (load, build and 4 frames)"
}
# Peak RSS where GNU time exists (a bare machine may lack it).
timed() { if [ -x /usr/bin/time ]; then /usr/bin/time -f "  peak RSS %M KB" "$@"; else "$@"; fi; }

part_a() {
  step "adapter"; tetvr gpu-info | head -8
  step "blunt fin side 512x512: shells samplers, raycast"
  timeout 90 tetvr bench --data $D --scenes bluntfin-side --size 512x512 --runs 7 --modes shells,raycast --out $W/side 2>&1 | tail -25
  step "blunt fin 512x512: walk stage timings"
  timeout 30 tetvr render $D/bluntfin_tet.vtk --mode shells --sampler walk --size 512x512 --frames 15 --timings -o $W/fin_walk.png 2>&1 | tail -24
  step "grid 10M 1024x1024 static: walk, raycast"
  grid 10000000 g10
  big $W/g10.vtu --mode shells --sampler walk
  big $W/g10.vtu --mode raycast
  step "grid 10M 1024x1024 deforming: walk, compute, raycast"
  for s in walk compute; do
    timeout 60 tetvr animate $W/g10.vtu --mode shells --sampler $s --size 1024x1024 --deform twist --frames 6 --timings -o $W/g10_$s.gif 2>&1 | tail -6
  done
  timeout 60 tetvr animate $W/g10.vtu --mode raycast --size 1024x1024 --deform twist --frames 6 --timings -o $W/g10_rc.gif 2>&1 | tail -6
  rm -f $W/g10.vtu
  step "grid 35M 1024x1024: walk, raycast"
  grid 35000000 g35
  big $W/g35.vtu --mode shells --sampler walk
  big $W/g35.vtu --mode raycast
  rm -f $W/g35.vtu
  step "grid 100M 1024x1024: walk, raycast"
  grid 100000000 g100
  big $W/g100.vtu --mode shells --sampler walk
  big $W/g100.vtu --mode raycast
  rm -f $W/g100.vtu
}
part_b() {
  step "standard check, shells and raycast"
  timeout 330 bash .device/gpu.sh --modes shells,raycast
  B=$D/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz
  step "brain 11.7M tets, shells walk first frame"
  timeout 40 tetvr generate nifti $B --threshold 10 -o $W/brain.vtu 2>&1 | tail -2
  timeout 40 tetvr render $W/brain.vtu --mode shells --sampler walk --size 512x512 --timings -o $W/brain.png 2>&1 | head -16
  rm -f $W/brain.vtu
  step "grid 35M 1024x1024: shells raster (records chunked within the 2 GiB bindings)"
  grid 35000000 g35
  big $W/g35.vtu --mode shells --sampler raster
  rm -f $W/g35.vtu
  step "shells tuner, blunt fin 512x512"
  timeout 60 tetvr render $D/bluntfin_tet.vtk --mode shells --tune on --size 512x512 --frames 36 -o $W/fin_tuned.png 2>&1 | tail -12
}
{ part_$PART; step done; } 2>&1 | tee $OUT/log-$PART.txt
rm -rf $W/*/cache $W/*.vtu
cp /tmp/gpu-out/log.txt $OUT/ 2>/dev/null
tar czf $OUT/gpu-$PART.tgz -C $W . 2>/dev/null
