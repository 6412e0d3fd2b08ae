#!/usr/bin/env bash
# What a machine with a CUDA GPU should run on the CUDA loop, most important first, so that a short
# session gets the most out of its minutes (a run cut short keeps what it wrote): the gpu tests; the
# run known to fault on the device, its GPU core dump read by cuda-gdb, and again with the pool as
# one plain allocation and with the refinement in order after the raycast; the raycast with its
# marches queued for a second kernel, alone and with the tracking model raycast at a quarter of the
# frame's resolution, against the default, once each; ncu's time a frame for every kernel, then the
# ray kernel's stalls line by line; with the loop of an earlier build in the bundle (gpu_bundle.sh,
# HIVOX_BUNDLE_BEFORE), the two alternated (a change made without a GPU against what it changed);
# meshing and a render on the device against the host; bench/gpu_loop on fr1/rpy and the desk with
# each opt-in no GPU has judged yet against the default, alternated (the marches queued for a second
# kernel, alone and with the model at a quarter, the model at a quarter alone, split marches of up
# to 8 and 32 rays a warp, refinement after the raycast, frames up beside it, the two together), one
# round on both before the second; compute-sanitizer's initcheck on the mesh tests and on the run
# that faulted; the rest (the opt-ins measured before: register caps, split marches of 1,
# Gauss-Newton on the host, allocation threads of several pixels, tracking as a graph; the coarse
# grid off, frames decoded as the loop goes, opt-ins together, the fixed grid); ncu on the ray
# kernel with a register cap; and last compute-sanitizer's memcheck on the newest tests. Each step's
# log goes to OUT/NAME.log, each benchmark's numbers to OUT/NAME.json, and OUT/summary.txt lists
# every step with its exit status and time; a failed step's failures are printed as well.
# OUT/times.txt lists every run's numbers, OUT/ratios.txt each variant's mean frame time against the
# default's (after against before). A device machine that returns only a few files: give an OUT
# outside the returned folder and pack it, `bench/gpu_check.sh B /tmp/check ...; tar czf
# $OUT/check.tgz -C /tmp check`.
#
#   bench/gpu_check.sh BUILD OUT [FR1_RPY_FOLDER]    # BUILD: a -DHIVOX_WITH_CUDA=ON build
#
# BUILD may be a bundle made by bench/gpu_bundle.sh (binaries, libraries and a cut of fr1/rpy in
# one folder for a machine without the toolchain).
#
# Environment: HIVOX_CHECK_STEP_S (default 300) bounds each step; HIVOX_CHECK_BUDGET_S (default:
# none) bounds the whole check: a step starts only while the budget lasts and gets no more than
# what is left, the steps it leaves are listed as skipped, and times.txt is still written, so a
# lease's single call ends with its numbers (give the lent machines' calls a budget well inside
# their limit); HIVOX_CHECK_SKIP_MEMCHECK=1 leaves the compute-sanitizer runs (memcheck,
# initcheck) out.
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

budget=${HIVOX_CHECK_BUDGET_S:-0}
skipped=0
# step NAME COMMAND...: runs COMMAND with its output in OUT/NAME.log, bounded by $limit seconds
# and by what is left of the budget (none left: listed as skipped, not run).
step() {
  local name=$1
  shift
  local bound=$limit
  if [ "$budget" -gt 0 ]; then
    local left=$((budget - SECONDS))
    if [ "$left" -lt 5 ]; then
      printf '%-28s skipped (budget of %d s spent)  %s\n' "$name" "$budget" "$*" >> "$summary"
      skipped=$((skipped + 1))
      return
    fi
    [ "$left" -lt "$bound" ] && bound=$left
  fi
  local start=$SECONDS
  timeout -k 5 "$bound" "$@" > "$out/$name.log" 2>&1
  local status=$?
  printf '%-28s exit %3d  %4d s  %s\n' "$name" "$status" $((SECONDS - start)) "$*" | tee -a "$summary"
  # A failed step's failures on the terminal too (a device session may bring back few files).
  if [ "$status" -ne 0 ]; then
    grep -A6 -E 'Failure|FAILED|ERROR SUMMARY|error' "$out/$name.log" | head -n 40
  fi
}

for binary in tests/test_cuda_loop tests/test_cuda_kernels bench/hivox_gpu_loop hivox; do
  if [ ! -x "$build/$binary" ]; then
    echo "$0: $build/$binary is missing (build with -DHIVOX_WITH_CUDA=ON)" >&2
    exit 2
  fi
done
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$out/gpu.txt" 2>&1
# The map commands' gpu test runs the CLI: this build's, wherever the build now lies.
export HIVOX_BIN=$build/hivox

step test_cuda_loop "$build/tests/test_cuda_loop"
step test_cuda_kernels "$build/tests/test_cuda_kernels"

loop="$build/bench/hivox_gpu_loop"
desk="synthetic:desk?frames=150&noise=kinect"
ncu=$(command -v ncu || ls /usr/local/cuda*/bin/ncu 2> /dev/null | head -n 1)
gdb=$(command -v cuda-gdb || ls /usr/local/cuda*/bin/cuda-gdb 2> /dev/null | head -n 1)

# The run that faulted on the H200 (refinement after the raycast on fr1/rpy: an illegal memory
# access between frames 110 and 120, none under memcheck), with CUDA's core dump on a device
# exception, then cuda-gdb's reading of the dump: the kernel, the faulting line (the build's
# -lineinfo), the exception and its address. A dump without memory: a few MiB. Then the same
# run with the pool as one plain allocation of its whole capacity: where that one runs through,
# the fault read memory the growing pool had not committed.
if [ -n "$fr1" ]; then
  faulted=("$loop" "$fr1" --levels 3 --refine-after-raycast --frames 120)
  core="$out/fault.cudacore"
  CUDA_ENABLE_COREDUMP_ON_EXCEPTION=1 CUDA_ENABLE_LIGHTWEIGHT_COREDUMP=1 \
    CUDA_ENABLE_CPU_COREDUMP_ON_EXCEPTION=0 CUDA_COREDUMP_FILE="$core" \
    step fault_refine_after "${faulted[@]}"
  if [ -f "$core" ] && [ -n "$gdb" ]; then
    step fault_where "$gdb" -batch -ex "target cudacore $core" -ex "info cuda kernels" -ex bt \
      -ex "info cuda warps" -ex "x/4i \$errorpc" "$loop"
    head -n 60 "$out/fault_where.log"
    rm -f "$core"
  fi
  HIVOX_CUDA_VIRTUAL_MEMORY=off step fault_refine_after_plain_pool "${faulted[@]}"
  # The same refinement in order after the raycast on the loop's stream, not beside it: where
  # this one runs through, the fault needs the overlap (the emulation never interleaves the two
  # streams' kernels); where it faults too, the order of the edits.
  step fault_refine_after_in_order "${faulted[@]}" --refine-in-order
fi

# run_loop BINARY NAME DATA LEVELS [FLAGS...]: one run of a loop, its numbers in OUT/NAME.json
# (none without DATA: fr1/rpy not given).
run_loop() {
  local binary=$1 name=$2 data=$3 levels=$4
  shift 4
  [ -z "$data" ] && return
  step "$name" "$binary" "$data" --levels "$levels" "$@" --json "$out/$name.json"
}
# bench NAME DATA LEVELS [FLAGS...]: a run of the bundle's loop.
bench() { run_loop "$loop" "$@"; }
# data_of fr1|desk: what the loop runs on (fr1/rpy's folder, empty when not given).
data_of() { if [ "$1" = fr1 ]; then echo "$fr1"; else echo "$desk"; fi; }
# Before the profiles, the opt-in the 1000 fps target waits on: the raycast with its marches
# queued for a second kernel against the default, once on each (round c; rounds a and b follow
# with the other opt-ins), so that the shortest session still times it.
# queued DATA ROUND: the default and the queued marches, 3 levels, on fr1|desk; then the queued
# marches with the tracking model raycast at a quarter of the frame's resolution instead of a
# half (4x fewer rays; on the CPU the ATE moves by 1-5 %: BENCHMARKS.md, nineteenth session).
queued() {
  bench "${1}_l3_default_$2" "$(data_of "$1")" 3
  bench "${1}_l3_queued_$2" "$(data_of "$1")" 3 --queued-marches
  bench "${1}_l3_queued_model4_$2" "$(data_of "$1")" 3 --queued-marches --model-subsample 4
}
queued fr1 c
queued desk c

# Every kernel's time a frame (fr1/rpy, 3 levels, about ten frames after the first ~45): where a
# frame's device time goes, for the 1000 fps target (bench/ncu_kernels.py's table).
if [ -n "$ncu" ] && [ -n "$fr1" ]; then
  step ncu_kernels "$ncu" --metrics gpu__time_duration.sum --csv --page raw --print-units base \
    --launch-skip 3000 --launch-count 650 "$loop" "$fr1" --levels 3 --frames 80
  if [ -f "$out/ncu_kernels.log" ]; then
    python3 "$(dirname "$0")/ncu_kernels.py" "$out/ncu_kernels.log" | tee "$out/ncu_kernels.txt"
  fi
fi
# The ray kernel, the largest, one launch after 40 frames: its registers, occupancy and waves,
# what its warps stall on and where (ncu's source page, by the build's -lineinfo, as CSV: each
# line's instructions, stall samples and memory traffic). Is its time the latency of its
# slowest warps' look-ups, or the instructions' fetch?
if [ -n "$ncu" ] && [ -n "$fr1" ]; then
  rep="$out/rays"
  step ncu_rays "$ncu" --kernel-name regex:cast_rays --launch-skip 40 --launch-count 1 \
    --section LaunchStats --section Occupancy --section SpeedOfLight --section WarpStateStats \
    --section SchedulerStats --section SourceCounters --import-source yes -o "$rep" \
    "$loop" "$fr1" --levels 3 --frames 50
  if [ -f "$rep.ncu-rep" ]; then
    step ncu_rays_details "$ncu" --import "$rep.ncu-rep" --page details
    step ncu_rays_source "$ncu" --import "$rep.ncu-rep" --page source --csv --print-source cuda
    rm -f "$rep.ncu-rep"
  fi
fi
# A bundle with the loop of the build before a change (gpu_bundle.sh, HIVOX_BUNDLE_BEFORE): the
# two alternated first, 3 levels and the fixed grid.
before="$build/bench/hivox_gpu_loop_before"
if [ -x "$before" ]; then
  for data in fr1 desk; do
    for round in a b c; do
      for levels in 3 1; do
        run_loop "$before" "${data}_l${levels}_before_$round" "$(data_of $data)" "$levels"
        bench "${data}_l${levels}_after_$round" "$(data_of $data)" "$levels"
      done
    done
  done
fi
# A mesh and a render on the device against the host's way (the map downloaded), the desk.
bench desk_l3_mesh "$desk" 3 --poses gt --mesh --render
# The opt-ins no GPU has judged yet against the default, alternated, 3 levels, fr1/rpy first
# (its marches are long): the raycast as two kernels, the marches queued and each taken across a
# warp's lanes (bench/ray_cost's model: the tail of the ray kernel is its marches, in 20 % of
# its warps), alone and with the tracking model raycast at a quarter of the frame's resolution;
# the model at a quarter alone; split marches where up to 8 and 32 of a warp's rays march (each
# taken across the warp's 32 lanes; up to 1 changed nothing on the H200); refinement after the
# raycast (beside it, on a stream of its own), frames up beside the raycast, the two together. A
# first round on both, then the second, so that a short budget still compares each once. The
# opt-ins measured before (register caps, split marches of 1, Gauss-Newton on the host,
# allocation threads of several pixels, tracking as a graph: none faster) come after, with the
# rest.
optins() {
  local data=$1 round=$2 src
  src=$(data_of "$data")
  queued "$data" "$round"
  bench "${data}_l3_split8_$round" "$src" 3 --split-marches 8
  bench "${data}_l3_split32_$round" "$src" 3 --split-marches 32
  bench "${data}_l3_model4_$round" "$src" 3 --model-subsample 4
  bench "${data}_l3_refine_after_$round" "$src" 3 --refine-after-raycast
  bench "${data}_l3_upload_beside_$round" "$src" 3 --upload-beside
  bench "${data}_l3_both_beside_$round" "$src" 3 --refine-after-raycast --upload-beside
}
optins fr1 a
optins desk a
# The two mesh tests whose results moved under memcheck (a race or a read of memory never
# written would explain it): initcheck names reads of device memory never written.
sanitize=0
if [ "${HIVOX_CHECK_SKIP_MEMCHECK:-0}" != 1 ] && command -v compute-sanitizer > /dev/null; then
  sanitize=1
  step initcheck_mesh_tests compute-sanitizer --tool initcheck --error-exitcode 3 \
    "$build/tests/test_cuda_loop" --gtest_filter='*MeshesOnTheDevice*:*AReconstructionAndARun*'
  # The run that faulted, under initcheck: memcheck ran it through clean (no read outside an
  # allocation, 2026-11-29), and clang's ASan found nothing on the CPU's or the emulation's way
  # through it, so a read of device memory never written is the suspect left.
  if [ -n "$fr1" ]; then
    step initcheck_fault compute-sanitizer --tool initcheck --error-exitcode 3 --print-limit 50 \
      "${faulted[@]}"
  fi
fi
optins fr1 b
optins desk b
# The rest, on each: the opt-ins measured before, the coarse occupancy grid off, the loop with
# its frames decoded as it goes (in turn and ahead: wall_fps in the json), opt-ins together, and
# the fixed grid (the hierarchy's target is 1.2x the fixed grid's time).
for data in fr1 desk; do
  src=$(data_of $data)
  bench "${data}_l3_regs96" "$src" 3 --raycast-registers 96
  bench "${data}_l3_regs64" "$src" 3 --raycast-registers 64
  bench "${data}_l3_split1" "$src" 3 --split-marches 1
  bench "${data}_l3_gn_host" "$src" 3 --gn-on-host
  bench "${data}_l3_alloc2" "$src" 3 --allocation-pixels 2
  bench "${data}_l3_alloc4" "$src" 3 --allocation-pixels 4
  bench "${data}_l3_graph" "$src" 3 --tracking-graph
  bench "${data}_l3_regs80" "$src" 3 --raycast-registers 80
  bench "${data}_l3_regs128" "$src" 3 --raycast-registers 128
  bench "${data}_l3_no_grid" "$src" 3 --no-coarse-grid
  bench "${data}_l3_read_in_turn" "$src" 3 --read-threads 0
  bench "${data}_l3_read_ahead8" "$src" 3 --read-threads 8
  bench "${data}_l3_all" "$src" 3 --split-marches 1 --no-coarse-grid
  bench "${data}_l1_default" "$src" 1
  bench "${data}_l1_queued" "$src" 1 --queued-marches
  bench "${data}_l1_regs96" "$src" 1 --raycast-registers 96
  bench "${data}_l1_alloc4" "$src" 1 --allocation-pixels 4
  bench "${data}_l1_graph" "$src" 1 --tracking-graph
  bench "${data}_l1_upload_beside" "$src" 1 --upload-beside
  bench "${data}_l3_alloc4_graph" "$src" 3 --allocation-pixels 4 --tracking-graph
  bench "${data}_l3_alloc4_graph_refine_after" "$src" 3 --allocation-pixels 4 --tracking-graph \
    --refine-after-raycast
  bench "${data}_l1_all" "$src" 1 --split-marches 1 --no-coarse-grid
done
# The ray kernel capped at 96 registers as ncu sees it, against the uncapped ncu_rays above:
# its registers, occupancy, waves and what its warps stall on (fr1/rpy, 3 levels, three launches
# after 40 frames).
if [ -n "$ncu" ] && [ -n "$fr1" ]; then
  step ncu_rays_regs96 "$ncu" --kernel-name regex:cast_rays --launch-skip 40 --launch-count 3 \
    --section LaunchStats --section Occupancy --section SpeedOfLight --section WarpStateStats \
    "$loop" "$fr1" --levels 3 --frames 50 --raycast-registers 96
fi
if [ "$sanitize" = 1 ]; then
  step memcheck_new_tests compute-sanitizer --tool memcheck --error-exitcode 3 \
    "$build/tests/test_cuda_loop" \
    --gtest_filter='*MeshesOnTheDevice*:*AReconstructionAndARun*:*RendersOnTheDevice*:*RefinesBeside*:*UploadsBeside*:*RegistersCapped*:*SplitMarches*:*SeveralPixels*:*GaussNewtonOnTheDevice*'
fi
# Every run's frame time, allocation and raycast (mean ms), wall-clock fps and blocks in one list,
# OUT/times.txt, and on the terminal: a device call that brings back only its output's tail still
# has the numbers.
field() { grep -o "\"$1\": [^,}]*" "$2" | head -n 1 | sed 's/.*: //'; }
for json in "$out"/*.json; do
  [ -f "$json" ] || continue
  printf '%-28s total %s  allocate %s  raycast %s  wall_fps %s  blocks %s\n' \
    "$(basename "$json" .json)" "$(field total "$json")" "$(field allocate "$json")" \
    "$(field raycast "$json")" "$(field wall_fps "$json")" "$(field blocks "$json")"
done | tee "$out/times.txt"
# Each variant's mean frame time against the default's on the same data and levels (the
# before-and-after runs: after against before), OUT/ratios.txt, also on the terminal.
awk '$1 !~ /mesh/ && $3 ~ /^[0-9.]+$/ {
  n = split($1, p, "_"); key = p[1] "_" p[2]; v = ""
  for (i = 3; i <= n; ++i) {
    if (i == n && p[i] ~ /^[abc]$/) break
    v = v (v == "" ? "" : "_") p[i]
  }
  sum[key, v] += $3; count[key, v]++
} END {
  for (kv in count) {
    split(kv, q, SUBSEP); base = q[2] == "after" ? "before" : "default"
    if (q[2] == base || q[2] == "before" || !((q[1], base) in count)) continue
    m = sum[kv] / count[kv]; b = sum[q[1], base] / count[q[1], base]
    printf "%-8s %-24s %.3f ms (%d runs) against %s %.3f ms (%d): %.3fx\n", q[1], q[2], m,
           count[kv], base, b, count[q[1], base], m / b
  }
  # The hierarchy against the fixed grid (the target: at most 1.2x), by the same variant.
  for (kv in count) {
    split(kv, q, SUBSEP)
    if (q[1] !~ /_l3$/) continue
    d = q[1]; sub(/_l3$/, "", d)
    if (!((d "_l1", q[2]) in count)) continue
    printf "%-8s %-24s 3 levels against the fixed grid: %.3fx\n", d, q[2],
           (sum[kv] / count[kv]) / (sum[d "_l1", q[2]] / count[d "_l1", q[2]])
  }
}' "$out/times.txt" | sort | tee "$out/ratios.txt"
[ "$skipped" -gt 0 ] && echo "$skipped steps skipped: the budget of $budget s was spent (summary.txt)"
echo "logs and numbers in $out"
