#pragma once
// Device helpers shared by the CUDA loop's kernels (nvcc only).

#include <cstdint>

#include "cuda/loop_kernels.h"

namespace hivox::cuda {

/// This thread's lane in its warp (blocks of one or two dimensions).
__device__ inline unsigned lane_index() {
  return (threadIdx.x + threadIdx.y * blockDim.x) & 31u;
}

/// Adds 1 to `counter` for every lane of the warp where `flag` holds: one atomic per warp.
__device__ inline void count_warp(bool flag, int32_t* counter) {
  const unsigned mask = __activemask();
  const unsigned ballot = __ballot_sync(mask, flag);
  const int leader = __ffs(mask) - 1;
  if (static_cast<int>(lane_index()) == leader && ballot != 0) atomicAdd(counter, __popc(ballot));
}

/// The lanes of the warp that are here where `flag` holds take consecutive indices of
/// `*counter` (one atomic per warp); -1 where `flag` is false.
__device__ inline int32_t append_index(bool flag, int32_t* counter) {
  const unsigned mask = __activemask();
  const unsigned ballot = __ballot_sync(mask, flag);
  if (ballot == 0) return -1;
  const unsigned lane = lane_index();
  const int leader = __ffs(ballot) - 1;
  int32_t base = 0;
  if (static_cast<int>(lane) == leader) base = atomicAdd(counter, __popc(ballot));
  base = __shfl_sync(mask, base, leader);
  return flag ? base + __popc(ballot & ((1u << lane) - 1u)) : -1;
}

/// A block key packed in 64 bits: 20 bits per coordinate, 4 for the level; never all ones.
__device__ inline unsigned long long pack_key(int level, const Vec3i& p) {
  return (static_cast<unsigned long long>(p.x & 0xFFFFF) << 44) |
         (static_cast<unsigned long long>(p.y & 0xFFFFF) << 24) |
         (static_cast<unsigned long long>(p.z & 0xFFFFF) << 4) |
         static_cast<unsigned long long>(level);
}

/// Adds block key (level, pos) to `set` once: the first thread to add it appends it to the list
/// (when there is room) and counts it in `*count`; a full set counts it too, and drops it.
__device__ inline void add_unique(const BlockKeySet& set, int level, const Vec3i& pos,
                                  int32_t* count) {
  const unsigned long long key = pack_key(level, pos);
  uint32_t slot = static_cast<uint32_t>((key * 0x9E3779B97F4A7C15ull) >> 32) & set.mask;
  for (uint32_t probe = 0; probe <= set.mask; ++probe) {
    const unsigned long long seen = atomicCAS(&set.keys[slot], ~0ull, key);
    if (seen == key) return;  // another thread added it
    if (seen == ~0ull) {
      const int32_t i = atomicAdd(count, 1);
      if (i < set.capacity) set.list[i] = BlockKey{pos, level};
      return;
    }
    slot = (slot + 1) & set.mask;
  }
  atomicAdd(count, 1);  // the set is full: counted, dropped by the caller
}

/// The bitwise or of `value` over the warp's 32 lanes, every one of which calls it: one
/// instruction from compute capability 8.0 on (and in the CPU emulation, which stands for such a
/// GPU), shuffles before.
__device__ inline unsigned warp_or(unsigned value) {
#if (defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800) || defined(HIVOX_CUDA_EMULATION)
  return __reduce_or_sync(0xffffffffu, value);
#else
  for (unsigned d = 16; d > 0; d >>= 1) value |= __shfl_xor_sync(0xffffffffu, value, d);
  return value;
#endif
}

/// A block's surface summary (BlockSurface) built by its threads, one voxel each, in shared
/// memory: clear() by one thread, a barrier, add() by each (whole warps), a barrier, then get().
struct SharedSurface {
  unsigned octants;  ///< bits 0-7: observed octants; bits 8-15: octants at or behind a surface
  __device__ void clear() { octants = 0; }
  /// Takes in voxel `i` of the block when observed (`weight` > 0) with TSDF `tsdf`. Every lane
  /// of the warp calls it: the warp's octants are or-ed together first (both masks in one word:
  /// one or), and its first lane adds them (one atomic a warp; one a lane, all on the same word,
  /// would wait in turn).
  __device__ void add(int i, int weight, int tsdf) {
    unsigned bits = 0;
    if (weight != 0) {
      const Vec3i q = voxel_coords(i);
      const unsigned seen = voxel_octants(q.x, q.y, q.z);
      bits = tsdf <= 0 ? seen | seen << 8 : seen;
    }
    bits = warp_or(bits);
    if (lane_index() == 0 && bits != 0) atomicOr(&octants, bits);
  }
  __device__ BlockSurface get() const {
    return BlockSurface{static_cast<uint8_t>(octants & 0xFFu), static_cast<uint8_t>(octants >> 8)};
  }
};

}  // namespace hivox::cuda
