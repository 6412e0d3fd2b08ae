#!/usr/bin/env bash
# What a machine with a CUDA GPU should run on the CUDA loop, most important first, so that a
# short session gets the most out of its minutes: the gpu tests, compute-sanitizer's memcheck on
# the newest of them, then bench/gpu_loop on the desk and fr1/rpy (fixed grid and 3 levels;
# Gauss-Newton on the host and on the device, alternated; the coarse occupancy grid off and on;
# split marches off and on; meshing on the device and the host).
# Each step's log goes to OUT/NAME.log, each benchmark's numbers to OUT/NAME.json, and
# OUT/summary.txt lists every step with its exit status and time.
#
#   bench/gpu_check.sh BUILD OUT [FR1_RPY_FOLDER]    # BUILD: a -DHIVOX_WITH_CUDA=ON build
#
# BUILD may be a bundle made by bench/gpu_bundle.sh (binaries, libraries and a cut of fr1/rpy in
# one folder for a machine without the toolchain).
#
# Environment: HIVOX_CHECK_STEP_S (default 300) bounds each step, HIVOX_CHECK_SKIP_MEMCHECK=1
# leaves the memcheck out.
set -u
if [ $# -lt 2 ]; then
  echo "usage: $0 BUILD OUT [FR1_RPY_FOLDER]" >&2
  exit 2
fi
build=$1
out=$2
fr1=${3:-}
limit=${HIVOX_CHECK_STEP_S:-300}
mkdir -p "$out"
summary="$out/summary.txt"
: > "$summary"

# step NAME COMMAND...: runs COMMAND with its output in OUT/NAME.log, bounded by $limit seconds.
step() {
  local name=$1
  shift
  local start=$SECONDS
  timeout "$limit" "$@" > "$out/$name.log" 2>&1
  local status=$?
  printf '%-28s exit %3d  %4d s  %s\n' "$name" "$status" $((SECONDS - start)) "$*" | tee -a "$summary"
}

for binary in tests/test_cuda_loop tests/test_cuda_kernels bench/hivox_gpu_loop; do
  if [ ! -x "$build/$binary" ]; then
    echo "$0: $build/$binary is missing (build with -DHIVOX_WITH_CUDA=ON)" >&2
    exit 2
  fi
done
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt" 2>&1

step test_cuda_loop "$build/tests/test_cuda_loop"
step test_cuda_kernels "$build/tests/test_cuda_kernels"
if [ "${HIVOX_CHECK_SKIP_MEMCHECK:-0}" != 1 ] && command -v compute-sanitizer > /dev/null; then
  step memcheck_new_tests compute-sanitizer --tool memcheck --error-exitcode 3 \
    "$build/tests/test_cuda_loop" \
    --gtest_filter='*MeshesOnTheDevice*:*GaussNewtonOnTheDevice*:*HoldsNoMoreMemory*:*SplitMarches*'
fi

loop="$build/bench/hivox_gpu_loop"
desk="synthetic:desk?frames=150&noise=kinect"
# Gauss-Newton on the host and on the device, alternated: a pair per data set.
for levels in 3 1; do
  step "desk_l${levels}_gn_host" "$loop" "$desk" --levels "$levels" --json "$out/desk_l${levels}_gn_host.json"
  step "desk_l${levels}_gn_device" "$loop" "$desk" --levels "$levels" --gn-on-device \
    --json "$out/desk_l${levels}_gn_device.json"
  if [ -n "$fr1" ]; then
    step "fr1_l${levels}_gn_host" "$loop" "$fr1" --levels "$levels" --json "$out/fr1_l${levels}_gn_host.json"
    step "fr1_l${levels}_gn_device" "$loop" "$fr1" --levels "$levels" --gn-on-device \
      --json "$out/fr1_l${levels}_gn_device.json"
  fi
done
# The raycast's coarse occupancy grid off and on, alternated (fr1/rpy has the long marches).
if [ -n "$fr1" ]; then
  for grid in off on; do
    flag=""
    [ "$grid" = off ] && flag=--no-coarse-grid
    step "fr1_l3_grid_$grid" "$loop" "$fr1" --levels 3 $flag --json "$out/fr1_l3_grid_$grid.json"
  done
fi
# Split marches (a warp with at most N marching rays splits them across its lanes) off and on,
# alternated, where the marches are long (fr1/rpy) and short (the desk).
for data in desk fr1; do
  src=$desk
  [ "$data" = fr1 ] && src=$fr1
  [ -z "$src" ] && continue
  run=0
  for split in 0 1 0 1; do
    run=$((run + 1))
    step "${data}_l3_split${split}_run$run" "$loop" "$src" --levels 3 --split-marches "$split" \
      --json "$out/${data}_l3_split${split}_run$run.json"
  done
done
step desk_l3_mesh "$loop" "$desk" --levels 3 --poses gt --mesh --json "$out/desk_l3_mesh.json"
echo "logs and numbers in $out"
