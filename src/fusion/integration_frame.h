#pragma once
// What the integration kernels read of one frame, set up on the host the same way for every
// driver (the CPU's, and a GPU driver that copies the views' images to the device).

#include <cstdint>
#include <vector>

#include "fusion/fusion_kernels.h"
#include "hivox/fusion/integrator.h"

namespace hivox {

struct IntegrationFrame {
  kernels::DepthFrameView depth;
  kernels::ColorFrameView color;  ///< empty image when no colour is fused
  kernels::IntegrationConstants constants;
};

/// The views and constants for integrating `in` with `params` into a map with `map_params`
/// (its truncation band, and whether it stores colour). When the colour is registered to the
/// depth, `packed_color` receives it as 32-bit words (ColorFrameView::packed) and must outlive
/// the views.
IntegrationFrame integration_frame(const FusionInput& in, const FusionParams& params,
                                   const MapParams& map_params,
                                   std::vector<uint32_t>* packed_color);

}  // namespace hivox
