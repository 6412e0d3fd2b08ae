#pragma once
// The launch points of every driver loop. An operation's per-element body is written once as a
// function of an index (`HIVOX_HD` where a GPU runs it too); `parallel_for(device, n, body)`
// runs it on the CPU's threads or as a CUDA grid-stride loop, as Open3D's ParallelFor does. CPU
// specialisations that keep per-thread state (caches, ray packets, private lists) run as a
// `ThreadTeam` that shares out loops. No driver writes an OpenMP pragma of its own, and this
// header is private: <omp.h> stays out of the installed headers.

#include <cstdint>
#include <string_view>

#include "hivox/core/device.h"
#include "hivox/core/hd.h"
#include "hivox/core/threads.h"

#if defined(HIVOX_CUDA_CODE)  // (hd.h)
#include <cuda_runtime.h>

#include <type_traits>
#include <utility>
#endif

namespace hivox {

/// How a CPU loop hands out its items: in equal blocks, one per thread (items of equal cost), or
/// in chunks taken as threads come free (items of uneven cost).
struct CpuSchedule {
  int64_t chunk = 0;  ///< 0: static blocks; > 0: dynamic chunks of this many items
  static CpuSchedule dynamic(int64_t chunk) { return {chunk > 0 ? chunk : 1}; }
};

/// Throws `Error(Cuda)`: a launch on `device` failed with `message` (defined in host code: fmt's
/// headers are not for nvcc).
[[noreturn]] void cuda_launch_failed(const Device& device, const char* message);

namespace detail {
int thread_index();  // inside a parallel region: this thread's index in its team
int team_size();     // inside a parallel region: the team's size
/// The calling thread's parallel loops use `n` threads (OpenMP keeps the count per thread: a
/// thread of hivox's own starts with the default, not its creator's set_thread_count).
void use_thread_count(int n);

template <typename Body>
void cpu_for(int64_t n, Body&& body, CpuSchedule schedule) {
  if (schedule.chunk > 0) {
    [[maybe_unused]] const int64_t chunk = schedule.chunk;
#pragma omp parallel for schedule(dynamic, chunk)
    for (int64_t i = 0; i < n; ++i) body(i);
  } else {
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < n; ++i) body(i);
  }
}

#if defined(HIVOX_CUDA_CODE)
template <typename Body>
__global__ void grid_stride_loop(int64_t n, Body body) {
  const int64_t stride = static_cast<int64_t>(blockDim.x) * gridDim.x;
  for (int64_t i = static_cast<int64_t>(blockIdx.x) * blockDim.x + threadIdx.x; i < n; i += stride)
    body(i);
}
#endif
}  // namespace detail

#if defined(HIVOX_CUDA_CODE)
namespace detail {
/// The stream the calling thread's launches go to: the default stream, or a stream that
/// records them into a graph (cuda::LaunchGraph).
inline cudaStream_t& launch_stream() {
  thread_local cudaStream_t stream = nullptr;
  return stream;
}
}  // namespace detail

/// Launches `kernel(args...)` on a grid of `grid` blocks of `block` threads: CUDA's
/// `kernel<<<grid, block, 0, stream>>>(args...)` on the thread's launch stream, written once for
/// nvcc and for the CPU emulation (which runs the grid before it returns, or records it with
/// its arguments while a graph is recorded). Every kernel of the CUDA loop starts here.
template <typename... Params, typename... Args>
void launch(void (*kernel)(Params...), dim3 grid, dim3 block, Args&&... args) {
#if defined(HIVOX_CUDA_EMULATION)
  cuda::emulation::launch_on(detail::launch_stream(), grid, block,
                             [kernel, ... held = std::decay_t<Args>(args)] { kernel(held...); });
#else
  kernel<<<grid, block, 0, detail::launch_stream()>>>(std::forward<Args>(args)...);
#endif
}
#endif

/// Runs `body(i)` for i in [0, n) on `device`. On CUDA (code compiled by nvcc, or for the CPU
/// emulation of CUDA) the body runs on the GPU and must be a `HIVOX_HD` callable holding views by
/// value; `schedule` applies to the CPU only.
template <typename Body>
void parallel_for(const Device& device, int64_t n, const Body& body, CpuSchedule schedule = {}) {
  if (n <= 0) return;
  switch (device.type) {
    case DeviceType::Cpu:
      detail::cpu_for(n, body, schedule);
      return;
    case DeviceType::Cuda:
#if defined(HIVOX_CUDA_CODE)
    {
      constexpr int kThreads = 256;
      const int64_t blocks = (n + kThreads - 1) / kThreads;
      launch(detail::grid_stride_loop<Body>, static_cast<unsigned>(blocks < 65535 ? blocks : 65535),
             kThreads, n, body);
      const cudaError_t e = cudaGetLastError();
      if (e != cudaSuccess) cuda_launch_failed(device, cudaGetErrorString(e));
      return;
    }
#else
      break;
#endif
  }
  no_implementation(device, "parallel_for (this file was not compiled for CUDA)");
}

/// An operation's one dispatch point: runs `cpu()` (the CPU's implementation) when `device` is
/// the CPU. This build has no other implementation (no_implementation names `operation`); the
/// CUDA backend adds its branch here, so that no operation body tests the device itself.
template <typename Cpu>
decltype(auto) dispatch(const Device& device, std::string_view operation, Cpu&& cpu) {
  if (device.is_cpu()) return cpu();
  no_implementation(device, operation);
}

/// `parallel_for` on the CPU: static blocks of items of equal cost.
template <typename Body>
void parallel_for(int64_t n, Body&& body) {
  if (n > 0) detail::cpu_for(n, body, {});
}

/// `parallel_for` on the CPU in dynamic chunks of `chunk` items (uneven costs).
template <typename Body>
void parallel_for_dynamic(int64_t n, int64_t chunk, Body&& body) {
  if (n > 0) detail::cpu_for(n, body, CpuSchedule::dynamic(chunk));
}

/// The threads of one CPU parallel region, as its body sees them: each thread's index, the
/// team's size, and loops whose items the team shares out. Every thread of the team must reach
/// each `for_each`, `single` and `barrier` (they synchronise the team).
class ThreadTeam {
 public:
  int index() const { return index_; }
  int size() const { return size_; }

  /// Runs `body(i)` for i in [0, n), the items shared out among the team; returns when the whole
  /// team is done.
  template <typename Body>
  void for_each(int64_t n, Body&& body, CpuSchedule schedule = {}) const {
    if (schedule.chunk > 0) {
      [[maybe_unused]] const int64_t chunk = schedule.chunk;
#pragma omp for schedule(dynamic, chunk)
      for (int64_t i = 0; i < n; ++i) body(i);
    } else {
#pragma omp for schedule(static)
      for (int64_t i = 0; i < n; ++i) body(i);
    }
  }
  /// This thread's share of the items [0, n) in a static schedule: a contiguous block, blocks in
  /// thread order. For loops that must stay in the calling function rather than in a lambda (a
  /// loop reading the caller's locals through a closure may not vectorize). No synchronisation.
  struct Share {
    int64_t begin = 0, end = 0;
  };
  Share static_share(int64_t n) const {
    const int64_t per = n / size_, extra = n % size_;
    const int64_t begin = index_ * per + (index_ < extra ? index_ : extra);
    return {begin, begin + per + (index_ < extra ? 1 : 0)};
  }
  /// Runs `body()` on one thread of the team; the others wait for it.
  template <typename Body>
  void single(Body&& body) const {
#pragma omp single
    body();
  }
  /// Waits until every thread of the team got here.
  void barrier() const;

 private:
  template <typename Body>
  friend void parallel_team(Body&& body);
  ThreadTeam(int index, int size) : index_(index), size_(size) {}
  int index_ = 0, size_ = 1;
};

/// Runs `body(team)` once on each of the CPU's threads (thread_count() of them, or fewer); for
/// CPU specialisations that keep state per thread.
template <typename Body>
void parallel_team(Body&& body) {
#pragma omp parallel
  {
    const ThreadTeam team(detail::thread_index(), detail::team_size());
    body(team);
  }
}

}  // namespace hivox
