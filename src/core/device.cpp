#include "hivox/core/device.h"

#include <charconv>

#include "core/parallel.h"
#include "hivox/core/error.h"

namespace hivox {

Device Device::parse(std::string_view name) {
  if (name == "cpu") return cpu();
  if (name == "cuda") return cuda(0);
  if (name.starts_with("cuda:")) {
    const std::string_view digits = name.substr(5);
    int index = -1;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), index);
    if (ec == std::errc() && end == digits.data() + digits.size() && index >= 0) return cuda(index);
  }
  fail(ErrorCode::InvalidArgument, "device must be 'cpu', 'cuda' or 'cuda:N', got '{}'", name);
}

std::string Device::to_string() const {
  return is_cpu() ? std::string("cpu") : fmt::format("cuda:{}", index);
}

std::string DeviceInfo::to_string() const {
  if (device.is_cpu()) return name;
  constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;
  return fmt::format(
      "{}: {:.1f} GiB, {:.1f} GiB free, compute capability {}.{}, {} multiprocessors", name,
      static_cast<double>(memory_bytes) / kGiB, static_cast<double>(free_bytes) / kGiB,
      compute_major, compute_minor, multiprocessors);
}

void Device::require_available() const {
  if (is_cpu()) return;
  fail(ErrorCode::Unsupported,
       "device {}: this operation runs on the CPU only; runs on a GPU go through "
       "hivox::make_reconstruction in builds with -DHIVOX_WITH_CUDA=ON (docs/cuda.md); use "
       "--device cpu",
       to_string());
}

void cuda_launch_failed(const Device& device, const char* message) {
  fail(ErrorCode::Cuda, "a launch on {} failed: {}", device.to_string(), message);
}

void no_implementation(const Device& device, std::string_view operation) {
  fail(ErrorCode::Unsupported, "{} has no implementation on device {} in this build", operation,
       device.to_string());
}

}  // namespace hivox
