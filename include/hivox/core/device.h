#pragma once
/// @file
/// Where a map lives and its stages run. Every operation (allocation, integration, refinement,
/// raycasting, the ICP reduction, meshing) dispatches on it in one place; this build runs them on
/// the CPU, and a CUDA implementation plugs in behind the same operations.

#include <cstdint>
#include <string>
#include <string_view>

namespace hivox {

enum class DeviceType { Cpu, Cuda };

struct Device {
  DeviceType type = DeviceType::Cpu;
  int index = 0;  ///< which CUDA device (0 for the CPU)

  static Device cpu() { return {}; }
  static Device cuda(int index = 0) { return {DeviceType::Cuda, index}; }
  /// Parses "cpu", "cuda" or "cuda:N"; throws `Error(InvalidArgument)` otherwise.
  static Device parse(std::string_view name);

  bool is_cpu() const { return type == DeviceType::Cpu; }
  /// "cpu", "cuda:0", ...
  std::string to_string() const;
  /// Throws `Error(Unsupported)` when this build cannot run hivox on the device (CUDA: built
  /// without it, or no such device), naming the device and what to do.
  void require_available() const;
  bool operator==(const Device&) const = default;
};

/// A device a reconstruction can run on (ReconstructionParams::device), as `hivox devices`
/// lists it (hivox::list_devices).
struct DeviceInfo {
  Device device;
  /// The GPU's name; for the CPU, the threads the loop runs on.
  std::string name;
  int64_t memory_bytes = 0;                  ///< a GPU's memory (0 for the CPU)
  int64_t free_bytes = 0;                    ///< of it, free now
  int compute_major = 0, compute_minor = 0;  ///< a GPU's compute capability
  int multiprocessors = 0;                   ///< a GPU's

  /// The name; for a GPU followed by ": 139.8 GiB, 137.2 GiB free, compute capability 9.0, 132
  /// multiprocessors".
  std::string to_string() const;
};

/// Throws `Error(Unsupported)`: `operation` has no implementation on `device` in this build.
/// The fallback of every operation's dispatch.
[[noreturn]] void no_implementation(const Device& device, std::string_view operation);

}  // namespace hivox
