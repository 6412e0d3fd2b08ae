#include "hivox/core/dataset.h"

namespace hivox {

std::string_view to_string(DatasetLayout layout) {
  switch (layout) {
    case DatasetLayout::Tum:
      return "TUM";
    case DatasetLayout::SevenScenes:
      return "7-Scenes";
    case DatasetLayout::InfiniTam:
      return "InfiniTAM";
    case DatasetLayout::Open3d:
      return "Open3D";
    case DatasetLayout::ImageFolder:
      return "image folder";
    case DatasetLayout::Replica:
      return "Replica";
    case DatasetLayout::ScanNet:
      return "ScanNet";
    case DatasetLayout::Synthetic:
      return "synthetic";
  }
  return "unknown";
}

}  // namespace hivox
