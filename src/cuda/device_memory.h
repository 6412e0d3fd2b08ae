#pragma once
// Device memory for the CUDA loop: plain buffers, page-locked host buffers for uploads, and a
// buffer that reserves its whole capacity as addresses but commits memory only as it is used
// (the device's counterpart of the CPU map's lazily committed pool). Host code (runtime API).

#include <cuda_runtime_api.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hivox::cuda {

/// Device memory the map's pool leaves free when the device fills: for the buffers grown on
/// demand (the refinement's jobs, the raycast's coarse grid) and the mesher (its scratch takes at
/// most a quarter of what is free).
inline constexpr std::size_t kPoolKeepsFreeBytes = std::size_t{192} << 20;

/// Throws `Error(Cuda)` naming `what` when `status` is not success; `Error(OutOfCapacity)` where
/// the device is out of memory.
void check_status(cudaError_t status, const char* what);

/// The current device's free memory in bytes (`Error(Cuda)` where the runtime cannot say).
std::size_t free_device_memory();

/// `bytes` of device memory (null for 0); `Error(OutOfCapacity)` naming the size and the memory
/// free where the device has not that much.
void* allocate_device(std::size_t bytes);

/// Blocking copies of `bytes` (none when 0) to and from device memory; `what` names the copy in
/// errors. A copy to the host waits for the device's queue up to it.
inline void copy_to_device(void* device, const void* host, std::size_t bytes,
                           const char* what = "upload") {
  if (bytes > 0) check_status(cudaMemcpy(device, host, bytes, cudaMemcpyHostToDevice), what);
}
inline void copy_to_host(void* host, const void* device, std::size_t bytes,
                         const char* what = "download") {
  if (bytes > 0) check_status(cudaMemcpy(host, device, bytes, cudaMemcpyDeviceToHost), what);
}

/// Queued copies of `n` elements between page-locked host memory and the device, on `stream`
/// (null: the default stream): the host does not wait (the next synchronisation of the stream
/// or the device, or a blocking copy, ends them). `what` names the copy in errors.
template <typename T>
void upload_async(T* device, const T* host, std::size_t n, const char* what,
                  cudaStream_t stream = nullptr) {
  if (n > 0)
    check_status(cudaMemcpyAsync(device, host, n * sizeof(T), cudaMemcpyHostToDevice, stream),
                 what);
}
template <typename T>
void download_async(T* host, const T* device, std::size_t n, const char* what,
                    cudaStream_t stream = nullptr) {
  if (n > 0)
    check_status(cudaMemcpyAsync(host, device, n * sizeof(T), cudaMemcpyDeviceToHost, stream),
                 what);
}

/// Waits until `stream` has done what was queued on it; null: until the whole device has.
inline void wait_for_queue(cudaStream_t stream, const char* what) {
  check_status(stream != nullptr ? cudaStreamSynchronize(stream) : cudaDeviceSynchronize(), what);
}

/// A queue of the device's own, beside the default stream: what goes on it does not wait for
/// the default stream's work, nor that for it, except where a QueueMark orders them. Its kernels
/// go first where both have blocks waiting for a multiprocessor (the highest priority): short
/// work whose results the host waits for, beside long work it does not.
class Stream {
 public:
  Stream() = default;
  ~Stream() {
    if (stream_ != nullptr) cudaStreamDestroy(stream_);
  }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  /// The stream, made on the current device at the first call.
  cudaStream_t get(const char* what) {
    if (stream_ == nullptr) {
      int least = 0, greatest = 0;
      check_status(cudaDeviceGetStreamPriorityRange(&least, &greatest), what);
      check_status(cudaStreamCreateWithPriority(&stream_, cudaStreamNonBlocking, greatest), what);
    }
    return stream_;
  }

 private:
  cudaStream_t stream_ = nullptr;
};

/// A mark in the device's queue. The time between two marks is the device's own, and reading it
/// costs no wait once a later synchronisation has passed both: stages timed without waiting
/// just to time them.
class QueueMark {
 public:
  QueueMark() = default;
  ~QueueMark() {
    if (event_ != nullptr) cudaEventDestroy(event_);
  }
  QueueMark(const QueueMark&) = delete;
  QueueMark& operator=(const QueueMark&) = delete;
  /// Marks the queue of `stream` (null: the default stream) here (the first mark makes the
  /// event, on the current device).
  void record(const char* what, cudaStream_t stream = nullptr) {
    if (event_ == nullptr) check_status(cudaEventCreate(&event_), what);
    check_status(cudaEventRecord(event_, stream), what);
  }
  /// Waits until the device has passed this mark (recorded).
  void wait(const char* what) const { check_status(cudaEventSynchronize(event_), what); }
  /// What is queued on `stream` (null: the default stream) from now on starts after the device
  /// has passed this mark (the last recorded; none: no wait).
  void order_before(cudaStream_t stream, const char* what) const {
    if (event_ != nullptr) check_status(cudaStreamWaitEvent(stream, event_, 0), what);
  }
  /// Milliseconds on the device from `earlier` to this mark (both recorded, both passed).
  double ms_since(const QueueMark& earlier, const char* what) const {
    float ms = 0;
    check_status(cudaEventElapsedTime(&ms, earlier.event_, event_), what);
    return ms;
  }

 private:
  cudaEvent_t event_ = nullptr;
};

/// Device memory freed with its owner; its bytes are added to `*total` (when not null).
template <typename T>
class Buffer {
 public:
  Buffer() = default;
  ~Buffer() { release(); }
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
  Buffer(Buffer&& o) noexcept : ptr_(o.ptr_), size_(o.size_) {
    o.ptr_ = nullptr;
    o.size_ = 0;
  }
  void reset(std::size_t n, int64_t* total) {
    release();
    ptr_ = static_cast<T*>(allocate(n * sizeof(T)));
    size_ = n;
    if (total != nullptr) *total += static_cast<int64_t>(n * sizeof(T));
  }
  /// reset(n, total), then the first n elements uploaded from `host`.
  void assign(const T* host, std::size_t n, int64_t* total = nullptr) {
    reset(n, total);
    upload(host, n);
  }
  T* get() const { return ptr_; }
  std::size_t size() const { return size_; }
  void upload(const T* host, std::size_t n, std::size_t offset = 0) {
    copy_to_device(ptr_ + offset, host, n * sizeof(T));
  }
  void download(T* host, std::size_t n, std::size_t offset = 0) const {
    copy_to_host(host, ptr_ + offset, n * sizeof(T));
  }

 private:
  static void* allocate(std::size_t bytes) { return allocate_device(bytes); }
  void release() {
    cudaFree(ptr_);
    ptr_ = nullptr;
    size_ = 0;
  }
  T* ptr_ = nullptr;
  std::size_t size_ = 0;
};

/// Page-locked host memory, grown on demand (uploads from it run at the bus's speed).
template <typename T>
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  ~PinnedBuffer() { release(); }
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  T* reserve(std::size_t n) {
    if (n > size_) {
      release();
      ptr_ = static_cast<T*>(allocate(n * sizeof(T)));
      size_ = n;
    }
    return ptr_;
  }

 private:
  static void* allocate(std::size_t bytes) {
    void* p = nullptr;
    check_status(cudaMallocHost(&p, bytes), "allocation of page-locked host memory");
    return p;
  }
  void release() {
    cudaFreeHost(ptr_);
    ptr_ = nullptr;
    size_ = 0;
  }
  T* ptr_ = nullptr;
  std::size_t size_ = 0;
};

/// Address space reserved on the current device, memory committed as `commit(n)` asks for the
/// first n bytes: in the driver's allocation granularity (2 MiB on current GPUs), one mapping a
/// call. Falls back to one plain allocation of the whole capacity where the driver has no virtual
/// memory management, or HIVOX_CUDA_VIRTUAL_MEMORY=off asks for it.
class GrowingBuffer {
 public:
  GrowingBuffer() = default;
  ~GrowingBuffer();
  GrowingBuffer(const GrowingBuffer&) = delete;
  GrowingBuffer& operator=(const GrowingBuffer&) = delete;
  /// Reserves `bytes` of addresses (committing nothing yet).
  void reserve(std::size_t bytes, int device);
  /// Makes at least the first `bytes` usable; returns the bytes committed now in all. Where the
  /// device's memory cannot hold that many, commits what fits while `keep_free` bytes stay free
  /// (perhaps nothing more) and returns less than `bytes`.
  std::size_t commit(std::size_t bytes, std::size_t keep_free = 0);
  void* get() const { return base_; }
  std::size_t committed() const { return committed_; }

 private:
  void release();
  /// Maps `size` more bytes (a multiple of the chunk) after what is committed; false where the
  /// device is out of memory.
  bool map_more(std::size_t size);
  void* base_ = nullptr;
  std::size_t reserved_ = 0, committed_ = 0, chunk_ = 0;
  int device_ = 0;
  bool virtual_ = false;
  struct Mapping {
    unsigned long long handle;  ///< the driver's allocation
    std::size_t offset, bytes;  ///< where it is mapped from base_
  };
  std::vector<Mapping> mappings_;
};

/// A GrowingBuffer of `T`s: room for `capacity` of them, the first n committed on demand. What
/// lies beyond the uploaded or written elements is undefined (freshly committed memory).
template <typename T>
class GrowingArray {
 public:
  void reserve(std::size_t capacity, int device) { buffer_.reserve(capacity * sizeof(T), device); }
  /// Commits the first `n` (see GrowingBuffer::commit); returns how many are committed.
  std::size_t commit(std::size_t n, std::size_t keep_free = 0) {
    return buffer_.commit(n * sizeof(T), keep_free) / sizeof(T);
  }
  T* get() const { return static_cast<T*>(buffer_.get()); }
  std::size_t committed_bytes() const { return buffer_.committed(); }
  /// The first `n` elements (committed) from and to the host.
  void upload(const T* host, std::size_t n) { copy_to_device(get(), host, n * sizeof(T)); }
  void download(T* host, std::size_t n) const { copy_to_host(host, get(), n * sizeof(T)); }

 private:
  GrowingBuffer buffer_;
};

}  // namespace hivox::cuda
