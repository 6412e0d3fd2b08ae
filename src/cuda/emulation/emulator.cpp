// The CPU emulation of the CUDA the loop uses (README.md in this folder): grids over the host's
// threads, a block's threads as fibers, device memory as tracked host memory, the driver's
// virtual memory as reserved host addresses.

#include <omp.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/context/fiber.hpp>
#include <boost/context/stack_context.hpp>
#include <chrono>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <string_view>
#include <vector>

// Under valgrind's memcheck: fiber stacks made known, new device memory undefined on request
// (the macros do nothing outside valgrind).
#if __has_include(<valgrind/memcheck.h>)
#include <valgrind/memcheck.h>
#define HIVOX_WITH_VALGRIND 1
#else
#define HIVOX_WITH_VALGRIND 0
#define VALGRIND_STACK_REGISTER(low, high) 0
#define VALGRIND_MAKE_MEM_UNDEFINED(p, bytes) 0
#endif

#include "cuda.h"
#include "cuda_runtime.h"

thread_local uint3 threadIdx{0, 0, 0};
thread_local uint3 blockIdx{0, 0, 0};
thread_local uint3 blockDim{1, 1, 1};
thread_local uint3 gridDim{1, 1, 1};

namespace hivox::cuda::emulation {
namespace {

namespace ctx = boost::context;

[[noreturn]] __attribute__((format(printf, 1, 2))) void die(const char* format, ...) {
  std::fprintf(stderr, "hivox CUDA emulation: ");
  va_list args;
  va_start(args, format);
  std::vfprintf(stderr, format, args);
  va_end(args);
  std::fprintf(stderr, "\n");
  std::fflush(stderr);
  std::abort();
}

// ---- fibers ------------------------------------------------------------------------------------

/// Fiber stacks, kept for reuse by the host thread that made them; a guard page below each
/// turns an overflow into a fault. Each stack starts at its own offset below its mapping's top
/// (one of 64 cache lines): the tops of page-aligned stacks all fall into the same sets of the
/// L1 cache, and a block's hundreds of threads, switched at every warp operation, then evicted
/// each other's stack frames at every switch.
class StackPool {
 public:
  static constexpr std::size_t kBytes = 256 * 1024;
  static constexpr std::size_t kColours = 64, kLine = 64;

  ctx::stack_context allocate() {
    std::vector<void*>& free = free_list();
    void* base = nullptr;
    if (!free.empty()) {
      base = free.back();
      free.pop_back();
    } else {
      base = mmap(nullptr, kBytes + page(), PROT_READ | PROT_WRITE,
                  MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
      if (base == MAP_FAILED) die("no memory for a thread's stack");
      mprotect(base, page(), PROT_NONE);
      // Under valgrind, a switch between two fibers' stacks is then a switch of stacks, not a
      // frame hundreds of kilobytes deep that leaves the other fiber's frames undefined.
      static_cast<void>(VALGRIND_STACK_REGISTER(static_cast<char*>(base) + page(),
                                                static_cast<char*>(base) + page() + kBytes));
    }
    // The colour of a stack follows from its address (the mapping is page-aligned), so that a
    // stack taken again from the free list keeps its own.
    const std::size_t colour = (reinterpret_cast<std::uintptr_t>(base) / page()) % kColours;
    ctx::stack_context sc;
    sc.size = kBytes - colour * kLine;
    sc.sp = static_cast<char*>(base) + page() + sc.size;
    return sc;
  }
  void deallocate(ctx::stack_context& sc) {
    free_list().push_back(static_cast<char*>(sc.sp) - sc.size - page());
  }

 private:
  static std::size_t page() {
    static const std::size_t bytes = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
    return bytes;
  }
  static std::vector<void*>& free_list() {
    thread_local std::vector<void*> stacks;
    return stacks;
  }
};

/// Item `i` of a grid or block of `dim` (x fastest), as CUDA numbers threads and blocks.
uint3 unflatten(int64_t i, uint3 dim) {
  return uint3{static_cast<unsigned>(i % dim.x), static_cast<unsigned>((i / dim.x) % dim.y),
               static_cast<unsigned>(i / (int64_t{dim.x} * dim.y))};
}

/// The order in which a grid's blocks and a block's threads run (HIVOX_EMULATION_SCHEDULE, read
/// at each launch). `InOrder`: blocks and threads in index order, a thread switching only where
/// it waits. `Reverse`: both from the last index, and a thread yields to the next at every
/// atomic and fence. `Random`: both in an order drawn per launch and block from `seed`, and a
/// thread yields at half of its atomics and fences to a ready thread drawn the same way. A result
/// that changes with the schedule depends on an order a GPU does not promise.
enum class Schedule : uint8_t { InOrder, Reverse, Random };
struct ScheduleAsked {
  Schedule kind = Schedule::InOrder;
  uint64_t seed = 0;
};

ScheduleAsked schedule_asked() {
  const char* v = std::getenv("HIVOX_EMULATION_SCHEDULE");
  if (v == nullptr || *v == '\0' || std::string_view(v) == "in-order") return {};
  const std::string_view s(v);
  if (s == "reverse") return {Schedule::Reverse, 0};
  if (s == "random") return {Schedule::Random, 1};
  if (s.substr(0, 7) == "random:" && s.size() > 7) {
    char* end = nullptr;
    const unsigned long long seed = std::strtoull(v + 7, &end, 10);
    if (*end == '\0' && v[7] != '-') return {Schedule::Random, seed};
  }
  die("HIVOX_EMULATION_SCHEDULE=%s is none of in-order, reverse, random, random:SEED", v);
}

/// splitmix64: the next draw of the generator whose state is `x`.
uint64_t draw(uint64_t& x) {
  uint64_t z = (x += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// 0, 1, ..., n - 1 in the schedule's order (`rng` drawn from for Random).
std::vector<int64_t> scheduled_order(int64_t n, Schedule kind, uint64_t& rng) {
  std::vector<int64_t> order(static_cast<std::size_t>(n));
  for (int64_t i = 0; i < n; ++i)
    order[static_cast<std::size_t>(i)] = kind == Schedule::Reverse ? n - 1 - i : i;
  if (kind == Schedule::Random)
    for (int64_t i = n - 1; i > 0; --i)
      std::swap(order[static_cast<std::size_t>(i)],
                order[static_cast<std::size_t>(draw(rng) % static_cast<uint64_t>(i + 1))]);
  return order;
}

enum class Wait : uint8_t { None, Barrier, Warp };

/// One thread of the running block.
struct Thread {
  uint3 idx{0, 0, 0};  // threadIdx
  Wait wait = Wait::None;
  ctx::fiber parked;           // its fiber while it waits
  WarpOp op = WarpOp::Ballot;  // the warp operation it waits in
  unsigned mask = 0, arg = 0;
  uint64_t value = 0, result = 0;
};

/// The block a host thread runs. Its threads start one after another on a fiber, which moves on
/// to the next thread when one finishes. A thread that has to wait parks its fiber and switches
/// straight to a thread whose wait is over, or to a new fiber for the next thread, or (when
/// neither is left) back to the scheduler, which then either finds every thread finished or
/// reports the deadlock.
struct Block {
  static constexpr int kScheduler = -2, kFinished = -1;

  const std::function<void()>* body = nullptr;
  int n = 0;
  std::vector<Thread> threads;
  std::vector<unsigned> warp_arrived;  // per warp: the lanes in a warp operation
  std::vector<int> ready;              // threads whose wait is over
  int next = 0, done = 0, at_barrier = 0;
  int current = -1;  // the thread running now
  Schedule schedule = Schedule::InOrder;
  uint64_t rng = 0;            // Random's draws for this block
  std::vector<int64_t> order;  // the threads' start order (empty: in index order)
  int switched_from = -1;      // what just switched away: a thread, kScheduler or kFinished
  ctx::fiber scheduler;        // the scheduler's continuation while the threads run

  void enter(int id) {
    current = id;
    threadIdx = threads[static_cast<std::size_t>(id)].idx;
  }

  /// Keeps the continuation of what just switched here, so that it can be resumed.
  void file(ctx::fiber&& from) {
    if (!from) return;
    if (switched_from == kScheduler)
      scheduler = std::move(from);
    else if (switched_from >= 0)
      threads[static_cast<std::size_t>(switched_from)].parked = std::move(from);
  }

  /// What runs next: a thread whose wait is over, else a new fiber for the next thread, else
  /// (`or_scheduler`) the scheduler; an empty fiber when nothing can run.
  ctx::fiber take_next(bool or_scheduler) {
    if (!ready.empty()) return std::move(threads[static_cast<std::size_t>(take_ready())].parked);
    if (next < n) return worker();
    return or_scheduler ? std::move(scheduler) : ctx::fiber{};
  }

  /// Removes and returns a thread whose wait is over: the last one that became ready, or for
  /// Random one drawn.
  int take_ready() {
    if (schedule == Schedule::Random)
      std::swap(ready[static_cast<std::size_t>(draw(rng) % ready.size())], ready.back());
    const int id = ready.back();
    ready.pop_back();
    return id;
  }

  /// At an atomic or a fence: under the Reverse and Random schedules the running thread may let
  /// another run first and goes on after the threads ready now. Reverse starts every thread
  /// before it resumes one (each then runs up to its next atomic, turn by turn); Random draws
  /// between starting the next thread and resuming a ready one.
  void yield() {
    if (schedule == Schedule::InOrder || (ready.empty() && next >= n)) return;
    if (schedule == Schedule::Random && (draw(rng) & 1u) == 0) return;
    const bool start = next < n && (ready.empty() || schedule == Schedule::Reverse ||
                                    draw(rng) % (ready.size() + 1) == 0);
    const int me = current;
    ctx::fiber other =
        start ? worker() : std::move(threads[static_cast<std::size_t>(take_ready())].parked);
    ready.insert(ready.begin(), me);
    switched_from = me;
    file(std::move(other).resume());
    enter(me);
  }

  /// Parks the running thread until its wait is over.
  void park() {
    const int me = current;
    switched_from = me;
    file(take_next(true).resume());
    enter(me);
  }

  /// Releases the barrier when every thread that has not finished is at it.
  bool release_barrier(int self) {
    if (at_barrier == 0 || next < n || at_barrier + done < n) return false;
    // Taken last first: InOrder's threads go on from the last, Reverse's from the first.
    for (int k = 0; k < n; ++k) {
      const int i = schedule == Schedule::Reverse ? n - 1 - k : k;
      Thread& t = threads[static_cast<std::size_t>(i)];
      if (t.wait != Wait::Barrier) continue;
      t.wait = Wait::None;
      if (i != self) ready.push_back(i);
    }
    at_barrier = 0;
    return true;
  }

  ctx::fiber worker() {
    return ctx::fiber(std::allocator_arg, StackPool{}, [this](ctx::fiber&& from) {
      file(std::move(from));
      while (next < n) {
        const int id =
            order.empty() ? next : static_cast<int>(order[static_cast<std::size_t>(next)]);
        ++next;
        enter(id);
        (*body)();
        ++done;
        release_barrier(-1);
      }
      switched_from = kFinished;
      return take_next(true);
    });
  }

  [[noreturn]] void deadlock() const {
    char waits[512] = "";
    std::size_t used = 0;
    for (int i = 0; i < n && used + 32 < sizeof waits; ++i) {
      const Thread& t = threads[static_cast<std::size_t>(i)];
      if (t.wait == Wait::Barrier)
        used += static_cast<std::size_t>(
            std::snprintf(waits + used, sizeof waits - used, " %d:barrier", i));
      else if (t.wait == Wait::Warp)
        used += static_cast<std::size_t>(
            std::snprintf(waits + used, sizeof waits - used, " %d:warp(mask %08x)", i, t.mask));
    }
    die("block (%u,%u,%u) of %d threads cannot go on: %d finished, the others wait for threads "
        "that cannot come (%s )",
        blockIdx.x, blockIdx.y, blockIdx.z, n, done, waits);
  }

  /// Runs the block's threads under schedule `kind` (`seed`: this block's draws for Random).
  void run(const std::function<void()>& thread, uint3 dim, Schedule kind, uint64_t seed) {
    body = &thread;
    n = static_cast<int>(dim.x * dim.y * dim.z);
    schedule = kind;
    rng = seed;
    order.clear();
    if (kind != Schedule::InOrder) order = scheduled_order(n, kind, rng);
    threads.clear();
    threads.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) threads[static_cast<std::size_t>(i)].idx = unflatten(i, dim);
    warp_arrived.assign(static_cast<std::size_t>((n + 31) / 32), 0u);
    ready.clear();
    next = done = at_barrier = 0;
    while (done < n) {
      ctx::fiber f = take_next(false);
      if (!f) deadlock();
      switched_from = kScheduler;
      file(std::move(f).resume());
    }
    current = -1;
  }
};

thread_local Block* running = nullptr;

Block& running_block(const char* what) {
  if (running == nullptr || running->current < 0) die("%s called outside a kernel", what);
  return *running;
}

// ---- the runtime's state -----------------------------------------------------------------------

thread_local cudaError_t last_error = cudaSuccess;

cudaError_t record(cudaError_t e) {
  if (e != cudaSuccess) last_error = e;
  return e;
}

/// Address ranges by start.
struct AddressRanges {
  std::mutex mutex;
  std::map<uintptr_t, std::size_t> ranges;

  void add(const void* p, std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    ranges[reinterpret_cast<uintptr_t>(p)] = bytes;
  }
  /// Forgets the range at `p`; returns its size (0: there was none).
  std::size_t remove(const void* p) {
    std::lock_guard<std::mutex> lock(mutex);
    const auto it = ranges.find(reinterpret_cast<uintptr_t>(p));
    if (it == ranges.end()) return 0;
    const std::size_t bytes = it->second;
    ranges.erase(it);
    return bytes;
  }
  /// Whether [p, p + bytes) lies in one range.
  bool holds(const void* p, std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    const uintptr_t a = reinterpret_cast<uintptr_t>(p);
    auto it = ranges.upper_bound(a);
    if (it == ranges.begin()) return false;
    --it;
    return a + bytes <= it->first + it->second;
  }
};

/// Device memory: what cudaMalloc gave and what is reserved for virtual memory; and the memory
/// in use (cudaMalloc's and the driver's allocations, not reservations) against the device's
/// size, which the tests can lower (hivoxEmulationSetDeviceMemory).
struct DeviceMemory : AddressRanges {
  std::size_t in_use = 0;
  std::size_t size = std::size_t{80} << 30;  // an H100's

  /// Counts `bytes` more in use; false (nothing counted) where the device has not that much free.
  bool take(std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    if (in_use + bytes > size) return false;
    in_use += bytes;
    return true;
  }
  void give_back(std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex);
    in_use -= bytes;
  }
  std::size_t free_bytes() {
    std::lock_guard<std::mutex> lock(mutex);
    return in_use < size ? size - in_use : 0;
  }
};

DeviceMemory& device_memory() {
  static DeviceMemory memory;
  return memory;
}

/// Page-locked host memory (cudaMallocHost's): where a GPU's cudaMemcpyAsync returns before the
/// copy is done.
AddressRanges& pinned_memory() {
  static AddressRanges memory;
  return memory;
}

/// What memory a GPU hands out holds: not cleared, so new device memory is filled [p, p + bytes).
/// By default with 0xA5, except cudaMalloc's beyond 64 MiB (`large`), left as they come;
/// HIVOX_EMULATION_FILL=N (a byte, 0-255) fills all of it with N, =random each allocation with
/// bytes of its own, so that a kernel reading memory nothing wrote gives results that move with
/// the fill; =undefined leaves it as it is and tells valgrind's memcheck that it is undefined,
/// so that memcheck reports where such a read decides a branch, an address or an output. Read at
/// each allocation.
void fill_new(void* p, std::size_t bytes, bool large) {
  static std::atomic<uint64_t> allocations{0};
  const char* v = std::getenv("HIVOX_EMULATION_FILL");
  if (v == nullptr || *v == '\0') {
    if (!large) std::memset(p, 0xA5, bytes);
    return;
  }
  if (std::string_view(v) == "undefined") {
    if (!HIVOX_WITH_VALGRIND)
      die("HIVOX_EMULATION_FILL=undefined needs valgrind's headers (valgrind/memcheck.h) at build "
          "time");
    static_cast<void>(VALGRIND_MAKE_MEM_UNDEFINED(p, bytes));
    return;
  }
  if (std::string_view(v) != "random") {
    char* end = nullptr;
    const long byte = std::strtol(v, &end, 0);
    if (*end != '\0' || byte < 0 || byte > 255)
      die("HIVOX_EMULATION_FILL=%s is neither a byte (0-255) nor \"random\" nor \"undefined\"", v);
    std::memset(p, static_cast<int>(byte), bytes);
    return;
  }
  uint64_t x = 0x9E3779B97F4A7C15ull * (1 + allocations.fetch_add(1));  // xorshift64
  auto* out = static_cast<unsigned char*>(p);
  for (std::size_t i = 0; i < bytes; i += 8) {
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    std::memcpy(out + i, &x, std::min<std::size_t>(8, bytes - i));
  }
}

std::size_t stack_limit = 1024;
/// Launches sized by the multiprocessor count (the ICP's grid-stride reduction) get smaller grids
/// than on an H100 (132): the same code with fewer threads, each taking more of the items.
constexpr int kMultiprocessors = 16;
constexpr std::size_t kGranularity = std::size_t{2} << 20;

/// Bytes copied from the device to the host so far (hivoxEmulationBytesToHost).
std::atomic<std::size_t> bytes_to_host{0};

/// Checks a copy's sides (and counts what it brings to the host).
void check_copy(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind) {
  const char* what = "cudaMemcpy";
  if (kind == cudaMemcpyDeviceToHost) bytes_to_host += bytes;
  DeviceMemory& memory = device_memory();
  const bool dst_device = kind == cudaMemcpyHostToDevice || kind == cudaMemcpyDeviceToDevice;
  const bool src_device = kind == cudaMemcpyDeviceToHost || kind == cudaMemcpyDeviceToDevice;
  if (dst_device && !memory.holds(dst, bytes))
    die("%s of %zu bytes writes to %p, outside device memory", what, bytes, dst);
  if (src_device && !memory.holds(src, bytes))
    die("%s of %zu bytes reads from %p, outside device memory", what, bytes, src);
  if (kind == cudaMemcpyHostToDevice && memory.holds(src, 1))
    die("%s host-to-device reads from device memory at %p", what, src);
  if (kind == cudaMemcpyDeviceToHost && memory.holds(dst, 1))
    die("%s device-to-host writes to device memory at %p", what, dst);
}

/// The device's queue of copies between page-locked host memory and the device, which a GPU may
/// still be doing when cudaMemcpyAsync returns. An upload reads its host side when the device
/// gets to it: just before the next kernel, copy or memset. A download reads the device at once
/// (nothing queued after it has run yet) but hands its bytes to the host only at a
/// synchronisation that waits for it: cudaDeviceSynchronize, a free, an event recorded after it,
/// a synchronisation of its stream, or (on the default stream) a blocking copy. Until then its host
/// side holds what new device memory holds (fill_new), so a host that reads it without waiting
/// reads nonsense, as it may on a GPU.
class CopyQueue {
 public:
  void upload(void* dst, const void* src, std::size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    uploads_.push_back({dst, src, bytes});
  }
  void download(void* dst, const void* src, std::size_t bytes, const void* stream) {
    run_uploads();
    std::lock_guard<std::mutex> lock(mutex_);
    const auto* from = static_cast<const unsigned char*>(src);
    downloads_.push_back({dst, std::vector<unsigned char>(from, from + bytes), queued_++, stream});
    fill_new(dst, bytes, false);
  }
  /// Before the device does anything: the uploads queued, in order.
  void run_uploads() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Upload& u : uploads_) std::memcpy(u.dst, u.src, u.bytes);
    uploads_.clear();
  }
  /// The downloads queued before mark `before` (every one by default) handed to the host.
  void finish(uint64_t before = UINT64_MAX) {
    hand_over([&](const Download& d) { return d.mark < before; });
  }
  /// The downloads queued on `stream` handed to the host.
  void finish_stream(const void* stream) {
    hand_over([&](const Download& d) { return d.stream == stream; });
  }
  /// The mark of what is queued now (an event's).
  uint64_t mark() {
    std::lock_guard<std::mutex> lock(mutex_);
    return queued_;
  }

 private:
  struct Download;
  /// The downloads `which` picks handed to the host (the uploads queued run first).
  template <typename Which>
  void hand_over(Which&& which) {
    run_uploads();
    std::lock_guard<std::mutex> lock(mutex_);
    std::erase_if(downloads_, [&](const Download& d) {
      if (!which(d)) return false;
      std::memcpy(d.dst, d.bytes.data(), d.bytes.size());
      return true;
    });
  }
  struct Upload {
    void* dst;
    const void* src;
    std::size_t bytes;
  };
  struct Download {
    void* dst;
    std::vector<unsigned char> bytes;
    uint64_t mark;
    const void* stream;  ///< queued on (null: the default stream)
  };
  std::mutex mutex_;
  std::vector<Upload> uploads_;
  std::vector<Download> downloads_;
  uint64_t queued_ = 0;
};

CopyQueue& copy_queue() {
  static CopyQueue queue;
  return queue;
}

struct Stream;

struct Event {
  std::chrono::steady_clock::time_point at;
  uint64_t mark = 0;         // the copy queue's when recorded
  Stream* holder = nullptr;  // recorded last on a stream that holds its work (late), else null
};

/// A recorded launch: its configuration and its threads' function (the arguments held).
struct Launch {
  dim3 grid, block;
  std::function<void()> thread;
};
struct Graph {
  std::vector<Launch> launches;
};
struct Stream {
  Graph* capture = nullptr;  ///< the graph being recorded, or null
  /// While its work comes late (HIVOX_EMULATION_STREAMS): what it was given and has not done
  /// yet, in order.
  std::vector<std::function<void()>> held;
};

/// HIVOX_EMULATION_STREAMS (read at each use): which queues hold their work back until something
/// waits for it. `early` (the default): none, each runs what it is given when it is given.
/// `late`: the streams of the program's own; `default-late`: the default stream (the others run
/// early). Held work runs at a synchronisation of its stream, of an event recorded on it, or of
/// the device, a wait of another stream for such an event (cudaStreamWaitEvent), a free, the
/// stream's end, or (the default stream's) a blocking copy. On a GPU such work may run any time
/// in between, so a result that changes with the mode depends on an order the program did not
/// ask for: `late` shows the default stream reading what a stream of its own makes without
/// waiting for it, `default-late` a stream of its own doing so with the default stream's work
/// (or writing what that work still reads).
enum class StreamsMode { Early, Late, DefaultLate };
StreamsMode streams_mode() {
  const char* v = std::getenv("HIVOX_EMULATION_STREAMS");
  if (v == nullptr || *v == '\0' || std::string_view(v) == "early") return StreamsMode::Early;
  if (std::string_view(v) == "late") return StreamsMode::Late;
  if (std::string_view(v) == "default-late") return StreamsMode::DefaultLate;
  die("HIVOX_EMULATION_STREAMS=%s is none of early, late and default-late", v);
}

/// The default stream's queue (null handle).
Stream& default_stream() {
  static Stream s;
  return s;
}
/// The queue of `stream` (null: the default stream's).
Stream* queue_of(cudaStream_t stream) {
  return stream == nullptr ? &default_stream() : reinterpret_cast<Stream*>(stream);
}

/// Every stream made and not yet destroyed (the device's synchronisation runs all they hold).
std::vector<Stream*>& streams() {
  static std::vector<Stream*> all;
  return all;
}

/// The queue whose work is held back now, or null (it runs at once: streams early, a capturing
/// stream, or the other kind of stream than the mode holds).
Stream* holding(cudaStream_t stream) {
  const StreamsMode mode = streams_mode();
  if (stream == nullptr) return mode == StreamsMode::DefaultLate ? &default_stream() : nullptr;
  auto* s = reinterpret_cast<Stream*>(stream);
  return mode == StreamsMode::Late && s->capture == nullptr ? s : nullptr;
}

/// Gives `work` to `stream`: held back when the stream's work comes late (returns its queue),
/// else done now (returns null).
Stream* give(cudaStream_t stream, std::function<void()> work) {
  Stream* s = holding(stream);
  if (s != nullptr)
    s->held.push_back(std::move(work));
  else
    work();
  return s;
}

/// Does the work `s` holds, in order.
void run_held(Stream* s) {
  while (!s->held.empty()) {
    std::vector<std::function<void()>> work;
    work.swap(s->held);
    for (const std::function<void()>& w : work) w();
  }
}
/// What the device's synchronisation (and a free) waits for: every stream's work, then every
/// download handed to the host.
void synchronize_device() {
  run_held(&default_stream());
  for (Stream* s : streams()) run_held(s);
  copy_queue().finish();
}

/// A copy the host waits for, in the order of `stream`: what the stream holds runs and its
/// downloads reach the host first.
void blocking_copy(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind,
                   cudaStream_t stream) {
  check_copy(dst, src, bytes, kind);
  run_held(queue_of(stream));
  copy_queue().finish_stream(stream);
  std::memcpy(dst, src, bytes);
}
/// A clear the device does now (checked when it was given).
void clear_now(void* ptr, int value, std::size_t bytes) {
  copy_queue().run_uploads();
  std::memset(ptr, value, bytes);
}

// ---- the driver's virtual memory ---------------------------------------------------------------

struct Allocation {
  std::size_t bytes = 0;
};

CUresult vm_granularity(std::size_t* granularity, const CUmemAllocationProp*,
                        CUmemAllocationGranularity_flags) {
  *granularity = kGranularity;
  return CUDA_SUCCESS;
}

CUresult vm_reserve(CUdeviceptr* ptr, std::size_t size, std::size_t, CUdeviceptr,
                    unsigned long long) {
  if (size == 0 || size % kGranularity != 0) return CUDA_ERROR_INVALID_VALUE;
  // Addresses aligned to the granularity, as a GPU's are: mmap aligns only to a page (a kernel
  // may align large mappings further, valgrind's placement does not), so one granule more is
  // reserved and what lies outside the aligned range given back.
  void* raw = mmap(nullptr, size + kGranularity, PROT_NONE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (raw == MAP_FAILED) return CUDA_ERROR_OUT_OF_MEMORY;
  const uintptr_t start = reinterpret_cast<uintptr_t>(raw);
  const uintptr_t aligned = (start + kGranularity - 1) / kGranularity * kGranularity;
  if (aligned > start) munmap(raw, aligned - start);
  munmap(reinterpret_cast<void*>(aligned + size), start + kGranularity - aligned);  // > 0 bytes
  void* p = reinterpret_cast<void*>(aligned);
  device_memory().add(p, size);
  *ptr = reinterpret_cast<CUdeviceptr>(p);
  return CUDA_SUCCESS;
}

CUresult vm_free(CUdeviceptr ptr, std::size_t size) {
  void* p = reinterpret_cast<void*>(ptr);
  if (device_memory().remove(p) == 0) return CUDA_ERROR_INVALID_VALUE;
  munmap(p, size);
  return CUDA_SUCCESS;
}

CUresult vm_create(CUmemGenericAllocationHandle* handle, std::size_t size,
                   const CUmemAllocationProp*, unsigned long long) {
  if (size == 0 || size % kGranularity != 0) return CUDA_ERROR_INVALID_VALUE;
  if (!device_memory().take(size)) return CUDA_ERROR_OUT_OF_MEMORY;
  *handle = reinterpret_cast<CUmemGenericAllocationHandle>(new Allocation{size});
  return CUDA_SUCCESS;
}

CUresult vm_release(CUmemGenericAllocationHandle handle) {
  const Allocation* a = reinterpret_cast<const Allocation*>(handle);
  device_memory().give_back(a->bytes);
  delete a;
  return CUDA_SUCCESS;
}

CUresult vm_map(CUdeviceptr ptr, std::size_t size, std::size_t offset,
                CUmemGenericAllocationHandle handle, unsigned long long) {
  const Allocation* a = reinterpret_cast<const Allocation*>(handle);
  if (a == nullptr || offset + size > a->bytes || ptr % kGranularity != 0 ||
      !device_memory().holds(reinterpret_cast<void*>(ptr), size))
    return CUDA_ERROR_INVALID_VALUE;
  return CUDA_SUCCESS;  // accessible only once cuMemSetAccess opens it
}

CUresult vm_unmap(CUdeviceptr ptr, std::size_t size) {
  void* p = reinterpret_cast<void*>(ptr);
  madvise(p, size, MADV_DONTNEED);
  return mprotect(p, size, PROT_NONE) == 0 ? CUDA_SUCCESS : CUDA_ERROR_INVALID_VALUE;
}

CUresult vm_set_access(CUdeviceptr ptr, std::size_t size, const CUmemAccessDesc* desc,
                       std::size_t count) {
  if (count != 1 || desc->flags != CU_MEM_ACCESS_FLAGS_PROT_READWRITE)
    return CUDA_ERROR_INVALID_VALUE;
  if (mprotect(reinterpret_cast<void*>(ptr), size, PROT_READ | PROT_WRITE) != 0)
    return CUDA_ERROR_INVALID_VALUE;
  fill_new(reinterpret_cast<void*>(ptr), size, false);
  return CUDA_SUCCESS;
}

CUresult vm_device(CUdevice* device, int ordinal) {
  if (ordinal != 0) return CUDA_ERROR_INVALID_DEVICE;
  *device = 0;
  return CUDA_SUCCESS;
}

CUresult vm_attribute(int* value, CUdevice_attribute attribute, CUdevice device) {
  if (device != 0) return CUDA_ERROR_INVALID_DEVICE;
  *value = attribute == CU_DEVICE_ATTRIBUTE_VIRTUAL_MEMORY_MANAGEMENT_SUPPORTED ? 1 : 0;
  return CUDA_SUCCESS;
}

// ---- kernels -----------------------------------------------------------------------------------

/// Whether a GPU takes the launch configuration (else the launch's error is recorded, at the
/// launch as on a GPU, also when the kernel itself comes late).
bool launchable(dim3 grid, dim3 block) {
  const uint64_t threads = uint64_t{block.x} * block.y * block.z;
  if (grid.x == 0 || grid.y == 0 || grid.z == 0 || grid.y > 65535 || grid.z > 65535 ||
      threads == 0 || threads > 1024 || block.z > 64) {
    record(cudaErrorInvalidConfiguration);
    return false;
  }
  return true;
}

/// Runs `thread` for every thread of a grid of `grid` blocks of `block` threads (a configuration
/// launchable), with the built-in indices set; returns when all have finished.
void run_grid(dim3 grid, dim3 block, const std::function<void()>& thread) {
  if (running != nullptr) die("a kernel launched from a kernel");
  copy_queue().run_uploads();
  const int64_t blocks = int64_t{grid.x} * grid.y * grid.z;
  const uint3 g{grid.x, grid.y, grid.z}, b{block.x, block.y, block.z};
  // Each launch draws its orders from the seed and its number (a program that launches the same
  // kernels in the same order gets the same orders in every run).
  static std::atomic<uint64_t> launches{0};
  const ScheduleAsked asked = schedule_asked();
  uint64_t rng = asked.seed ^ (0xD1B54A32D192ED03ull * (1 + launches.fetch_add(1)));
  std::vector<int64_t> order;
  if (asked.kind != Schedule::InOrder) order = scheduled_order(blocks, asked.kind, rng);
#pragma omp parallel for schedule(dynamic, 1)
  for (int64_t k = 0; k < blocks; ++k) {
    const int64_t i = order.empty() ? k : order[static_cast<std::size_t>(k)];
    thread_local Block state;
    running = &state;
    gridDim = g;
    blockDim = b;
    blockIdx = unflatten(i, g);
    uint64_t block_rng = rng ^ static_cast<uint64_t>(i);
    state.run(thread, b, asked.kind, draw(block_rng));
    running = nullptr;
  }
}

}  // namespace

void launch_on(cudaStream_t stream, dim3 grid, dim3 block, std::function<void()> thread) {
  if (stream != nullptr) {
    if (Graph* g = reinterpret_cast<Stream*>(stream)->capture) {
      g->launches.push_back({grid, block, std::move(thread)});
      return;
    }
  }
  if (!launchable(grid, block)) return;
  give(stream, [grid, block, thread = std::move(thread)] { run_grid(grid, block, thread); });
}

unsigned lane() {
  return static_cast<unsigned>(running_block("a warp function").current) & 31u;
}

void at_atomic() {
  if (running != nullptr && running->current >= 0) running->yield();
}

uint64_t warp_op(WarpOp op, unsigned mask, uint64_t value, unsigned arg) {
  Block& b = running_block("a warp operation");
  const int id = b.current;
  const unsigned lane = static_cast<unsigned>(id) & 31u;
  const int base = id - static_cast<int>(lane);
  if ((mask >> lane & 1u) == 0)
    die("block (%u,%u,%u) thread %d: a warp operation whose mask %08x leaves out its own lane",
        blockIdx.x, blockIdx.y, blockIdx.z, id, mask);
  if (base + 32 - __builtin_clz(mask) > b.n)
    die("block (%u,%u,%u) thread %d: warp mask %08x names lanes beyond the block's %d threads",
        blockIdx.x, blockIdx.y, blockIdx.z, id, mask, b.n);
  Thread& me = b.threads[static_cast<std::size_t>(id)];
  me.op = op;
  me.mask = mask;
  me.value = value;
  me.arg = arg;
  me.wait = Wait::Warp;
  unsigned& arrived = b.warp_arrived[static_cast<std::size_t>(id / 32)];
  arrived |= 1u << lane;
  if ((arrived & mask) != mask) {
    b.park();
    return me.result;
  }
  // Every lane of the mask is here: each gets its result.
  arrived &= ~mask;
  uint64_t ballot = 0, ored = 0;
  for (unsigned l = 0; l < 32; ++l) {
    if ((mask >> l & 1u) == 0) continue;
    const Thread& t = b.threads[static_cast<std::size_t>(base) + l];
    if (t.op != op || t.mask != mask)
      die("block (%u,%u,%u) warp %d: lanes %u and %u meet in different warp operations or masks "
          "(%08x, %08x)",
          blockIdx.x, blockIdx.y, blockIdx.z, id / 32, lane, l, mask, t.mask);
    if (t.value != 0) ballot |= uint64_t{1} << l;
    ored |= t.value;
  }
  for (unsigned l = 0; l < 32; ++l) {
    if ((mask >> l & 1u) == 0) continue;
    Thread& t = b.threads[static_cast<std::size_t>(base) + l];
    unsigned src = l;
    switch (op) {
      case WarpOp::Ballot:
        t.result = ballot;
        break;
      case WarpOp::ReduceOr:
        t.result = ored;
        break;
      case WarpOp::Shuffle:
        src = t.arg;
        break;
      case WarpOp::ShuffleDown:
        src = l + t.arg < 32 ? l + t.arg : l;
        break;
      case WarpOp::ShuffleXor:
        src = l ^ t.arg;
        break;
    }
    if (op != WarpOp::Ballot && op != WarpOp::ReduceOr) {
      if ((mask >> src & 1u) == 0)
        die("block (%u,%u,%u) warp %d: lane %u reads lane %u, outside the mask %08x", blockIdx.x,
            blockIdx.y, blockIdx.z, id / 32, l, src, mask);
      t.result = b.threads[static_cast<std::size_t>(base) + src].value;
    }
    t.wait = Wait::None;
    if (base + static_cast<int>(l) != id) b.ready.push_back(base + static_cast<int>(l));
  }
  return me.result;
}

}  // namespace hivox::cuda::emulation

namespace e = hivox::cuda::emulation;

void __syncthreads() {
  e::Block& b = e::running_block("__syncthreads");
  b.threads[static_cast<std::size_t>(b.current)].wait = e::Wait::Barrier;
  ++b.at_barrier;
  if (!b.release_barrier(b.current)) b.park();
}

// ---- the runtime -------------------------------------------------------------------------------

cudaError_t cudaGetDeviceCount(int* count) {
  *count = 1;
  return cudaSuccess;
}
cudaError_t cudaGetDevice(int* device) {
  *device = 0;
  return cudaSuccess;
}
cudaError_t cudaSetDevice(int device) {
  return e::record(device == 0 ? cudaSuccess : cudaErrorInvalidDevice);
}
cudaError_t cudaGetDeviceProperties(cudaDeviceProp* prop, int device) {
  if (device != 0) return e::record(cudaErrorInvalidDevice);
  *prop = cudaDeviceProp{};
  std::snprintf(prop->name, sizeof prop->name, "CPU emulation of CUDA (%d threads)",
                omp_get_max_threads());
  prop->totalGlobalMem = e::device_memory().size;
  prop->multiProcessorCount = e::kMultiprocessors;
  prop->major = 9;
  prop->minor = 0;
  prop->warpSize = 32;
  prop->maxThreadsPerBlock = 1024;
  return cudaSuccess;
}
cudaError_t cudaDeviceGetAttribute(int* value, cudaDeviceAttr attr, int device) {
  if (device != 0) return e::record(cudaErrorInvalidDevice);
  if (attr != cudaDevAttrMultiProcessorCount) return e::record(cudaErrorInvalidValue);
  *value = e::kMultiprocessors;
  return cudaSuccess;
}
cudaError_t cudaDeviceGetLimit(std::size_t* value, cudaLimit limit) {
  if (limit != cudaLimitStackSize) return e::record(cudaErrorInvalidValue);
  *value = e::stack_limit;
  return cudaSuccess;
}
cudaError_t cudaDeviceSetLimit(cudaLimit limit, std::size_t value) {
  if (limit != cudaLimitStackSize) return e::record(cudaErrorInvalidValue);
  e::stack_limit = value;
  return cudaSuccess;
}
cudaError_t cudaDeviceSynchronize() {
  e::synchronize_device();
  return e::last_error;
}
cudaError_t cudaGetLastError() {
  const cudaError_t error = e::last_error;
  e::last_error = cudaSuccess;
  return error;
}
cudaError_t cudaPeekAtLastError() {
  return e::last_error;
}
const char* cudaGetErrorString(cudaError_t error) {
  switch (error) {
    case cudaSuccess:
      return "no error";
    case cudaErrorInvalidValue:
      return "invalid argument";
    case cudaErrorMemoryAllocation:
      return "out of memory";
    case cudaErrorInvalidConfiguration:
      return "invalid configuration argument";
    case cudaErrorNoDevice:
      return "no CUDA-capable device is detected";
    case cudaErrorInvalidDevice:
      return "invalid device ordinal";
    case cudaErrorInvalidResourceHandle:
      return "invalid resource handle";
  }
  return "unrecognized error code";
}

cudaError_t cudaMalloc(void** ptr, std::size_t bytes) {
  // Aligned as cudaMalloc's (256 bytes), of the exact size (an ASan build then sees a read past
  // its end); filled (fill_new), as a GPU's memory is not cleared either.
  const std::size_t size = std::max<std::size_t>(bytes, 1);
  e::DeviceMemory& memory = e::device_memory();
  if (!memory.take(size)) return e::record(cudaErrorMemoryAllocation);
  void* p = nullptr;
  if (posix_memalign(&p, 256, size) != 0) {
    memory.give_back(size);
    return e::record(cudaErrorMemoryAllocation);
  }
  e::fill_new(p, size, size > (std::size_t{64} << 20));
  memory.add(p, size);
  *ptr = p;
  return cudaSuccess;
}
cudaError_t cudaFree(void* ptr) {
  if (ptr == nullptr) return cudaSuccess;
  e::synchronize_device();  // a free waits for the device
  const std::size_t bytes = e::device_memory().remove(ptr);
  if (bytes == 0) return e::record(cudaErrorInvalidValue);
  e::device_memory().give_back(bytes);
  std::free(ptr);
  return cudaSuccess;
}
cudaError_t cudaMemGetInfo(std::size_t* free, std::size_t* total) {
  e::DeviceMemory& memory = e::device_memory();
  *free = memory.free_bytes();
  *total = memory.size;
  return cudaSuccess;
}
cudaError_t hivoxEmulationSetDeviceMemory(std::size_t bytes) {
  e::DeviceMemory& memory = e::device_memory();
  std::lock_guard<std::mutex> lock(memory.mutex);
  memory.size = bytes;
  return cudaSuccess;
}
std::size_t hivoxEmulationBytesToHost() {
  return e::bytes_to_host.load();
}
cudaError_t cudaMallocHost(void** ptr, std::size_t bytes) {
  const std::size_t size = std::max<std::size_t>(bytes, 1);
  *ptr = std::malloc(size);
  if (*ptr == nullptr) return e::record(cudaErrorMemoryAllocation);
  e::pinned_memory().add(*ptr, size);
  return cudaSuccess;
}
cudaError_t cudaFreeHost(void* ptr) {
  if (ptr == nullptr) return cudaSuccess;
  e::synchronize_device();  // a free waits for the device
  if (e::pinned_memory().remove(ptr) == 0) return e::record(cudaErrorInvalidValue);
  std::free(ptr);
  return cudaSuccess;
}

cudaError_t cudaMemcpy(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind) {
  // A blocking copy waits for what the default stream queued before it (not for a stream of
  // its own: the loop's are non-blocking).
  if (bytes != 0) e::blocking_copy(dst, src, bytes, kind, nullptr);
  return cudaSuccess;
}
cudaError_t cudaMemcpyAsync(void* dst, const void* src, std::size_t bytes, cudaMemcpyKind kind,
                            cudaStream_t stream) {
  // Copies with page-locked host memory are left to the queue and device-to-device ones run in
  // the device's order; with pageable memory a GPU finishes the copy before returning.
  const bool upload = kind == cudaMemcpyHostToDevice && e::pinned_memory().holds(src, bytes);
  const bool download = kind == cudaMemcpyDeviceToHost && e::pinned_memory().holds(dst, bytes);
  if (bytes == 0) return cudaSuccess;
  if (!(upload || download || kind == cudaMemcpyDeviceToDevice)) {
    e::blocking_copy(dst, src, bytes, kind, stream);
    return cudaSuccess;
  }
  e::check_copy(dst, src, bytes, kind);
  const auto copy = [=] {
    if (upload) {
      e::copy_queue().upload(dst, src, bytes);
    } else if (download) {
      e::copy_queue().download(dst, src, bytes, stream);
    } else {
      e::copy_queue().run_uploads();
      std::memcpy(dst, src, bytes);
    }
  };
  // Held back with the stream's work, the copy reads its source when the stream gets to it.
  e::give(stream, copy);
  return cudaSuccess;
}
cudaError_t cudaMemset(void* ptr, int value, std::size_t bytes) {
  return cudaMemsetAsync(ptr, value, bytes, nullptr);  // on the default stream, in its order
}
cudaError_t cudaMemsetAsync(void* ptr, int value, std::size_t bytes, cudaStream_t stream) {
  if (bytes == 0) return cudaSuccess;
  if (!e::device_memory().holds(ptr, bytes))
    e::die("cudaMemset of %zu bytes at %p, outside device memory", bytes, ptr);
  e::give(stream, [=] { e::clear_now(ptr, value, bytes); });
  return cudaSuccess;
}

cudaError_t cudaStreamCreateWithFlags(cudaStream_t* stream, unsigned) {
  auto* s = new e::Stream{};
  e::streams().push_back(s);
  *stream = reinterpret_cast<cudaStream_t>(s);
  return cudaSuccess;
}
cudaError_t cudaStreamCreateWithPriority(cudaStream_t* stream, unsigned flags, int) {
  return cudaStreamCreateWithFlags(stream, flags);  // one queue: priorities change no order
}
cudaError_t cudaDeviceGetStreamPriorityRange(int* least, int* greatest) {
  *least = 0;
  *greatest = -5;  // as a GPU's: lower numbers go first
  return cudaSuccess;
}
cudaError_t cudaStreamDestroy(cudaStream_t stream) {
  auto* s = reinterpret_cast<e::Stream*>(stream);
  if (s != nullptr && s->capture != nullptr) e::die("a stream destroyed while it captures");
  if (s != nullptr) {
    e::run_held(s);  // its work is done, as a GPU does it
    std::erase(e::streams(), s);
  }
  delete s;
  return cudaSuccess;
}
cudaError_t cudaStreamSynchronize(cudaStream_t stream) {
  e::run_held(e::queue_of(stream));
  e::copy_queue().finish_stream(stream);
  return e::last_error;
}
cudaError_t cudaStreamWaitEvent(cudaStream_t, cudaEvent_t event, unsigned) {
  if (event == nullptr) e::die("a stream told to wait for no event");
  // The work before the event is done now, before whatever the waiting stream is given next
  // (its own work held back runs after it anyway).
  if (e::Stream* s = reinterpret_cast<e::Event*>(event)->holder) e::run_held(s);
  return cudaSuccess;
}
cudaError_t cudaStreamBeginCapture(cudaStream_t stream, cudaStreamCaptureMode) {
  auto* s = reinterpret_cast<e::Stream*>(stream);
  if (s == nullptr) e::die("a capture on the default stream (a GPU refuses it)");
  if (s->capture != nullptr) e::die("a capture begun on a stream that captures");
  s->capture = new e::Graph{};
  return cudaSuccess;
}
cudaError_t cudaStreamEndCapture(cudaStream_t stream, cudaGraph_t* graph) {
  auto* s = reinterpret_cast<e::Stream*>(stream);
  if (s == nullptr || s->capture == nullptr)
    e::die("a capture ended on a stream that does not capture");
  *graph = reinterpret_cast<cudaGraph_t>(s->capture);
  s->capture = nullptr;
  return cudaSuccess;
}
cudaError_t cudaGraphInstantiate(cudaGraphExec_t* exec, cudaGraph_t graph, unsigned long long) {
  *exec = reinterpret_cast<cudaGraphExec_t>(new e::Graph(*reinterpret_cast<e::Graph*>(graph)));
  return cudaSuccess;
}
cudaError_t cudaGraphLaunch(cudaGraphExec_t exec, cudaStream_t stream) {
  for (const e::Launch& l : reinterpret_cast<e::Graph*>(exec)->launches)
    e::launch_on(stream, l.grid, l.block, l.thread);
  return cudaSuccess;
}
cudaError_t cudaGraphExecDestroy(cudaGraphExec_t exec) {
  delete reinterpret_cast<e::Graph*>(exec);
  return cudaSuccess;
}
cudaError_t cudaGraphDestroy(cudaGraph_t graph) {
  delete reinterpret_cast<e::Graph*>(graph);
  return cudaSuccess;
}

cudaError_t cudaEventCreate(cudaEvent_t* event) {
  *event = reinterpret_cast<cudaEvent_t>(new e::Event{});
  return cudaSuccess;
}
cudaError_t cudaEventDestroy(cudaEvent_t event) {
  delete reinterpret_cast<e::Event*>(event);
  return cudaSuccess;
}
cudaError_t cudaEventRecord(cudaEvent_t event, cudaStream_t stream) {
  auto* ev = reinterpret_cast<e::Event*>(event);
  const auto mark = [ev] {
    ev->at = std::chrono::steady_clock::now();
    ev->mark = e::copy_queue().mark();
  };
  ev->holder = e::give(stream, mark);
  return cudaSuccess;
}
cudaError_t cudaEventSynchronize(cudaEvent_t event) {
  auto* ev = reinterpret_cast<e::Event*>(event);
  if (ev->holder != nullptr) e::run_held(ev->holder);
  e::copy_queue().finish(ev->mark);
  return e::last_error;
}
cudaError_t cudaEventElapsedTime(float* ms, cudaEvent_t start, cudaEvent_t end) {
  *ms = std::chrono::duration<float, std::milli>(reinterpret_cast<e::Event*>(end)->at -
                                                 reinterpret_cast<e::Event*>(start)->at)
            .count();
  return cudaSuccess;
}

cudaError_t cudaGetDriverEntryPointByVersion(const char* symbol, void** function, unsigned,
                                             unsigned long long,
                                             cudaDriverEntryPointQueryResult* status) {
  static const std::map<std::string_view, void*> table = {
      {"cuMemGetAllocationGranularity", reinterpret_cast<void*>(&e::vm_granularity)},
      {"cuMemAddressReserve", reinterpret_cast<void*>(&e::vm_reserve)},
      {"cuMemAddressFree", reinterpret_cast<void*>(&e::vm_free)},
      {"cuMemCreate", reinterpret_cast<void*>(&e::vm_create)},
      {"cuMemRelease", reinterpret_cast<void*>(&e::vm_release)},
      {"cuMemMap", reinterpret_cast<void*>(&e::vm_map)},
      {"cuMemUnmap", reinterpret_cast<void*>(&e::vm_unmap)},
      {"cuMemSetAccess", reinterpret_cast<void*>(&e::vm_set_access)},
      {"cuDeviceGet", reinterpret_cast<void*>(&e::vm_device)},
      {"cuDeviceGetAttribute", reinterpret_cast<void*>(&e::vm_attribute)},
  };
  const auto it = table.find(symbol);
  *function = it != table.end() ? it->second : nullptr;
  if (status != nullptr)
    *status = it != table.end() ? cudaDriverEntryPointSuccess : cudaDriverEntryPointSymbolNotFound;
  return cudaSuccess;
}
