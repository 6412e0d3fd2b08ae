// The CUDA mesher's launches: the passes of mesh/mesh_passes.h. A block's marching cubes is one
// thread's serial work over its padded block (~26 KB of scratch, too much for a thread's local
// memory across a whole GPU), so a fixed set of threads loops over the blocks, each with its
// padded block in global memory; the corners are resolved one thread each.

#include <cuda_runtime.h>

#include "core/parallel.h"
#include "cuda/loop_kernels.h"

namespace hivox::cuda {

namespace {

constexpr int kMeshThreadsPerBlock = 64;

// In both passes a thread's look-up cache is a local variable: its size differs between host and
// device code (BlockLookupCache::kSlots), so it cannot be part of a buffer the host sizes.
__global__ void count_meshes_kernel(const __grid_constant__ MapView map,
                                    const __grid_constant__ kernels::MeshPassInput in,
                                    kernels::MeshBlockScratch* scratch,
                                    kernels::BlockMeshCount* counts) {
  const int64_t t = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const int64_t stride = static_cast<int64_t>(gridDim.x) * blockDim.x;
  kernels::BlockLookupCache cache;
  cache.reset();
  for (int64_t i = t; i < in.block_count; i += stride)
    counts[i] = kernels::count_block_mesh(map, cache, in, static_cast<int32_t>(i), scratch[t]);
}

__global__ void write_meshes_kernel(const __grid_constant__ MapView map,
                                    const __grid_constant__ kernels::MeshPassInput in,
                                    kernels::MeshBlockScratch* scratch,
                                    const __grid_constant__ kernels::MeshArrays out) {
  const int64_t t = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const int64_t stride = static_cast<int64_t>(gridDim.x) * blockDim.x;
  kernels::BlockLookupCache cache;
  cache.reset();
  for (int64_t i = t; i < in.block_count; i += stride)
    kernels::write_block_mesh(map, cache, in, static_cast<int32_t>(i), scratch[t], out);
}

__global__ void resolve_corners_kernel(const __grid_constant__ kernels::MeshPassInput in,
                                       const uint16_t* edges, const kernels::EdgeRef* corners,
                                       int64_t n, int32_t* vertex_index,
                                       unsigned long long* unresolved) {
  const int64_t k = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (k >= n) return;
  const int64_t v = kernels::resolve_corner(in, edges, corners[k]);
  vertex_index[k] = v < 0 ? 0 : static_cast<int32_t>(v);
  if (v < 0) atomicAdd(unresolved, 1ull);
}

unsigned mesh_grid(int threads) {
  return static_cast<unsigned>((threads + kMeshThreadsPerBlock - 1) / kMeshThreadsPerBlock);
}

}  // namespace

std::size_t mesh_scratch_bytes() {
  return sizeof(kernels::MeshBlockScratch);
}

int mesh_thread_count(int64_t blocks, int most) {
  const int64_t per = kMeshThreadsPerBlock;
  const int64_t wanted = blocks < most ? blocks : most;
  return static_cast<int>(((wanted + per - 1) / per) * per);
}

void count_meshes(const MapView& map, const kernels::MeshPassInput& in, void* scratch, int threads,
                  kernels::BlockMeshCount* counts) {
  if (in.block_count == 0) return;
  launch(count_meshes_kernel, mesh_grid(threads), kMeshThreadsPerBlock, map, in,
         static_cast<kernels::MeshBlockScratch*>(scratch), counts);
}

void write_meshes(const MapView& map, const kernels::MeshPassInput& in, void* scratch, int threads,
                  const kernels::MeshArrays& out) {
  if (in.block_count == 0) return;
  launch(write_meshes_kernel, mesh_grid(threads), kMeshThreadsPerBlock, map, in,
         static_cast<kernels::MeshBlockScratch*>(scratch), out);
}

void resolve_corners(const kernels::MeshPassInput& in, const uint16_t* edges,
                     const kernels::EdgeRef* corners, int64_t n, int32_t* vertex_index,
                     unsigned long long* unresolved) {
  if (n == 0) return;
  constexpr int kThreads = 256;
  launch(resolve_corners_kernel, static_cast<unsigned>((n + kThreads - 1) / kThreads), kThreads, in,
         edges, corners, n, vertex_index, unresolved);
}

}  // namespace hivox::cuda
