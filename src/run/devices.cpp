#include "hivox/run/devices.h"

#include <fmt/format.h>

#include "hivox/core/threads.h"
#if defined(HIVOX_WITH_CUDA)
#include "hivox/cuda/gpu_reconstruction.h"
#endif

namespace hivox {

DeviceList list_devices() {
  DeviceList list;
  DeviceInfo cpu;
  cpu.device = Device::cpu();
  cpu.name = fmt::format("{} thread{} (OpenMP)", thread_count(), thread_count() == 1 ? "" : "s");
  list.devices.push_back(cpu);
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
