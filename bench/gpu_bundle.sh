#!/usr/bin/env bash
# Packs what bench/gpu_check.sh needs into one folder that a GPU machine without the toolchain or
# the packages can run: BUILD's CUDA tests, loop benchmark and `hivox` (the map commands' gpu
# test runs it), stripped, in BUILD's layout; the shared libraries they load (all but the C
# library, the loader and the driver); and the first FRAMES frames of fr1/rpy from DATA (the
# real-data tests and the fr1/rpy benchmarks use them).
#
#   bench/gpu_bundle.sh BUILD DEST [DATA] [FRAMES]   # DATA: ../shared/data, FRAMES: 120
#
# With HIVOX_BUNDLE_BEFORE=PATH (the hivox_gpu_loop of a build before the change to measure, say
# a worktree of the commit before), that binary goes in as bench/hivox_gpu_loop_before, and
# gpu_check.sh alternates it with the bundle's own: a change written without a GPU measured
# against what it changed, in one device call.
#
# The bundle is also packed into DEST.tgz (the folder itself is larger than a device call
# carries). Then, on the GPU machine, from the project's root (DEST.tgz carried):
#
#   tar xzf DEST.tgz
#   export LD_LIBRARY_PATH=$PWD/DEST/lib HIVOX_DATA_DIR=$PWD/DEST/data
#   bench/gpu_check.sh DEST OUT DEST/data/tum_fr1_rpy
set -eu
if [ $# -lt 2 ]; then
  echo "usage: $0 BUILD DEST [DATA] [FRAMES]" >&2
  exit 2
fi
build=$1
dest=$2
data=${3:-$(dirname "$0")/../../shared/data}
frames=${4:-120}
binaries="tests/test_cuda_loop tests/test_cuda_kernels bench/hivox_gpu_loop hivox"
for binary in $binaries; do
  if [ ! -x "$build/$binary" ]; then
    echo "$0: $build/$binary is missing (build with -DHIVOX_WITH_CUDA=ON)" >&2
    exit 2
  fi
done
before=${HIVOX_BUNDLE_BEFORE:-}
if [ -n "$before" ] && [ ! -x "$before" ]; then
  echo "$0: HIVOX_BUNDLE_BEFORE=$before is not an executable" >&2
  exit 2
fi
rm -rf "$dest"
mkdir -p "$dest/tests" "$dest/bench" "$dest/lib"
# pack SOURCE TARGET: the binary, stripped, and every library it loads from a path but the C
# library, the loader and the driver (the GPU machine has its own).
pack() {
  strip -o "$dest/$2" "$1"
  ldd "$1" | awk '$2 == "=>" && $3 ~ /^\// {print $3}' |
    grep -Ev '/(libc|libm|libdl|libpthread|librt|ld-linux[^/]*|libcuda)\.so' |
    while read -r lib; do cp -L "$lib" "$dest/lib/"; done
}
for binary in $binaries; do
  pack "$build/$binary" "$binary"
done
[ -n "$before" ] && pack "$before" bench/hivox_gpu_loop_before

fr1="$data/tum_fr1_rpy"
if [ -d "$fr1" ]; then
  cut="$dest/data/tum_fr1_rpy"
  mkdir -p "$cut/rgb" "$cut/depth"
  cp "$fr1"/*.json "$fr1/groundtruth.txt" "$cut/" 2> /dev/null || true
  # The first FRAMES associated pairs; the per-stream lists cut to the same frames.
  grep -v '^#' "$fr1/associations.txt" | head -n "$frames" > "$cut/pairs"
  {
    grep '^#' "$fr1/associations.txt"
    cat "$cut/pairs"
  } > "$cut/associations.txt"
  while read -r _ rgb _ depth; do
    cp "$fr1/$rgb" "$cut/rgb/"
    cp "$fr1/$depth" "$cut/depth/"
  done < "$cut/pairs"
  for stream in rgb depth; do
    awk 'NR == FNR {keep[$2] = 1; keep[$4] = 1; next} /^#/ || keep[$2]' "$cut/pairs" \
      "$fr1/$stream.txt" > "$cut/$stream.txt"
  done
  rm "$cut/pairs"
else
  echo "$0: no $fr1; the bundle holds no real data (those tests skip)" >&2
fi
# A device call carries at most 64 MiB with the checkout: the bundle goes into one compressed
# archive beside it too (`hivox`'s ray-tracing library alone is 44 MB; it compresses to a third,
# the frames' PNGs not at all). Carry the archive and unpack it there.
archive="$dest.tgz"
tar czf "$archive" -C "$(dirname "$dest")" "$(basename "$dest")"
du -sh "$dest" "$archive"
bytes=$(stat -c %s "$archive")
if [ "$bytes" -gt $((60 << 20)) ]; then
  echo "$0: $archive is over 60 MiB: with the checkout it may not fit a device call's 64 MiB" >&2
fi
