#include "hivox/run/devices.h"

#include <fmt/format.h>

#include "hivox/core/error.h"
#include "hivox/core/threads.h"
#if defined(HIVOX_WITH_CUDA)
#include "hivox/cuda/gpu_reconstruction.h"
#endif

namespace hivox {

std::optional<DeviceInfo> describe_device(const Device& device) {
  if (device.is_cpu()) {
    DeviceInfo cpu;
    cpu.name = fmt::format("{} thread{} (OpenMP)", thread_count(), thread_count() == 1 ? "" : "s");
    return cpu;
  }
#if defined(HIVOX_WITH_CUDA)
  return cuda::describe_cuda_device(device.index);
#else
  return std::nullopt;
#endif
}

void check_device(const Device& device) {
  if (device.is_cpu()) return;
#if defined(HIVOX_WITH_CUDA)
  cuda::require_cuda_device(device);
#else
  fail(ErrorCode::Unsupported,
       "device {}: this build of hivox has no CUDA loop (build it with -DHIVOX_WITH_CUDA=ON, "
       "docs/cuda.md); use --device cpu",
       device.to_string());
#endif
}

DeviceList list_devices() {
  DeviceList list;
  list.devices.push_back(*describe_device(Device::cpu()));
#if defined(HIVOX_WITH_CUDA)
  list.cuda_built = true;
  for (const DeviceInfo& d : cuda::cuda_devices()) list.devices.push_back(d);
  if (list.devices.size() == 1)
    list.cuda_note = "no CUDA device found (no driver or no GPU): runs use --device cpu";
#else
  list.cuda_note =
      "not in this build (build hivox with -DHIVOX_WITH_CUDA=ON, docs/cuda.md): runs use "
      "--device cpu";
#endif
  return list;
}

}  // namespace hivox
