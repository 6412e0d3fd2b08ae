// The CPU emulation of CUDA (src/cuda/emulation) on kernels whose results are known by hand:
// barriers, shared memory, warp operations, atomics, the queue of copies, the schedules, the
// launch errors a GPU gives, and the misuses it stops with a message. Built only with
// -DHIVOX_CUDA_EMULATION=ON.

#include <cuda.h>
#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include <sys/mman.h>

#include "core/parallel.h"

namespace hivox::test {
namespace {

template <typename T>
T* device_array(std::size_t n) {
  T* p = nullptr;
  EXPECT_EQ(cudaMalloc(&p, n * sizeof(T)), cudaSuccess);
  return p;
}

template <typename T>
std::vector<T> download(const T* p, std::size_t n) {
  std::vector<T> host(n);
  EXPECT_EQ(cudaMemcpy(host.data(), p, n * sizeof(T), cudaMemcpyDeviceToHost), cudaSuccess);
  return host;
}

/// Sets environment variable `name` to `value` (null: unsets it) for its lifetime, then restores
/// what it held.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    set(value);
  }
  ~ScopedEnv() { set(old_ ? old_->c_str() : nullptr); }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  void set(const char* value) {
    if (value != nullptr)
      setenv(name_, value, 1);
    else
      unsetenv(name_);
  }
  const char* name_;
  std::optional<std::string> old_;
};

/// Each block sums its threads' values through shared memory: a tree with a barrier per step.
__global__ void block_sums(const int* in, int* out) {
  __shared__ int s[256];
  const unsigned t = threadIdx.x;
  s[t] = in[blockIdx.x * blockDim.x + t];
  __syncthreads();
  for (unsigned half = blockDim.x / 2; half > 0; half /= 2) {
    if (t < half) s[t] += s[t + half];
    __syncthreads();
  }
  if (t == 0) out[blockIdx.x] = s[0];
}

TEST(CudaEmulation, BarriersOrderASharedMemoryTreeSum) {
  constexpr int kBlocks = 7, kThreads = 256;
  std::vector<int> values(kBlocks * kThreads);
  std::iota(values.begin(), values.end(), 1);
  int* in = device_array<int>(values.size());
  int* out = device_array<int>(kBlocks);
  ASSERT_EQ(cudaMemcpy(in, values.data(), values.size() * sizeof(int), cudaMemcpyHostToDevice),
            cudaSuccess);
  launch(block_sums, kBlocks, kThreads, in, out);
  ASSERT_EQ(cudaGetLastError(), cudaSuccess);
  const std::vector<int> sums = download(out, kBlocks);
  for (int b = 0; b < kBlocks; ++b) {
    const int first = b * kThreads + 1, last = first + kThreads - 1;
    EXPECT_EQ(sums[b], (first + last) * kThreads / 2) << "block " << b;
  }
  cudaFree(in);
  cudaFree(out);
}

/// Per thread: the warp's sum of lane numbers by shuffles down and by a butterfly of xor
/// shuffles, lane 5's value broadcast, the ballot of the even lanes, and a slot taken with one
/// atomic per thread.
__global__ void warp_ops(int* sums, int* butterfly, int* broadcast, unsigned* ballots,
                         unsigned* ors, int* counter, int* slots) {
  const int lane = static_cast<int>(threadIdx.x & 31u);
  int x = lane, y = lane;
  for (int o = 16; o > 0; o >>= 1) {
    x += __shfl_down_sync(0xFFFFFFFFu, x, o);
    y += __shfl_xor_sync(0xFFFFFFFFu, y, o);
  }
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  sums[i] = x;
  butterfly[i] = y;
  broadcast[i] = __shfl_sync(0xFFFFFFFFu, lane * 10, 5);
  ballots[i] = __ballot_sync(0xFFFFFFFFu, lane % 2 == 0);
  ors[i] = __reduce_or_sync(0xFFFFFFFFu, lane % 3 == 0 ? 1u << (lane / 3) : 0u);
  slots[atomicAdd(counter, 1)] = i;
}

TEST(CudaEmulation, WarpOperationsGiveTheLanesTheirValues) {
  constexpr int kBlocks = 3, kThreads = 128, kN = kBlocks * kThreads;
  int* sums = device_array<int>(kN);
  int* butterfly = device_array<int>(kN);
  int* broadcast = device_array<int>(kN);
  unsigned* ballots = device_array<unsigned>(kN);
  unsigned* ors = device_array<unsigned>(kN);
  int* counter = device_array<int>(1);
  int* slots = device_array<int>(kN);
  ASSERT_EQ(cudaMemset(counter, 0, sizeof(int)), cudaSuccess);
  launch(warp_ops, kBlocks, kThreads, sums, butterfly, broadcast, ballots, ors, counter, slots);
  ASSERT_EQ(cudaGetLastError(), cudaSuccess);
  const std::vector<int> s = download(sums, kN), x = download(butterfly, kN),
                         b = download(broadcast, kN);
  const std::vector<unsigned> v = download(ballots, kN), o = download(ors, kN);
  std::vector<int> taken = download(slots, kN);
  for (int i = 0; i < kN; ++i) {
    // Lane 0 holds the whole warp's sum 0 + 1 + ... + 31; lane l the sum of a shrinking tree.
    if (i % 32 == 0) {
      EXPECT_EQ(s[i], 496) << "thread " << i;
    }
    EXPECT_EQ(x[i], 496) << "thread " << i;  // the butterfly gives every lane the sum
    EXPECT_EQ(b[i], 50) << "thread " << i;
    EXPECT_EQ(v[i], 0x55555555u) << "thread " << i;
    EXPECT_EQ(o[i], 0x7FFu) << "thread " << i;  // lanes 0, 3, ..., 30 set bits 0 to 10
  }
  EXPECT_EQ(download(counter, 1)[0], kN);
  std::sort(taken.begin(), taken.end());
  for (int i = 0; i < kN; ++i) ASSERT_EQ(taken[i], i);  // every slot once
  for (void* p : {static_cast<void*>(sums), static_cast<void*>(butterfly),
                  static_cast<void*>(broadcast), static_cast<void*>(ballots),
                  static_cast<void*>(ors), static_cast<void*>(counter), static_cast<void*>(slots)})
    cudaFree(p);
}

__global__ void nothing() {}

TEST(CudaEmulation, ALaunchAGpuRefusesSetsTheLastError) {
  launch(nothing, 0, 32);
  EXPECT_EQ(cudaGetLastError(), cudaErrorInvalidConfiguration);
  launch(nothing, 1, 2048);
  EXPECT_EQ(cudaGetLastError(), cudaErrorInvalidConfiguration);
  launch(nothing, 1, 1024);
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);
}

/// Lane 31 leaves before the warp's shuffle that names it.
__global__ void shuffle_without_lane_31(int* out) {
  if (threadIdx.x == 31) return;
  out[threadIdx.x] = __shfl_sync(0xFFFFFFFFu, 1, 0);
}

/// Lanes 0-15 shuffle among themselves, reading lane 20.
__global__ void shuffle_outside_mask(int* out) {
  if (threadIdx.x < 16)
    out[threadIdx.x] = __shfl_sync(0x0000FFFFu, static_cast<int>(threadIdx.x), 20);
}

/// Every lane names lane 0 alone.
__global__ void mask_without_own_lane(int* out) {
  out[threadIdx.x] = __shfl_sync(0x1u, static_cast<int>(threadIdx.x), 0);
}

TEST(CudaEmulationDeathTest, MisusesAGpuLeavesUndefinedStopWithTheirPlace) {
  // The threads named are the first to get there in the default schedule (the kernels run when
  // launched, as the default stream's work does unless held back).
  const ScopedEnv in_order("HIVOX_EMULATION_SCHEDULE", "in-order");
  const ScopedEnv early("HIVOX_EMULATION_STREAMS", nullptr);
  int* out = device_array<int>(32);
  EXPECT_DEATH(launch(shuffle_without_lane_31, 1, 32, out),
               "block \\(0,0,0\\) of 32 threads cannot go on: 1 finished");
  EXPECT_DEATH(launch(shuffle_outside_mask, 1, 32, out), "reads lane 20, outside the mask");
  EXPECT_DEATH(launch(mask_without_own_lane, 1, 32, out), "thread 1: .* leaves out its own lane");
  int host[4] = {};
  EXPECT_DEATH(cudaMemcpy(host, host + 2, sizeof(int), cudaMemcpyDeviceToHost),
               "reads from .*, outside device memory");
  EXPECT_DEATH(cudaMemcpy(out, out, sizeof(int), cudaMemcpyHostToDevice),
               "host-to-device reads from device memory");
  // A clear outside device memory stops the program where it is given, also held back.
  EXPECT_DEATH(cudaMemset(host, 0, sizeof(int)), "cudaMemset of 4 bytes at .*, outside device");
  {
    const ScopedEnv late("HIVOX_EMULATION_STREAMS", "default-late");
    EXPECT_DEATH(cudaMemset(host, 0, sizeof(int)), "cudaMemset of 4 bytes at .*, outside device");
  }
  cudaFree(out);
}

/// New device memory holds what HIVOX_EMULATION_FILL says: 0xA5 by default, a byte, or bytes of
/// each allocation's own; a value that is neither stops the program with the variable's name.
TEST(CudaEmulationDeathTest, NewMemoryHoldsTheFillAsked) {
  constexpr std::size_t kBytes = 1000;
  const auto filled = [&](const char* fill) {
    const ScopedEnv asked("HIVOX_EMULATION_FILL", fill);
    unsigned char* p = device_array<unsigned char>(kBytes);
    std::vector<unsigned char> host = download(p, kBytes);
    cudaFree(p);
    return host;
  };
  const auto all = [](const std::vector<unsigned char>& v, int byte) {
    return std::all_of(v.begin(), v.end(), [&](unsigned char b) { return b == byte; });
  };
  EXPECT_TRUE(all(filled(nullptr), 0xA5));
  EXPECT_TRUE(all(filled("7"), 7));
  EXPECT_TRUE(all(filled("0xff"), 0xFF));
  const std::vector<unsigned char> a = filled("random"), b = filled("random");
  EXPECT_NE(a, b);
  // Bytes of every value, none of them a run: at least 200 distinct 0-255 values in 1000 bytes.
  std::vector<bool> seen(256);
  for (const unsigned char x : a) seen[x] = true;
  EXPECT_GT(std::count(seen.begin(), seen.end(), true), 200);
  EXPECT_DEATH(filled("256"), "HIVOX_EMULATION_FILL=256 is neither a byte");
  // Left as it is and marked undefined for valgrind's memcheck (which a run under valgrind then
  // reports where it is used); without valgrind's headers at build time, refused.
#if __has_include(<valgrind/memcheck.h>)
  EXPECT_EQ(filled("undefined").size(), kBytes);
#else
  EXPECT_DEATH(filled("undefined"), "needs valgrind's headers");
#endif
}

/// Each thread takes the next slot for its index (the threads' order through the atomic), then
/// adds one to `counter` without an atomic but with an atomic between its read and its write: a
/// race that loses updates whenever another thread runs in between.
__global__ void order_and_race(int* next, int* slots, int* counter, int* calls) {
  slots[atomicAdd(next, 1)] = static_cast<int>(threadIdx.x);
  const int v = *counter;
  atomicAdd(calls, 1);
  *counter = v + 1;
}

/// HIVOX_EMULATION_SCHEDULE orders a block's threads: in index order by default, from the last
/// with `reverse`, drawn with `random` (each launch its own order); the last two switch threads at
/// atomics, so the race above loses updates there and not in index order (with `reverse` all
/// but one: every thread reads before any writes).
TEST(CudaEmulationDeathTest, TheScheduleOrdersThreadsAndSwitchesThemAtAtomics) {
  constexpr int kThreads = 64;
  struct Outcome {
    std::vector<int> slots;
    int counter = 0, calls = 0;
  };
  const auto run = [&](const char* schedule) {
    const ScopedEnv asked("HIVOX_EMULATION_SCHEDULE", schedule);
    int* ints = device_array<int>(3 + kThreads);
    EXPECT_EQ(cudaMemset(ints, 0, 3 * sizeof(int)), cudaSuccess);
    launch(order_and_race, 1, kThreads, ints, ints + 3, ints + 1, ints + 2);
    EXPECT_EQ(cudaGetLastError(), cudaSuccess);
    const std::vector<int> all = download(ints, 3 + kThreads);
    cudaFree(ints);
    return Outcome{std::vector<int>(all.begin() + 3, all.end()), all[1], all[2]};
  };
  std::vector<int> in_order(kThreads);
  std::iota(in_order.begin(), in_order.end(), 0);
  for (const char* schedule : {static_cast<const char*>(nullptr), "in-order"}) {
    const Outcome o = run(schedule);
    EXPECT_EQ(o.slots, in_order);
    EXPECT_EQ(o.counter, kThreads);  // one thread after another: no update lost
  }
  const Outcome reverse = run("reverse");
  EXPECT_EQ(reverse.slots.front(), kThreads - 1);
  EXPECT_EQ(reverse.counter, 1);
  const Outcome a = run("random:7"), c = run("random");
  EXPECT_NE(a.slots, c.slots);
  EXPECT_NE(a.slots, in_order);
  EXPECT_LT(a.counter, kThreads);
  for (const Outcome& o : {reverse, a, c}) {
    EXPECT_EQ(o.calls, kThreads);  // the atomics themselves lose nothing
    std::vector<int> sorted = o.slots;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(sorted, in_order);
  }
  EXPECT_DEATH(run("sideways"), "HIVOX_EMULATION_SCHEDULE=sideways is none of");
  EXPECT_DEATH(run("random:x"), "HIVOX_EMULATION_SCHEDULE=random:x is none of");
}

/// Writes `value` to `*out`.
__global__ void store(int* out, int value) {
  *out = value;
}

/// *out = *in.
__global__ void copy_one(const int* in, int* out) {
  *out = *in;
}

/// Copies with page-locked host memory are left to the device's queue, as on a GPU: a download
/// reaches the host only at a synchronisation that waits for it (until then its host side holds
/// the fill), with the device's bytes of when it was queued (on a stream: at that stream's
/// synchronisation); an upload reads its host side when the device gets to it. Copies with
/// pageable memory are done when they return.
TEST(CudaEmulation, CopiesWithPageLockedMemoryFinishAtASynchronisation) {
  const ScopedEnv fill("HIVOX_EMULATION_FILL", nullptr);      // 0xA5 bytes
  const ScopedEnv early("HIVOX_EMULATION_STREAMS", nullptr);  // no stream's work held back
  constexpr int kFill = static_cast<int>(0xA5A5A5A5u);
  int* dev = device_array<int>(2);
  int* host = nullptr;
  ASSERT_EQ(cudaMallocHost(reinterpret_cast<void**>(&host), 2 * sizeof(int)), cudaSuccess);
  cudaEvent_t before = nullptr, after = nullptr;
  ASSERT_EQ(cudaEventCreate(&before), cudaSuccess);
  ASSERT_EQ(cudaEventCreate(&after), cudaSuccess);

  launch(store, 1, 1, dev, 42);
  ASSERT_EQ(cudaEventRecord(before, nullptr), cudaSuccess);
  ASSERT_EQ(cudaMemcpyAsync(host, dev, sizeof(int), cudaMemcpyDeviceToHost, nullptr), cudaSuccess);
  ASSERT_EQ(cudaEventRecord(after, nullptr), cudaSuccess);
  launch(store, 1, 1, dev, 7);  // after the download: not in it
  EXPECT_EQ(host[0], kFill);
  ASSERT_EQ(cudaEventSynchronize(before), cudaSuccess);
  EXPECT_EQ(host[0], kFill);  // the event came before the copy
  ASSERT_EQ(cudaEventSynchronize(after), cudaSuccess);
  EXPECT_EQ(host[0], 42);

  // cudaDeviceSynchronize and a blocking copy wait for every download.
  ASSERT_EQ(cudaMemcpyAsync(host, dev, sizeof(int), cudaMemcpyDeviceToHost, nullptr), cudaSuccess);
  EXPECT_EQ(host[0], kFill);
  ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
  EXPECT_EQ(host[0], 7);
  launch(store, 1, 1, dev, 8);
  ASSERT_EQ(cudaMemcpyAsync(host, dev, sizeof(int), cudaMemcpyDeviceToHost, nullptr), cudaSuccess);
  int pageable = 0;
  ASSERT_EQ(cudaMemcpy(&pageable, dev + 1, sizeof(int), cudaMemcpyDeviceToHost), cudaSuccess);
  EXPECT_EQ(host[0], 8);

  // A download on a stream reaches the host when that stream is synchronised, not another.
  cudaStream_t side = nullptr;
  ASSERT_EQ(cudaStreamCreateWithFlags(&side, cudaStreamNonBlocking), cudaSuccess);
  launch(store, 1, 1, dev, 9);
  ASSERT_EQ(cudaMemcpyAsync(host, dev, sizeof(int), cudaMemcpyDeviceToHost, side), cudaSuccess);
  ASSERT_EQ(cudaStreamSynchronize(nullptr), cudaSuccess);
  EXPECT_EQ(host[0], kFill);
  ASSERT_EQ(cudaMemcpy(&pageable, dev + 1, sizeof(int), cudaMemcpyDeviceToHost), cudaSuccess);
  EXPECT_EQ(host[0], kFill);  // a blocking copy waits for the default stream alone
  ASSERT_EQ(cudaStreamWaitEvent(side, after), cudaSuccess);
  ASSERT_EQ(cudaStreamSynchronize(side), cudaSuccess);
  EXPECT_EQ(host[0], 9);
  ASSERT_EQ(cudaStreamDestroy(side), cudaSuccess);

  // An upload reads the host when the next kernel comes: a host write before that is uploaded.
  host[1] = 1;
  ASSERT_EQ(cudaMemcpyAsync(dev, host + 1, sizeof(int), cudaMemcpyHostToDevice, nullptr),
            cudaSuccess);
  host[1] = 2;
  launch(copy_one, 1, 1, dev, dev + 1);
  host[1] = 3;  // too late
  ASSERT_EQ(cudaMemcpy(&pageable, dev + 1, sizeof(int), cudaMemcpyDeviceToHost), cudaSuccess);
  EXPECT_EQ(pageable, 2);

  // With pageable memory the copy is done at once, either way.
  pageable = 5;
  ASSERT_EQ(cudaMemcpyAsync(dev, &pageable, sizeof(int), cudaMemcpyHostToDevice, nullptr),
            cudaSuccess);
  pageable = 0;
  ASSERT_EQ(cudaMemcpyAsync(&pageable, dev, sizeof(int), cudaMemcpyDeviceToHost, nullptr),
            cudaSuccess);
  EXPECT_EQ(pageable, 5);

  cudaEventDestroy(before);
  cudaEventDestroy(after);
  EXPECT_EQ(cudaFreeHost(host), cudaSuccess);
  EXPECT_EQ(cudaFreeHost(host), cudaErrorInvalidValue);  // not page-locked memory any more
  cudaGetLastError();
  cudaFree(dev);
}

/// While it lives, the launches go to `stream` (then to the default stream again).
struct LaunchesOnStream {
  explicit LaunchesOnStream(cudaStream_t stream) { detail::launch_stream() = stream; }
  ~LaunchesOnStream() { detail::launch_stream() = nullptr; }
  LaunchesOnStream(const LaunchesOnStream&) = delete;
  LaunchesOnStream& operator=(const LaunchesOnStream&) = delete;
};

/// A device int, a stream of the program's own beside the default stream, an event, and the two
/// ways to read the int back: a blocking copy (waits for the default stream) and a pageable copy
/// on the side stream (waits for that stream alone).
struct SideStream {
  int* dev = device_array<int>(2);
  cudaStream_t side = nullptr;
  cudaEvent_t done = nullptr;
  SideStream() {
    EXPECT_EQ(cudaStreamCreateWithFlags(&side, cudaStreamNonBlocking), cudaSuccess);
    EXPECT_EQ(cudaEventCreate(&done), cudaSuccess);
  }
  ~SideStream() {
    cudaEventDestroy(done);
    EXPECT_EQ(cudaStreamDestroy(side), cudaSuccess);
    cudaFree(dev);
  }
  SideStream(const SideStream&) = delete;
  SideStream& operator=(const SideStream&) = delete;
  int read() const {
    int v = 0;
    EXPECT_EQ(cudaMemcpy(&v, dev, sizeof(int), cudaMemcpyDeviceToHost), cudaSuccess);
    return v;
  }
  int read_beside() const {
    int v = 0;
    EXPECT_EQ(cudaMemcpyAsync(&v, dev, sizeof(int), cudaMemcpyDeviceToHost, side), cudaSuccess);
    return v;
  }
};

/// HIVOX_EMULATION_STREAMS=late: what a stream of the program's own is given (kernels, clears,
/// copies, event marks) waits until something waits for it, as a GPU may leave it; the default
/// stream's work runs when it is given. Early (the default), it runs at once.
TEST(CudaEmulation, LateStreamsHoldTheirWorkUntilWaitedFor) {
  const ScopedEnv early("HIVOX_EMULATION_STREAMS", nullptr);
  SideStream s;
  int* host = nullptr;
  ASSERT_EQ(cudaMallocHost(reinterpret_cast<void**>(&host), sizeof(int)), cudaSuccess);
  launch(store, 1, 1, s.dev, 1);
  {
    const ScopedEnv late("HIVOX_EMULATION_STREAMS", "late");
    // A kernel and a mark on the side stream: held until the default stream waits for the mark.
    const LaunchesOnStream on(s.side);
    launch(store, 1, 1, s.dev, 2);
    ASSERT_EQ(cudaEventRecord(s.done, s.side), cudaSuccess);
    EXPECT_EQ(s.read(), 1) << "a blocking copy waits for the default stream alone";
    ASSERT_EQ(cudaStreamWaitEvent(nullptr, s.done), cudaSuccess);
    EXPECT_EQ(s.read(), 2);
    // A clear and a download: held until the stream is synchronised.
    ASSERT_EQ(cudaMemsetAsync(s.dev, 0, sizeof(int), s.side), cudaSuccess);
    ASSERT_EQ(cudaMemcpyAsync(host, s.dev, sizeof(int), cudaMemcpyDeviceToHost, s.side),
              cudaSuccess);
    EXPECT_EQ(s.read(), 2);
    ASSERT_EQ(cudaStreamSynchronize(s.side), cudaSuccess);
    EXPECT_EQ(s.read(), 0);
    EXPECT_EQ(host[0], 0);
    // The device's synchronisation runs what every stream holds.
    launch(store, 1, 1, s.dev, 3);
    EXPECT_EQ(s.read(), 0);
    ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
    EXPECT_EQ(s.read(), 3);
  }
  {
    const LaunchesOnStream on(s.side);
    launch(store, 1, 1, s.dev, 4);
    EXPECT_EQ(s.read(), 4);
  }
  EXPECT_EQ(cudaFreeHost(host), cudaSuccess);
}

/// HIVOX_EMULATION_STREAMS=default-late: the default stream's work (kernels, clears, copies,
/// event marks) waits until something waits for it, while a stream of the program's own runs
/// what it is given at once: a stream that reads the default stream's results, or writes what
/// its work reads, without waiting for it shows.
TEST(CudaEmulation, TheDefaultStreamsWorkCanComeLate) {
  const ScopedEnv early("HIVOX_EMULATION_STREAMS", nullptr);
  SideStream s;
  launch(store, 1, 1, s.dev, 7);
  const ScopedEnv late("HIVOX_EMULATION_STREAMS", "default-late");
  launch(store, 1, 1, s.dev, 1);
  EXPECT_EQ(s.read_beside(), 7) << "a stream of its own does not wait for the default stream";
  ASSERT_EQ(cudaEventRecord(s.done, nullptr), cudaSuccess);
  ASSERT_EQ(cudaStreamWaitEvent(s.side, s.done), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 1);
  // A stream of its own writes at once, under the default stream's work held back.
  launch(store, 1, 1, s.dev, 2);
  {
    const LaunchesOnStream on(s.side);
    launch(store, 1, 1, s.dev, 3);
  }
  EXPECT_EQ(s.read_beside(), 3);
  EXPECT_EQ(s.read(), 2) << "a blocking copy waits for the default stream's work";
  // A clear, and the synchronisations of the default stream, of an event on it, of the device.
  ASSERT_EQ(cudaMemset(s.dev, 0, sizeof(int)), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 2);
  ASSERT_EQ(cudaStreamSynchronize(nullptr), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 0);
  launch(store, 1, 1, s.dev, 4);
  ASSERT_EQ(cudaEventRecord(s.done, nullptr), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 0);
  ASSERT_EQ(cudaEventSynchronize(s.done), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 4);
  launch(store, 1, 1, s.dev, 5);
  ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 5);
  // A configuration a GPU refuses fails at its launch, though the kernel would come late.
  launch(store, 0, 1, s.dev, 6);
  EXPECT_EQ(cudaGetLastError(), cudaErrorInvalidConfiguration);
  ASSERT_EQ(cudaDeviceSynchronize(), cudaSuccess);
  EXPECT_EQ(s.read_beside(), 5);
}

/// The emulated driver function `name`, as the loop fetches it (src/cuda/device_memory.cpp).
template <typename F>
F entry(const char* name) {
  void* p = nullptr;
  cudaDriverEntryPointQueryResult status{};
  EXPECT_EQ(cudaGetDriverEntryPointByVersion(name, &p, 12000, cudaEnableDefault, &status),
            cudaSuccess);
  EXPECT_EQ(status, cudaDriverEntryPointSuccess) << name;
  return reinterpret_cast<F>(p);
}

TEST(CudaEmulationDeathTest, VirtualMemoryIsOpenOnlyWhereCommittedAndOpened) {
  const auto reserve = entry<decltype(&cuMemAddressReserve)>("cuMemAddressReserve");
  const auto create = entry<decltype(&cuMemCreate)>("cuMemCreate");
  const auto map = entry<decltype(&cuMemMap)>("cuMemMap");
  const auto set_access = entry<decltype(&cuMemSetAccess)>("cuMemSetAccess");
  const auto granularity =
      entry<decltype(&cuMemGetAllocationGranularity)>("cuMemGetAllocationGranularity");
  CUmemAllocationProp prop{};
  prop.type = CU_MEM_ALLOCATION_TYPE_PINNED;
  prop.location.type = CU_MEM_LOCATION_TYPE_DEVICE;
  std::size_t chunk = 0;
  ASSERT_EQ(granularity(&chunk, &prop, CU_MEM_ALLOC_GRANULARITY_RECOMMENDED), CUDA_SUCCESS);
  CUdeviceptr base = 0;
  ASSERT_EQ(reserve(&base, 4 * chunk, 0, 0, 0), CUDA_SUCCESS);
  CUmemGenericAllocationHandle h = 0;
  ASSERT_EQ(create(&h, chunk, &prop, 0), CUDA_SUCCESS);
  ASSERT_EQ(map(base, chunk, 0, h, 0), CUDA_SUCCESS);
  char* bytes = reinterpret_cast<char*>(base);
  EXPECT_DEATH(bytes[0] = 1, "");  // mapped, not yet opened
  CUmemAccessDesc access{};
  access.location = prop.location;
  access.flags = CU_MEM_ACCESS_FLAGS_PROT_READWRITE;
  ASSERT_EQ(set_access(base, chunk, &access, 1), CUDA_SUCCESS);
  bytes[0] = 1;
  bytes[chunk - 1] = 2;
  EXPECT_EQ(bytes[0] + bytes[chunk - 1], 3);
  EXPECT_DEATH(bytes[chunk] = 1, "");  // reserved, not committed
  const auto unmap = entry<decltype(&cuMemUnmap)>("cuMemUnmap");
  const auto release = entry<decltype(&cuMemRelease)>("cuMemRelease");
  const auto free = entry<decltype(&cuMemAddressFree)>("cuMemAddressFree");
  EXPECT_EQ(unmap(base, chunk), CUDA_SUCCESS);
  EXPECT_EQ(release(h), CUDA_SUCCESS);
  EXPECT_EQ(free(base, 4 * chunk), CUDA_SUCCESS);

  // Reserved addresses are aligned to the granularity, as a GPU's are, wherever the host's
  // mappings lie: here after odd-sized mappings of the host's own.
  std::vector<std::pair<void*, std::size_t>> odd;
  for (int k = 1; k <= 3; ++k) {
    const std::size_t bytes = static_cast<std::size_t>(k) * 4096 * 3;
    odd.push_back({mmap(nullptr, bytes, PROT_READ, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0), bytes});
    ASSERT_NE(odd.back().first, MAP_FAILED);
    CUdeviceptr at = 0;
    ASSERT_EQ(reserve(&at, static_cast<std::size_t>(k) * chunk, 0, 0, 0), CUDA_SUCCESS);
    EXPECT_EQ(at % chunk, 0u) << "reservation " << k << " at " << at;
    EXPECT_EQ(free(at, static_cast<std::size_t>(k) * chunk), CUDA_SUCCESS);
  }
  for (const auto& [p, bytes] : odd) munmap(p, bytes);
}

}  // namespace
}  // namespace hivox::test
