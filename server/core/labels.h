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

// Voxels the segmentation leaves at 0 that belong to something all the same:
// the partial-volume shell around labelled voxels (one voxel, the 26
// neighbours), or the CT's table and its rim (io/table_finder.h). Each has a
// value of its own above every label, so the renderer's one 16-bit lookup
// finds them; to everything else they are label 0.
struct DerivedLabel {
  enum class Kind : std::uint8_t { kShell, kTable };
  Kind kind = Kind::kShell;
  std::vector<std::uint16_t> touches;  // kShell: the labels it touches, ascending
};

// Immutable once loaded: shared by every session of its volume.
struct LabelVolume {
  Vec3i dims;                          // the image's
  std::vector<std::uint16_t> labels;   // one value per image voxel, x fastest: a label or a derived value
  std::map<int, std::string> names;    // from the label table (a DICOM SEG's segment labels)
  std::map<int, Vec3f> colors;         // a DICOM SEG's recommended display colours: sRGB, each in [0, 1]
  std::map<int, std::uint64_t> voxels; // voxels per label present (derived values count as 0)
  std::string source;                  // the file it came from
  std::string note;                    // how it was fitted to the image's grid, when it was
  // False where no segmentation is loaded and the values only mark the table.
  bool segmentation = true;
  // Values from first_derived on: derived[value - first_derived].
  int first_derived = 0;
  std::vector<DerivedLabel> derived;
  std::uint64_t table_voxels = 0;  // voxels with the table's value: the table and its rim
  std::string table_note;          // what the table search found (TableMask::note)

  int max_label() const { return voxels.empty() ? 0 : voxels.rbegin()->first; }
  // Values stored: labels up to max_label, then the derived ones.
  int value_count() const { return derived.empty() ? max_label() + 1 : first_derived + int(derived.size()); }
  // The table's value; -1 without one.
  int table_value() const {
    for (std::size_t i = 0; i < derived.size(); ++i) {
      if (derived[i].kind == DerivedLabel::Kind::kTable) return first_derived + int(i);
    }
    return -1;
  }
  // The label a stored value stands for: derived values are label 0.
  int LabelOf(int value) const { return derived.empty() || value < first_derived ? value : 0; }
};

struct LabelStyle {
  bool visible = true;
  float opacity_scale = 1.0f;  // multiplies extinction and opacity
  bool has_color = false;
  Vec3f color;                 // diffuse colour, where has_color
  int transfer = -1;           // index into LabelSetup::transfer_functions; -1: the image's
  bool hidden() const { return !visible || !(opacity_scale > 0.0f); }
};

struct LabelSetup {
  std::map<int, LabelStyle> styles;
  bool show_unlisted = true;  // labels without a style: the image's transfer function, else hidden
  bool remove_table = false;  // hides the table and its rim (Scene.labels.remove_table)
  std::vector<TransferFunction> transfer_functions;  // the labels' own
  const LabelStyle& StyleOf(int label) const {
    const auto it = styles.find(label);
    return it != styles.end() ? it->second : (show_unlisted ? Shown() : Hidden());
  }
  // How a stored value of `labels` shows: a label by its style; a shell as
  // label 0, hidden with any label it touches; the table as label 0, hidden
  // where the setup removes it.
  const LabelStyle& StyleOfValue(const LabelVolume& labels, int value) const {
    if (labels.derived.empty() || value < labels.first_derived) return StyleOf(value);
    const DerivedLabel& d = labels.derived[std::size_t(value - labels.first_derived)];
    if (d.kind == DerivedLabel::Kind::kTable) return remove_table ? Hidden() : StyleOf(0);
    for (std::uint16_t label : d.touches) {
      if (StyleOf(label).hidden()) return Hidden();
    }
    return StyleOf(0);
  }
  // Whether any stored value of `labels` shows otherwise than the image's
  // transfer function alone: renderers look labels up only then.
  bool ChangesAnything(const LabelVolume& labels) const {
    for (int v = 0; v < labels.value_count(); ++v) {
      const LabelStyle& s = StyleOfValue(labels, v);
      if (s.hidden() || s.opacity_scale != 1.0f || s.has_color || s.transfer >= 0) return true;
    }
    return false;
  }

 private:
  static const LabelStyle& Shown() {
    static const LabelStyle kShown{};
    return kShown;
  }
  static const LabelStyle& Hidden() {
    static const LabelStyle kHidden = [] {
      LabelStyle hidden;
      hidden.visible = false;
      return hidden;
    }();
    return kHidden;
  }
};

// At most this many labels may have their own transfer function.
inline constexpr int kMaxLabelTransferFunctions = 8;

}  // namespace cinevol
