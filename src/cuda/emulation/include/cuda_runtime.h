#pragma once
/// @file
/// CUDA's device-side language, emulated on the CPU for the CUDA loop's code (compiled by the
/// host compiler with -DHIVOX_CUDA_EMULATION; src/cuda/emulation/README.md): the qualifiers,
/// the built-in indices, __syncthreads, the warp operations and the atomics the kernels use.
/// A grid's blocks run on the host's threads; a block's threads run as fibers that switch at
/// __syncthreads and warp operations, so that these wait for the threads they name as on a GPU,
/// and under HIVOX_EMULATION_SCHEDULE=reverse or random at atomics and fences too. A thread that
/// waits for a thread that cannot come (one that has exited, a lane outside the block) stops the
/// program with a message naming the kernel's block and thread.

#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <functional>
#include <type_traits>

#include "cuda_runtime_api.h"

#define __global__
#define __device__
#define __host__
#define __grid_constant__
#define __launch_bounds__(...)
/// Shared memory is the block's: its threads are fibers of one host thread, which runs one
/// block at a time.
#define __shared__ static thread_local

// The running thread's indices (set by the emulator before it runs or resumes a thread).
extern thread_local uint3 threadIdx;
extern thread_local uint3 blockIdx;
extern thread_local uint3 blockDim;
extern thread_local uint3 gridDim;

namespace hivox::cuda::emulation {

/// Runs `thread` for every thread of a grid of `grid` blocks of `block` threads on `stream`, with
/// the built-in indices set: now (returning when all have finished), held back with the stream's
/// work (HIVOX_EMULATION_STREAMS), or recorded into the stream's graph while it captures
/// (`thread` holds the kernel's arguments by value). A configuration a GPU refuses (no blocks,
/// more than 1024 threads a block) sets the last error instead, as a launch would (a captured
/// launch's when the graph is launched).
void launch_on(cudaStream_t stream, dim3 grid, dim3 block, std::function<void()> thread);

enum class WarpOp : uint8_t { Shuffle, ShuffleDown, ShuffleXor, Ballot, ReduceOr };

/// A warp operation of the running thread: waits until every lane of `mask` is in it, then
/// returns this lane's result (the value of lane `arg`, of lane + `arg`, of lane ^ `arg`, the
/// ballot, or the bitwise or of the lanes' values).
uint64_t warp_op(WarpOp op, unsigned mask, uint64_t value, unsigned arg);

/// This thread's lane in its warp.
unsigned lane();

/// Called by every atomic and fence before it acts: under the Reverse and Random schedules
/// (HIVOX_EMULATION_SCHEDULE) the thread may let other threads of its block run first.
void at_atomic();

template <typename T>
uint64_t to_bits(T v) {
  static_assert(sizeof(T) <= 8 && std::is_trivially_copyable_v<T>);
  uint64_t bits = 0;
  std::memcpy(&bits, &v, sizeof(T));
  return bits;
}
template <typename T>
T from_bits(uint64_t bits) {
  T v;
  std::memcpy(&v, &bits, sizeof(T));
  return v;
}

/// warp_op for a value of any type up to 8 bytes.
template <typename T>
T shuffle(WarpOp op, unsigned mask, T value, unsigned arg) {
  return from_bits<T>(warp_op(op, mask, to_bits(value), arg));
}

/// Stores `v` at `p` while `keeps(v, *p)`; returns the value held before (the atomic minimum
/// and maximum).
template <typename T, typename Keeps>
T atomic_keep(T* p, T v, Keeps keeps) {
  at_atomic();
  std::atomic_ref<T> a(*p);
  T old = a.load(std::memory_order_relaxed);
  while (keeps(v, old) && !a.compare_exchange_weak(old, v, std::memory_order_relaxed)) {
  }
  return old;
}

}  // namespace hivox::cuda::emulation

void __syncthreads();
inline void __threadfence() {
  hivox::cuda::emulation::at_atomic();
  __atomic_thread_fence(__ATOMIC_SEQ_CST);
}

/// The lanes that run this instruction together: on a GPU with independent thread scheduling
/// any set that holds the caller; here the caller alone (its fellows may be elsewhere).
inline unsigned __activemask() {
  return 1u << hivox::cuda::emulation::lane();
}
inline unsigned __ballot_sync(unsigned mask, int predicate) {
  return static_cast<unsigned>(hivox::cuda::emulation::warp_op(
      hivox::cuda::emulation::WarpOp::Ballot, mask, predicate != 0 ? 1 : 0, 0));
}
/// The bitwise or of `value` over the lanes of `mask` (compute capability 8.0 and later): one
/// warp operation, as on such a GPU, where a loop of shuffles would take five.
inline unsigned __reduce_or_sync(unsigned mask, unsigned value) {
  return static_cast<unsigned>(
      hivox::cuda::emulation::warp_op(hivox::cuda::emulation::WarpOp::ReduceOr, mask, value, 0));
}
// Shuffles over whole warps (`width` 32, the only one the loop uses).
template <typename T>
T __shfl_sync(unsigned mask, T value, int src_lane, int = 32) {
  return hivox::cuda::emulation::shuffle(hivox::cuda::emulation::WarpOp::Shuffle, mask, value,
                                         static_cast<unsigned>(src_lane) & 31u);
}
template <typename T>
T __shfl_down_sync(unsigned mask, T value, unsigned delta, int = 32) {
  return hivox::cuda::emulation::shuffle(hivox::cuda::emulation::WarpOp::ShuffleDown, mask, value,
                                         delta);
}
template <typename T>
T __shfl_xor_sync(unsigned mask, T value, int lane_mask, int = 32) {
  return hivox::cuda::emulation::shuffle(hivox::cuda::emulation::WarpOp::ShuffleXor, mask, value,
                                         static_cast<unsigned>(lane_mask) & 31u);
}

inline int __popc(unsigned x) {
  return __builtin_popcount(x);
}
inline int __ffs(int x) {
  return __builtin_ffs(x);
}
inline float __uint_as_float(unsigned x) {
  return std::bit_cast<float>(x);
}
inline unsigned __float_as_uint(float x) {
  return std::bit_cast<unsigned>(x);
}
template <typename T>
T __ldcg(const T* p) {
  return *p;
}

// CUDA's atomics are relaxed.
template <typename T>
T atomicAdd(T* p, std::type_identity_t<T> v) {
  hivox::cuda::emulation::at_atomic();
  return std::atomic_ref<T>(*p).fetch_add(v, std::memory_order_relaxed);
}
template <typename T>
T atomicOr(T* p, std::type_identity_t<T> v) {
  hivox::cuda::emulation::at_atomic();
  return std::atomic_ref<T>(*p).fetch_or(v, std::memory_order_relaxed);
}
template <typename T>
T atomicExch(T* p, std::type_identity_t<T> v) {
  hivox::cuda::emulation::at_atomic();
  return std::atomic_ref<T>(*p).exchange(v, std::memory_order_relaxed);
}
template <typename T>
T atomicCAS(T* p, std::type_identity_t<T> expected, std::type_identity_t<T> desired) {
  hivox::cuda::emulation::at_atomic();
  std::atomic_ref<T>(*p).compare_exchange_strong(expected, desired, std::memory_order_relaxed);
  return expected;  // on failure compare_exchange wrote the value held here
}
template <typename T>
T atomicMin(T* p, std::type_identity_t<T> v) {
  return hivox::cuda::emulation::atomic_keep(p, v, std::less<T>());
}
template <typename T>
T atomicMax(T* p, std::type_identity_t<T> v) {
  return hivox::cuda::emulation::atomic_keep(p, v, std::greater<T>());
}
