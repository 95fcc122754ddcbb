// Segmentations on the host: a label volume on its image's grid (io/
// label_volume.h loads one) and how each label shows (Scene.labels).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/transfer_function.h"
#include "core/vec.h"

namespace cinevol {

// Immutable once loaded: shared by every session of its volume.
struct LabelVolume {
  Vec3i dims;                          // the image's
  std::vector<std::uint16_t> labels;   // one per image voxel, x fastest
  std::map<int, std::string> names;    // from the label table
  std::map<int, std::uint64_t> voxels; // voxels per label value present
  std::string source;                  // the file it came from
  std::string note;                    // how it was fitted to the image's grid, when it was
  int max_label() const { return voxels.empty() ? 0 : voxels.rbegin()->first; }
};

struct LabelStyle {
  bool visible = true;
  float opacity_scale = 1.0f;  // multiplies extinction and opacity
  bool has_color = false;
  Vec3f color;                 // diffuse colour, where has_color
  int transfer = -1;           // index into LabelSetup::transfer_functions; -1: the image's
};

struct LabelSetup {
  std::map<int, LabelStyle> styles;
  bool show_unlisted = true;  // labels without a style: the image's transfer function, else hidden
  std::vector<TransferFunction> transfer_functions;  // the labels' own
  const LabelStyle& StyleOf(int label) const {
    static const LabelStyle kShown{}, kHidden = [] {
      LabelStyle hidden;
      hidden.visible = false;
      return hidden;
    }();
    const auto it = styles.find(label);
    return it != styles.end() ? it->second : (show_unlisted ? kShown : kHidden);
  }
};

// At most this many labels may have their own transfer function.
inline constexpr int kMaxLabelTransferFunctions = 8;

}  // namespace cinevol
