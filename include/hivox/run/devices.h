#pragma once
/// @file
/// What can run hivox here: the CPU, and in builds with the CUDA loop (-DHIVOX_WITH_CUDA=ON) the
/// CUDA devices present. `hivox devices` prints it; Python's `hivox.devices()` returns it.

#include <optional>
#include <string>
#include <vector>

#include "hivox/core/device.h"

namespace hivox {

struct DeviceList {
  std::vector<DeviceInfo> devices;  ///< the CPU first, then the CUDA devices by index
  bool cuda_built = false;          ///< this build has the CUDA loop
  /// Where no CUDA device is listed, why (not in this build, or none found), with what to do.
  std::string cuda_note;
};

/// The devices of this build and machine. Starts the CUDA runtime on each GPU (to ask for its free
/// memory): a fraction of a second each.
DeviceList list_devices();

/// Throws `Error(Unsupported)`, one line naming `device` and what this build or machine has
/// instead, unless runs can use it here.
void check_device(const Device& device);

/// `device` described as list_devices() lists it; nullopt for a CUDA device this build or machine
/// does not have.
std::optional<DeviceInfo> describe_device(const Device& device);

}  // namespace hivox
