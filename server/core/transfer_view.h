// The transfer-function tables as kernels see them (core/transfer_function.h
// builds one): extinction and material channels by linear interpolation.
// Table 0 is the image's; labels with a transfer function of their own
// (core/label_view.h) read the tables after it, kEntries each.
#pragma once

#include "core/hd.h"
#include "core/sampling.h"
#include "core/transfer_function.h"
#include "core/vec.h"

namespace cinevol {

struct Material {
  Vec3f diffuse;
  float opacity;
  Vec3f specular;
  float roughness;
};

struct TransferView {
  static constexpr int kEntries = TransferTable::kEntries;
  const float* sigma_t = nullptr;
  const Vec4f* diffuse_opacity = nullptr;
  const Vec4f* specular_roughness = nullptr;
  const Vec4f* emission = nullptr;
  float entry_scale = 0, entry_offset = 0;  // table entry = stored voxel * scale + offset
  float gradient_factor = 0;                 // >= 0
  float gradient_normaliser = 0;             // |grad stored| * this = normalised gradient magnitude
  float phase_g = 0;
  // Extinction (per mm) never exceeds this: the tables are clamped to it, and
  // so are labels' scaled extinctions (render/scene_data.h, kMaxOpticalDepthPerVoxel).
  float max_sigma_t = 3.4e38f;

  // Fractional table position of a stored voxel value.
  CINEVOL_HD float Entry(float stored) const {
    return Clamp(stored * entry_scale + entry_offset, 0.0f, float(kEntries - 1));
  }

  CINEVOL_HD float SigmaT(float entry, int table = 0) const {
    const Lerp l = At(entry, table);
    const float a = LoadReadOnly(sigma_t + l.i), b = LoadReadOnly(sigma_t + l.i + 1);
    return a + (b - a) * l.t;
  }

  CINEVOL_HD Material MaterialAt(float entry, int table = 0) const {
    const Lerp l = At(entry, table);
    const Vec4f d = Mix(diffuse_opacity, l.i, l.t), s = Mix(specular_roughness, l.i, l.t);
    return {{d.x, d.y, d.z}, d.w, {s.x, s.y, s.z}, s.w};
  }

  CINEVOL_HD Vec3f Emission(float entry, int table = 0) const {
    const Lerp l = At(entry, table);
    return Xyz(Mix(emission, l.i, l.t));
  }

 private:
  // The array index of the entry below `entry` in `table`, and the fraction past it.
  struct Lerp {
    int i;
    float t;
  };
  CINEVOL_HD static Lerp At(float entry, int table) {
    const int below = MinInt(static_cast<int>(entry), kEntries - 2);
    return {below + table * kEntries, entry - float(below)};
  }

  CINEVOL_HD static Vec4f Mix(const Vec4f* table, int i, float t) {
    const Vec4f a = LoadReadOnly(table + i), b = LoadReadOnly(table + i + 1);
    return {a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.z + (b.z - a.z) * t, a.w + (b.w - a.w) * t};
  }
};

}  // namespace cinevol
