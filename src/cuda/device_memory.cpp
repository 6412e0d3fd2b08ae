#include "cuda/device_memory.h"

#include <cuda.h>
#include <cuda_runtime_api.h>

#include <algorithm>
#include <cstdlib>
#include <string_view>
#include <type_traits>

#include "hivox/core/error.h"

namespace hivox::cuda {

namespace {
double mib(std::size_t bytes) {
  return static_cast<double>(bytes) / (1024.0 * 1024.0);
}
}  // namespace

void check_status(cudaError_t status, const char* what) {
  if (status == cudaErrorMemoryAllocation) {  // the device is full: a capacity, not a fault
    cudaGetLastError();                       // not sticky: a later launch's check must not find it
    fail(ErrorCode::OutOfCapacity, "CUDA {} failed: the device is out of memory", what);
  }
  if (status != cudaSuccess)
    fail(ErrorCode::Cuda, "CUDA {} failed: {}", what, cudaGetErrorString(status));
}

std::size_t free_device_memory() {
  std::size_t free = 0, total = 0;
  check_status(cudaMemGetInfo(&free, &total), "asking for the free device memory");
  return free;
}

void* allocate_device(std::size_t bytes) {
  void* p = nullptr;
  if (bytes == 0) return p;
  const cudaError_t status = cudaMalloc(&p, bytes);
  if (status == cudaErrorMemoryAllocation) {
    cudaGetLastError();  // not sticky: later calls succeed
    std::size_t free = 0, total = 0;
    cudaMemGetInfo(&free, &total);
    fail(ErrorCode::OutOfCapacity,
         "CUDA allocation of {:.1f} MiB of device memory failed: {:.1f} of {:.1f} MiB free",
         mib(bytes), mib(free), mib(total));
  }
  check_status(status, "allocation of device memory");
  return p;
}

namespace {

/// The driver's virtual memory functions, fetched through the runtime (no link to the driver
/// library: binaries start where there is none, and the GPU tests skip).
struct VirtualMemory {
  decltype(&cuMemGetAllocationGranularity) granularity = nullptr;
  decltype(&cuMemAddressReserve) reserve = nullptr;
  decltype(&cuMemAddressFree) free = nullptr;
  decltype(&cuMemCreate) create = nullptr;
  decltype(&cuMemRelease) release = nullptr;
  decltype(&cuMemMap) map = nullptr;
  decltype(&cuMemUnmap) unmap = nullptr;
  decltype(&cuMemSetAccess) set_access = nullptr;
  decltype(&cuDeviceGet) device = nullptr;
  decltype(&cuDeviceGetAttribute) attribute = nullptr;
  bool ok = false;

  /// Whether device `ordinal` supports virtual memory management.
  bool supported(int ordinal) const {
    CUdevice d{};
    int yes = 0;
    return ok && device(&d, ordinal) == CUDA_SUCCESS &&
           attribute(&yes, CU_DEVICE_ATTRIBUTE_VIRTUAL_MEMORY_MANAGEMENT_SUPPORTED, d) ==
               CUDA_SUCCESS &&
           yes != 0;
  }

  static const VirtualMemory& get() {
    static const VirtualMemory vm = [] {
      VirtualMemory v;
      auto load = [](const char* name, auto** fn) {
        cudaDriverEntryPointQueryResult status{};
        void* p = nullptr;
        if (cudaGetDriverEntryPointByVersion(name, &p, 12000, cudaEnableDefault, &status) !=
                cudaSuccess ||
            status != cudaDriverEntryPointSuccess)
          return false;
        *fn = reinterpret_cast<std::remove_pointer_t<decltype(fn)>>(p);
        return true;
      };
      v.ok = load("cuMemGetAllocationGranularity", &v.granularity) &&
             load("cuMemAddressReserve", &v.reserve) && load("cuMemAddressFree", &v.free) &&
             load("cuMemCreate", &v.create) && load("cuMemRelease", &v.release) &&
             load("cuMemMap", &v.map) && load("cuMemUnmap", &v.unmap) &&
             load("cuMemSetAccess", &v.set_access) && load("cuDeviceGet", &v.device) &&
             load("cuDeviceGetAttribute", &v.attribute);
      cudaGetLastError();
      return v;
    }();
    return vm;
  }
};

/// HIVOX_CUDA_VIRTUAL_MEMORY (read at each reservation): "off" takes the map's pool as one plain
/// allocation of its whole capacity, as on a driver without virtual memory management (a check
/// that a fault depends on memory committed in steps, and the fallback's test); unset or "on":
/// virtual memory where the device has it.
bool virtual_memory_allowed() {
  const char* v = std::getenv("HIVOX_CUDA_VIRTUAL_MEMORY");
  if (v == nullptr || *v == '\0' || std::string_view(v) == "on") return true;
  if (std::string_view(v) == "off") return false;
  fail(ErrorCode::InvalidArgument, "HIVOX_CUDA_VIRTUAL_MEMORY={}: the values are on and off", v);
}

CUmemAllocationProp allocation_prop(int device) {
  CUmemAllocationProp prop{};
  prop.type = CU_MEM_ALLOCATION_TYPE_PINNED;
  prop.location.type = CU_MEM_LOCATION_TYPE_DEVICE;
  prop.location.id = device;
  return prop;
}

void check_driver(CUresult r, const char* what) {
  if (r == CUDA_ERROR_OUT_OF_MEMORY)
    fail(ErrorCode::OutOfCapacity, "CUDA {} failed: the device is out of memory", what);
  if (r != CUDA_SUCCESS)
    fail(ErrorCode::Cuda, "CUDA {} failed (driver error {})", what, static_cast<int>(r));
}

}  // namespace

GrowingBuffer::~GrowingBuffer() {
  release();
}

void GrowingBuffer::release() {
  const VirtualMemory& vm = VirtualMemory::get();
  if (virtual_) {
    // Each mapping whole (the driver unmaps no part of one), then its memory.
    for (const Mapping& m : mappings_) {
      vm.unmap(reinterpret_cast<CUdeviceptr>(base_) + m.offset, m.bytes);
      vm.release(m.handle);
    }
    if (base_ != nullptr) vm.free(reinterpret_cast<CUdeviceptr>(base_), reserved_);
  } else {
    cudaFree(base_);
  }
  mappings_.clear();
  base_ = nullptr;
  reserved_ = committed_ = 0;
}

void GrowingBuffer::reserve(std::size_t bytes, int device) {
  release();
  device_ = device;
  const VirtualMemory& vm = VirtualMemory::get();
  virtual_ = virtual_memory_allowed() && vm.supported(device);
  if (!virtual_) {
    base_ = allocate_device(std::max<std::size_t>(bytes, 1));
    reserved_ = committed_ = bytes;
    return;
  }
  const CUmemAllocationProp prop = allocation_prop(device);
  std::size_t granularity = 0;
  check_driver(vm.granularity(&granularity, &prop, CU_MEM_ALLOC_GRANULARITY_RECOMMENDED),
               "asking the allocation granularity");
  // Chunks of the recommended granularity: what is committed beyond the need stays below one.
  chunk_ = granularity;
  reserved_ = (std::max<std::size_t>(bytes, 1) + chunk_ - 1) / chunk_ * chunk_;
  CUdeviceptr base = 0;
  check_driver(vm.reserve(&base, reserved_, 0, 0, 0), "reserving device addresses");
  base_ = reinterpret_cast<void*>(base);
}

std::size_t GrowingBuffer::commit(std::size_t bytes, std::size_t keep_free) {
  if (!virtual_ || bytes <= committed_) return committed_;
  const std::size_t target = std::min(reserved_, (bytes + chunk_ - 1) / chunk_ * chunk_);
  if (target <= committed_) return committed_;
  // The whole shortfall as one allocation and one mapping: one call to each driver function
  // whatever the growth. Where the device cannot hold it, what fits with `keep_free` left.
  if (map_more(target - committed_)) return committed_;
  const std::size_t free = free_device_memory();
  if (free <= keep_free) return committed_;
  const std::size_t fits = (free - keep_free) / chunk_ * chunk_;
  if (fits > 0 && fits < target - committed_) map_more(fits);
  return committed_;
}

bool GrowingBuffer::map_more(std::size_t size) {
  const VirtualMemory& vm = VirtualMemory::get();
  const CUmemAllocationProp prop = allocation_prop(device_);
  CUmemGenericAllocationHandle h = 0;
  const CUresult created = vm.create(&h, size, &prop, 0);
  if (created == CUDA_ERROR_OUT_OF_MEMORY) return false;
  check_driver(created, "committing device memory");
  const CUdeviceptr at = reinterpret_cast<CUdeviceptr>(base_) + committed_;
  const CUresult mapped = vm.map(at, size, 0, h, 0);
  if (mapped != CUDA_SUCCESS) vm.release(h);
  check_driver(mapped, "mapping device memory");
  CUmemAccessDesc access{};
  access.location = prop.location;
  access.flags = CU_MEM_ACCESS_FLAGS_PROT_READWRITE;
  const CUresult access_set = vm.set_access(at, size, &access, 1);
  if (access_set != CUDA_SUCCESS) {
    vm.unmap(at, size);
    vm.release(h);
  } else {
    mappings_.push_back({h, committed_, size});
  }
  check_driver(access_set, "enabling access to device memory");
  committed_ += size;
  return true;
}

}  // namespace hivox::cuda
