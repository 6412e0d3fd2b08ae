#include "hivox/fusion/integrator.h"

#include <algorithm>

#include "core/parallel.h"
#include "fusion/fusion_kernels.h"
#include "fusion/integration_frame.h"
#include "hivox/core/atomic.h"
#include "hivox/core/dataset.h"
#include "hivox/core/error.h"
#include "hivox/core/log.h"
#include "map/map_access.h"

namespace hivox {

namespace {

/// Per-thread direct-mapped cache of blocks already handled this frame: neighbouring pixels
/// cross the same blocks, so most hash look-ups are skipped.
class BlockCache {
 public:
  static constexpr int kSlots = 4096;  // ~80 KB: stays in L2
  struct Slot {
    Vec3i pos;
    int32_t level = -1;
    int32_t ptr = kPtrEmpty;
  };
  void reset() { std::fill(std::begin(slots_), std::end(slots_), Slot{}); }
  Slot& slot(int level, const Vec3i& pos) {
    const uint32_t h = block_hash(pos, kSlots - 1) ^ static_cast<uint32_t>(level * 0x9E37);
    return slots_[h & (kSlots - 1)];
  }

 private:
  Slot slots_[kSlots];
};

struct ThreadState {
  BlockCache cache;
  std::vector<BlockKey> missing;
  std::vector<BlockRef> found;
  int64_t valid_pixels = 0;
  /// The most missing blocks worth keeping: what the pool can still take. The list is
  /// de-duplicated when it reaches twice that; keys beyond it are counted, not kept, so that the
  /// lists' memory follows the pool's capacity, not the band's length.
  std::size_t missing_limit = 0;
  int64_t missing_beyond = 0;  ///< distinct missing blocks this thread could not keep

  void add_missing(const BlockKey& key) {
    if (missing.size() >= 2 * missing_limit) {
      std::sort(missing.begin(), missing.end());
      missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
      if (missing.size() > missing_limit) {
        missing_beyond += static_cast<int64_t>(missing.size() - missing_limit);
        missing.resize(missing_limit);
      }
      if (missing.size() >= missing_limit) {  // full: from now on only counted
        ++missing_beyond;
        return;
      }
    }
    missing.push_back(key);
  }
};

/// Stage-one visitor on the CPU: looks a block up (once per thread, thanks to the cache),
/// records it as missing or marks it visible (once per frame, via the per-block stamp).
struct AllocationVisitor {
  const MapView& map;
  ThreadState& state;
  int32_t* stamps;
  int32_t frame;

  int32_t block(int level, const Vec3i& pos) {
    BlockCache::Slot& slot = state.cache.slot(level, pos);
    if (slot.level == level && slot.pos == pos) return slot.ptr;
    const LevelView& lv = map.level[level];
    const int32_t entry = find_entry(lv, pos);
    const int32_t ptr = entry == kNoEntry ? kPtrEmpty : lv.entries[entry].ptr;
    if (ptr == kPtrEmpty) {
      state.add_missing({pos, level});
    } else if (ptr >= 0 && atomic_load(&stamps[ptr]) != frame &&
               atomic_exchange(&stamps[ptr], frame) != frame) {  // load first: no lock if seen
      state.found.push_back({pos, level, entry, ptr});
    }
    slot = {pos, level, ptr};
    return ptr;
  }
};

kernels::DepthFrameView depth_view(const FusionInput& in, const FusionParams& p) {
  kernels::DepthFrameView v;
  v.depth_m = {in.depth_m->data(), in.depth_m->width(), in.depth_m->height()};
  v.camera = in.rig.depth_camera;
  v.min_depth_m = std::max(p.depth_range.min_m, 1e-6f);
  v.max_depth_m = p.depth_range.max_m;
  return v;
}

}  // namespace

struct TsdfIntegrator::Scratch {
  std::vector<ThreadState> threads;
  std::vector<uint32_t> packed_color;  // registered colour as 32-bit words, per frame
  std::vector<int32_t> stamps;         // per pool block: frame counter of the last visit
  int32_t frame = 0;
  std::size_t last_visible = 0;  // blocks the last frame touched (reserved for the next)
};

TsdfIntegrator::TsdfIntegrator(const FusionParams& params)
    : params_(params), scratch_(std::make_unique<Scratch>()) {
  params_.validate();
}
TsdfIntegrator::~TsdfIntegrator() = default;
TsdfIntegrator::TsdfIntegrator(TsdfIntegrator&&) noexcept = default;
TsdfIntegrator& TsdfIntegrator::operator=(TsdfIntegrator&&) noexcept = default;

void validate_input(const FusionInput& in) {
  if (in.depth_m == nullptr || in.depth_m->empty())
    fail(ErrorCode::InvalidArgument, "fusion input: depth image is missing");
  const PinholeCamera& depth = in.rig.depth_camera;
  depth.validate("depth camera");
  if (in.depth_m->width() != depth.width || in.depth_m->height() != depth.height)
    fail(ErrorCode::InvalidArgument, "fusion input: depth image is {}x{} but the camera is {}x{}",
         in.depth_m->width(), in.depth_m->height(), depth.width, depth.height);
  if (in.color != nullptr && !in.color->empty()) {
    const PinholeCamera& color = in.rig.color_camera;
    color.validate("colour camera");
    if (in.color->width() != color.width || in.color->height() != color.height)
      fail(ErrorCode::InvalidArgument,
           "fusion input: colour image is {}x{} but the colour camera is {}x{}", in.color->width(),
           in.color->height(), color.width, color.height);
  }
}

Allocation TsdfIntegrator::allocate(VoxelBlockMap& map, const FusionInput& in) {
  validate_input(in);
  return dispatch(map.device(), "allocation", [&] { return allocate_cpu(map, in); });
}

Allocation TsdfIntegrator::allocate_cpu(VoxelBlockMap& map, const FusionInput& in) {
  Scratch& s = *scratch_;
  const MapView view = map.view();
  if (static_cast<int64_t>(s.stamps.size()) != map.block_capacity()) {
    s.stamps.assign(static_cast<std::size_t>(map.block_capacity()), -1);
    s.frame = 0;
  }
  // Frame counter for visibility stamps; on wrap-around, reset the stamps.
  if (++s.frame == INT32_MAX) {
    std::fill(s.stamps.begin(), s.stamps.end(), -1);
    s.frame = 0;
  }
  const int32_t frame = s.frame;
  const auto free_blocks = static_cast<std::size_t>(map.block_capacity() - map.blocks_in_use());
  const int threads = thread_count();
  s.threads.resize(static_cast<std::size_t>(threads));
  const kernels::DepthFrameView depth = depth_view(in, params_);
  const Rigid3f T_wc = to_rigid3f(in.T_wc);
  const float mu = map.params().truncation_m;
  const int height = depth.depth_m.height, width = depth.depth_m.width;

  // Stage 1: every valid pixel walks its band; rows in chunks keep neighbouring pixels (which
  // cross the same blocks) on one thread and its cache.
  parallel_team([&](const ThreadTeam& team) {
    ThreadState& ts = s.threads[static_cast<std::size_t>(team.index())];
    ts.cache.reset();
    ts.missing.clear();
    ts.found.clear();
    ts.valid_pixels = 0;
    ts.missing_limit = free_blocks;
    ts.missing_beyond = 0;
    AllocationVisitor visitor{view, ts, s.stamps.data(), frame};
    team.for_each(
        height,
        [&](int64_t row) {
          const int y = static_cast<int>(row);
          for (int x = 0; x < width; ++x) {
            Vec3f a, b;
            if (!kernels::band_segment(depth, T_wc, mu, x, y, &a, &b)) continue;
            ++ts.valid_pixels;
            kernels::walk_segment(view, a, b, visitor);
          }
        },
        CpuSchedule::dynamic(16));
  });

  Allocation out;
  AllocationStats& stats = out.stats;
  std::vector<BlockRef>& visible = out.visible_blocks;
  visible.reserve(s.last_visible + s.last_visible / 4);
  std::vector<BlockKey> missing;
  int64_t beyond = 0;
  for (const ThreadState& ts : s.threads) {
    missing.insert(missing.end(), ts.missing.begin(), ts.missing.end());
    visible.insert(visible.end(), ts.found.begin(), ts.found.end());
    stats.valid_pixels += ts.valid_pixels;
    beyond += ts.missing_beyond;
  }
  // Stage 2: de-duplicate (threads may have recorded the same block) and insert.
  std::sort(missing.begin(), missing.end());
  missing.erase(std::unique(missing.begin(), missing.end()), missing.end());
  const std::size_t before = visible.size();
  const InsertStats inserted = map.insert_blocks(missing, &visible);
  for (std::size_t i = before; i < visible.size(); ++i) s.stamps[visible[i].ptr] = frame;
  stats.new_blocks = inserted.inserted;
  stats.dropped_blocks = inserted.dropped() + beyond;
  if (beyond > 0) {
    MapAccess::add_dropped_blocks(map, beyond);
    log::warn_once("map.pool_full",
                   "voxel block pool is full ({} blocks): new blocks are being dropped and counted "
                   "in stats (dropped_blocks); raise --max-blocks",
                   map.block_capacity());
  }
  s.last_visible = visible.size();
  return out;
}

FusionInput fusion_input(const CameraRig& rig, const RgbdFrame& frame, const Pose& T_wc) {
  FusionInput in;
  in.depth_m = &frame.depth_m;
  if (!frame.color.empty()) in.color = &frame.color;
  in.rig = rig;
  in.T_wc = T_wc;
  return in;
}

IntegrationFrame integration_frame(const FusionInput& in, const FusionParams& params,
                                   const MapParams& map_params,
                                   std::vector<uint32_t>* packed_color) {
  IntegrationFrame f;
  f.depth = depth_view(in, params);
  if (params.integrate_color && in.color != nullptr && !in.color->empty() &&
      map_params.store_color) {
    kernels::ColorFrameView& color = f.color;
    color.image = {in.color->data(), in.color->width(), in.color->height()};
    color.camera = in.rig.color_camera;
    color.T_color_depth = to_rigid3f(in.rig.T_color_depth);
    color.registered = in.rig.color_registered();
    if (color.registered) {
      packed_color->resize(in.color->size());
      const Rgb8* src = in.color->data();
      uint32_t* packed = packed_color->data();
      parallel_for(static_cast<int64_t>(packed_color->size()),
                   [&](int64_t i) { packed[i] = kernels::pack_rgb(src[i]); });
      color.packed = packed;
    }
  }
  kernels::IntegrationConstants& k = f.constants;
  k.T_cw = to_rigid3f(in.T_wc.inverse());
  k.mu_m = map_params.truncation_m;
  k.inv_mu = 1.0f / map_params.truncation_m;
  k.max_weight = params.max_weight;
  k.bilinear_depth = params.depth_sampling == DepthSampling::Bilinear;
  return f;
}

void TsdfIntegrator::integrate(VoxelBlockMap& map, const FusionInput& in,
                               std::span<const BlockRef> blocks) {
  validate_input(in);
  // The blocks come from the caller now: each must be what the map holds at its pool index.
  const int32_t high_water = map.block_high_water();
  for (const BlockRef& b : blocks) {
    const bool held = b.ptr >= 0 && b.ptr < high_water && map.block_meta(b.ptr).level == b.level &&
                      map.block_meta(b.ptr).pos == b.pos;
    if (!held)
      fail(ErrorCode::InvalidArgument,
           "integrate: block ({}, {}, {}) of level {} is not pool block {} of this map", b.pos.x,
           b.pos.y, b.pos.z, b.level, b.ptr);
  }
  const MutableMapView view = MapAccess::storage(map);
  const IntegrationFrame f = integration_frame(in, params_, map.params(), &scratch_->packed_color);
  // One block per item; on a GPU the frame's images and the block list must be device copies.
  const BlockRef* block = blocks.data();
  parallel_for(
      map.device(), static_cast<int64_t>(blocks.size()),
      [=] HIVOX_HD(int64_t i) {
        const BlockRef& b = block[i];
        kernels::integrate_block(view, b.level, b.pos, b.ptr, f.depth, f.color, f.constants);
      },
      CpuSchedule::dynamic(16));
}

Allocation TsdfIntegrator::fuse(VoxelBlockMap& map, const FusionInput& in) {
  Allocation a = allocate(map, in);
  integrate(map, in, a.visible_blocks);
  return a;
}

}  // namespace hivox
