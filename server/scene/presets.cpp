// Presets onto volumes, default presets by kind, and the preset scene.
#include "scene/presets.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "core/error.h"
#include "scene/scene_builder.h"
#include "scene/scene_frame.h"
#include "scene/volume_kind.h"

namespace cinevol {
namespace {

const PresetDefinition* Find(std::string_view name) {
  for (const PresetDefinition& p : PresetLibrary()) {
    if (name == p.name) return &p;
  }
  return nullptr;
}

void SetColor(v1::Color* c, PresetColor rgb) {
  c->set_r(rgb.r);
  c->set_g(rgb.g);
  c->set_b(rgb.b);
}

void SetVec(v1::Vec3* v, Vec3f p) {
  v->set_x(p.x);
  v->set_y(p.y);
  v->set_z(p.z);
}

// The extent of the volume's box along a world direction.
float ExtentAlong(const Volume& volume, Vec3f direction) {
  const Vec3f e = volume.extent_mm();
  return std::abs(direction.x) * e.x + std::abs(direction.y) * e.y + std::abs(direction.z) * e.z;
}

// Anterior, as radiologists start; but a thin stack of axial slices (a slab
// less than a quarter as deep as it is wide) is seen as PACS shows axial
// images: from the feet, anterior up, the patient's left on the right.
v1::NamedView DefaultView(const Volume& volume) {
  const float superior = ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {0, 0, 1}));
  const float lateral = std::min(ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {1, 0, 0})),
                                 ExtentAlong(volume, PatientToWorld(volume.metadata().direction, {0, 1, 0})));
  return superior < 0.25f * lateral ? v1::INFERIOR : v1::ANTERIOR;
}

// Vec3i has no arithmetic in core (device code needs none).
Vec3i MinI(Vec3i a, Vec3i b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
Vec3i MaxI(Vec3i a, Vec3i b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
Vec3i AddI(Vec3i a, int k) { return {a.x + k, a.y + k, a.z + k}; }

// The blocks (Volume::block_ranges) holding subject, split into 6-connected
// pieces; per piece its blocks, its bounding box in blocks and its largest value.
struct Piece {
  std::vector<std::size_t> blocks;
  Vec3i lo{INT32_MAX, INT32_MAX, INT32_MAX}, hi{-1, -1, -1};
  float max_value = -INFINITY;
};

std::vector<Piece> SubjectPieces(const Volume& volume, float threshold) {
  const Vec3i n = volume.block_counts();
  const auto& ranges = volume.block_ranges();
  std::vector<int> piece_of(ranges.size(), -1);
  std::vector<Piece> pieces;
  auto index = [&](Vec3i b) { return (std::size_t(b.z) * n.y + b.y) * n.x + b.x; };
  for (std::size_t seed = 0; seed < ranges.size(); ++seed) {
    if (piece_of[seed] >= 0 || !(ranges[seed].hi > threshold)) continue;
    Piece piece;
    std::vector<std::size_t> stack{seed};
    piece_of[seed] = int(pieces.size());
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      const Vec3i b{int(i % n.x), int(i / n.x % n.y), int(i / (std::size_t(n.x) * n.y))};
      piece.blocks.push_back(i);
      piece.lo = MinI(piece.lo, b), piece.hi = MaxI(piece.hi, b);
      piece.max_value = std::max(piece.max_value, ranges[i].hi);
      for (int a = 0; a < 3; ++a) {
        for (int step : {-1, 1}) {
          Vec3i m = b;
          m[a] += step;
          if (m[a] < 0 || m[a] >= n[a]) continue;
          const std::size_t j = index(m);
          if (piece_of[j] >= 0 || !(ranges[j].hi > threshold)) continue;
          piece_of[j] = int(pieces.size());
          stack.push_back(j);
        }
      }
    }
    pieces.push_back(std::move(piece));
  }
  return pieces;
}

// A stereotactic localizer's fiducials (or a specimen holder's rods): a
// piece apart from the subject, thin (at most kThinBlocks across) and bright
// (reaching the window's top), lying within kEdgeFraction of a face.
constexpr int kThinBlocks = 3;
constexpr float kEdgeFraction = 0.2f;

bool IsEdgeFiducial(const Piece& p, Vec3i n, float bright) {
  const Vec3i size = AddI(Vec3i{p.hi.x - p.lo.x, p.hi.y - p.lo.y, p.hi.z - p.lo.z}, 1);
  if (std::min({size.x, size.y, size.z}) > kThinBlocks || !(p.max_value >= bright)) return false;
  for (int a = 0; a < 3; ++a) {
    const int band = std::max(2, int(kEdgeFraction * float(n[a])));
    if (p.hi[a] < band || p.lo[a] >= n[a] - band) return true;
  }
  return false;
}

// The box of blocks holding the subject less its edge fiducials, or none
// where no fiducial lies outside it.
std::optional<std::pair<Vec3i, Vec3i>> SubjectBlocks(const Volume& volume) {
  const ValueWindow w = AutoWindow(volume);
  std::vector<Piece> pieces = SubjectPieces(volume, w.lo);
  if (pieces.size() < 2) return std::nullopt;
  const auto largest = std::max_element(pieces.begin(), pieces.end(), [](const Piece& a, const Piece& b) {
    return a.blocks.size() < b.blocks.size();
  });
  const Vec3i n = volume.block_counts();
  Vec3i lo{INT32_MAX, INT32_MAX, INT32_MAX}, hi{-1, -1, -1};
  bool dropped = false;
  for (auto it = pieces.begin(); it != pieces.end(); ++it) {
    if (it != largest && IsEdgeFiducial(*it, n, w.hi)) {
      dropped = true;
      continue;
    }
    lo = MinI(lo, it->lo), hi = MaxI(hi, it->hi);
  }
  if (!dropped) return std::nullopt;
  return std::pair{MaxI(AddI(lo, -1), Vec3i{0, 0, 0}), MinI(AddI(hi, 1), AddI(n, -1))};
}

// MR and data of unknown kind: a crop box around the subject that leaves out
// thin bright pieces at the volume's edges (a localizer frame), in patient
// coordinates along the volume's axes. CT's couch is left to table removal.
void CropToSubject(const Volume& volume, v1::Scene& scene) {
  const v1::VolumeKind kind = JudgeVolumeKind(volume).kind;
  if (kind != v1::MR && kind != v1::OTHER) return;
  const auto blocks = SubjectBlocks(volume);
  if (!blocks) return;
  const Vec3f block_mm = volume.spacing_mm() * float(Volume::kBlockSize);
  const Vec3f half = volume.extent_mm() * 0.5f;
  const Vec3f lo = Max(ToFloat(blocks->first) * block_mm - half, -half);
  const Vec3f hi = Min(ToFloat(AddI(blocks->second, 1)) * block_mm - half, half);
  const VolumePlacement placement = VolumePlacement::Of(volume);
  v1::CropBox* box = scene.mutable_clipping()->mutable_crop_box();
  SetVec(box->mutable_center(), placement.PointToPatient((lo + hi) * 0.5f));
  SetVec(box->mutable_size(), hi - lo);
  SetVec(box->mutable_axis_x(), placement.DirectionToPatient({1, 0, 0}));
  SetVec(box->mutable_axis_y(), placement.DirectionToPatient({0, 1, 0}));
}

}  // namespace

std::vector<std::string> PresetNames() {
  std::vector<std::string> names;
  for (const PresetDefinition& p : PresetLibrary()) names.emplace_back(p.name);
  return names;
}

bool IsPreset(std::string_view name) { return Find(name) != nullptr; }

const PresetDefinition& FindPreset(std::string_view name) {
  const PresetDefinition* preset = Find(name);
  if (!preset) {
    throw InputError(fmt::format("unknown transfer-function preset '{}': use {}", name,
                                 fmt::join(PresetNames(), ", ")));
  }
  return *preset;
}

namespace {

// The mean count of the bins within 25 HU of `hu`: a density smoothed over
// 50 HU, so that the bin width (the volume's range / 256) matters little.
float SmoothedCount(const ValueHistogram& h, float hu) {
  const int first = h.BinOf(hu - 25.0f), last = h.BinOf(hu + 25.0f);
  double sum = 0;
  for (int b = first; b <= last; ++b) sum += double(h.counts[b]);
  return float(sum / double(last - first + 1));
}

}  // namespace

BloodPool FindBloodPool(const ValueHistogram& h) {
  // Only CT in HU spans air and the blood pool; a bin must be narrower than
  // the pool is wide.
  if (h.counts.size() != ValueHistogram::kBins || h.min_value > -500.0f || h.max_value < 700.0f ||
      h.BinWidth() > 40.0f) {
    return {};
  }
  // The highest local maximum between 150 and 700 HU: soft tissue's tail
  // falls through 150 HU, so a maximum there is no pool.
  constexpr float kStep = 10.0f, kFrom = 150.0f, kTo = 700.0f, kAround = 30.0f;
  float peak = 0, peak_count = 0;
  for (float v = kFrom + kAround; v <= kTo; v += kStep) {
    const float c = SmoothedCount(h, v);
    if (c > peak_count && c >= SmoothedCount(h, v - kAround) && c >= SmoothedCount(h, v + kAround))
      peak = v, peak_count = c;
  }
  if (!(peak_count > 0)) return {};
  // A pool stands well above the valley between it and soft tissue, and
  // falls away above it.
  float valley = peak_count;
  for (float v = 100.0f; v < peak; v += kStep) valley = std::min(valley, SmoothedCount(h, v));
  if (valley > 0.75f * peak_count) return {};
  float top = peak;
  while (top < h.max_value && SmoothedCount(h, top) > 0.2f * peak_count) top += kStep;
  if (top - peak < kStep || SmoothedCount(h, peak + 150.0f) > 0.5f * peak_count) return {};
  return {peak, top};
}

float FindDensePhase(const ValueHistogram& h, float lo) {
  // Otsu's threshold again, on the subject's voxels alone.
  const int first = h.BinOf(lo);
  double total = 0, sum = 0;
  for (int b = first; b < ValueHistogram::kBins; ++b) total += double(h.counts[b]), sum += double(h.counts[b]) * b;
  if (!(total > 0)) return NAN;
  double weight_low = 0, sum_low = 0, best = -1;
  int split = first;
  for (int b = first; b < ValueHistogram::kBins - 1; ++b) {
    weight_low += double(h.counts[b]);
    sum_low += double(h.counts[b]) * b;
    const double weight_high = total - weight_low;
    if (weight_low <= 0 || weight_high <= 0) continue;
    const double gap = sum_low / weight_low - (sum - sum_low) / weight_high;
    if (const double between = weight_low * weight_high * gap * gap; between > best) best = between, split = b + 1;
  }
  // A skeleton: a small phase, far brighter than the rest of the subject,
  // which is one tissue (a compact peak, not a spread of values).
  double low = 0, low_sum = 0, low_sq = 0, high = 0, high_sum = 0;
  for (int b = first; b < ValueHistogram::kBins; ++b) {
    const double c = double(h.counts[b]), v = double(h.BinStart(b)) + 0.5 * h.BinWidth() - lo;
    if (b < split) {
      low += c, low_sum += c * v, low_sq += c * v * v;
    } else {
      high += c, high_sum += c * v;
    }
  }
  if (!(low > 0 && high > 0)) return NAN;
  const double low_mean = low_sum / low, low_spread = std::sqrt(std::max(0.0, low_sq / low - low_mean * low_mean));
  const bool small = high <= kDensePhaseMaxFraction * total;
  const bool far = high_sum / high >= kDensePhaseContrast * low_mean;
  const bool one_tissue = low_spread <= kDensePhaseMaxSpread * low_mean;
  return small && far && one_tissue ? h.BinStart(split) : NAN;
}

ValueWindow AutoWindow(const ValueHistogram& histogram, float voxel_mm) {
  ValueWindow w;
  w.lo = histogram.OtsuThreshold();
  w.hi = histogram.Percentile(0.995, w.lo);
  // A constant volume's window is one unit wide, or where that is below the
  // value's precision, a millionth of the value (as its transfer table's).
  if (!(w.hi > w.lo))
    w.hi = histogram.max_value > w.lo ? histogram.max_value : w.lo + std::max(1.0f, std::abs(w.lo) * 1e-6f);
  w.dense = FindDensePhase(histogram, w.lo);
  if (!(w.dense > w.lo && w.dense < w.hi)) w.dense = NAN;
  const BloodPool pool = FindBloodPool(histogram);
  w.blood = pool.peak, w.blood_top = pool.top;
  w.voxel_mm = voxel_mm > 0 ? voxel_mm : 1.0f;
  return w;
}

ValueWindow AutoWindow(const Volume& volume) {
  return AutoWindow(volume.histogram(), MinComponent(volume.spacing_mm()));
}

namespace {

// ContrastRule::kAboveBloodPool: the ramp up to the first point of full
// opacity starts at the pool's top and spans kAboveBloodPoolSpan of its
// width (bone that shows above the pool is cortex, which is thin); points
// beyond it move with it.
constexpr float kAboveBloodPoolSpan = 0.6f;

float AboveBloodPool(const PresetDefinition& preset, float hu, float top) {
  const float start = preset.points.front().value;
  if (top <= start) return hu;
  float full = preset.points.back().value;
  for (const PresetPoint& p : preset.points) {
    if (p.opacity >= 1.0f) {
      full = p.value;
      break;
    }
  }
  if (hu <= full) return top + (hu - start) * kAboveBloodPoolSpan;
  return hu + (top + (full - start) * kAboveBloodPoolSpan - full);
}

// A HU value of a preset on this volume's blood pool (ContrastRule).
float OnBloodPool(const PresetDefinition& preset, float hu, const ValueWindow& w) {
  if (preset.contrast == ContrastRule::kNone || !(w.blood > kSoftTissueHu && w.blood_top > w.blood)) return hu;
  if (preset.contrast == ContrastRule::kAboveBloodPool) return AboveBloodPool(preset, hu, w.blood_top);
  if (hu <= kSoftTissueHu) return hu;
  if (hu <= kReferenceBloodHu) {
    return kSoftTissueHu + (hu - kSoftTissueHu) * (w.blood - kSoftTissueHu) / (kReferenceBloodHu - kSoftTissueHu);
  }
  if (hu <= kReferenceBloodTopHu) {
    return w.blood + (hu - kReferenceBloodHu) * (w.blood_top - w.blood) / (kReferenceBloodTopHu - kReferenceBloodHu);
  }
  return hu + (w.blood_top - kReferenceBloodTopHu);
}

// A preset point's value in the volume's units.
float ValueOnVolume(const PresetDefinition& preset, float v, const ValueWindow& w) {
  switch (preset.scale) {
    case PresetScale::kWindow: return w.lo + v * (w.hi - w.lo);
    case PresetScale::kPhases: {
      const float dense = std::isnan(w.dense) ? w.lo + kSurfaceFraction * (w.hi - w.lo) : w.dense;
      return v <= 1.0f ? w.lo + v * (dense - w.lo) : dense + (v - 1.0f) * (w.hi - dense);
    }
    default: return OnBloodPool(preset, v, w);
  }
}

}  // namespace

v1::TransferFunction MakePreset(std::string_view name, const ValueWindow& window) {
  const PresetDefinition& preset = FindPreset(name);
  v1::TransferFunction tf;
  tf.set_preset(preset.name);
  const bool per_voxel = preset.scale == PresetScale::kPhases;
  tf.set_density_scale(per_voxel ? preset.density_scale / window.voxel_mm : preset.density_scale);
  tf.set_gradient_factor(preset.gradient_factor);
  tf.set_phase_g(0.0f);
  float previous = -INFINITY;
  for (const PresetPoint& p : preset.points) {
    auto* out = tf.add_points();
    // A degenerate window must still give strictly increasing points.
    const float value = std::max(ValueOnVolume(preset, p.value, window), std::nextafter(previous, INFINITY));
    previous = value;
    out->set_value(value);
    out->set_opacity(p.opacity);
    SetColor(out->mutable_diffuse(), p.diffuse);
    SetColor(out->mutable_specular(), {p.specular, p.specular, p.specular});
    out->set_roughness(p.roughness);
    SetColor(out->mutable_emission(), p.emission);
  }
  return tf;
}

v1::TransferFunction ExpandTransferFunction(const v1::TransferFunction& tf, const Volume& volume) {
  if (!tf.points().empty()) return tf;
  v1::TransferFunction expanded =
      MakePreset(tf.preset().empty() ? DefaultPreset(volume) : tf.preset(), AutoWindow(volume));
  if (tf.has_density_scale()) expanded.set_density_scale(tf.density_scale());
  if (tf.has_gradient_factor()) expanded.set_gradient_factor(tf.gradient_factor());
  expanded.set_phase_g(tf.phase_g());
  return expanded;
}

std::string DefaultPreset(v1::VolumeKind kind) {
  switch (kind) {
    case v1::CT_HU: return "ct-bone";
    case v1::CT_SCALED: return "ct-auto";
    case v1::MR: return "mr-default";
    default: return "auto";
  }
}

std::string DefaultPreset(const Volume& volume) { return DefaultPreset(JudgeVolumeKind(volume).kind); }

std::string PresetMisfit(std::string_view name, const Volume& volume) {
  if (!IsPreset(name)) return {};
  const PresetDefinition& preset = FindPreset(name);
  const VolumeKindJudgement kind = JudgeVolumeKind(volume);
  const std::string fitting = DefaultPreset(kind.kind);
  if (preset.scale == PresetScale::kHu && kind.kind != v1::CT_HU) {
    return fmt::format("preset '{}' is for CT in Hounsfield units, and this volume is {} ({}): its colours and "
                       "opacities fall on other values; '{}' is this volume's default",
                       name, v1::VolumeKind_Name(kind.kind), kind.reason, fitting);
  }
  if (name.substr(0, 3) == "mr-" && kind.kind == v1::CT_HU) {
    return fmt::format("preset '{}' is for MR, and this volume is CT in HU; '{}' is its default", name, fitting);
  }
  if (preset.contrast == ContrastRule::kOnBloodPool && kind.kind == v1::CT_HU &&
      !(FindBloodPool(volume.histogram()).peak > 0)) {
    return fmt::format("preset '{}' shows contrast-filled vessels, and this CT has no blood-pool peak (150 to 700 HU): "
                       "without contrast, vessels do not stand out from soft tissue",
                       name);
  }
  return {};
}

v1::Scene MakePresetScene(std::string_view preset, const Volume& volume) {
  FindPreset(preset);  // throws, naming the presets
  v1::Scene scene;
  scene.mutable_transfer_function()->set_preset(std::string(preset));
  const v1::NamedView default_view = DefaultView(volume);
  scene.mutable_camera()->set_view(default_view);
  scene.mutable_camera()->set_fov_y_deg(30.0f);
  // The key light sits above the viewer's left and in front, at 2.75 times
  // the volume's bounding radius; its edges scale with that distance, so the
  // solid angle it fills, and the light it gives, are the same for any
  // volume (the light of examples/ct-bone.json on its 256 mm head).
  const ViewDirections view = NamedViewDirections(default_view, volume.metadata().direction);
  const Vec3f right = Normalize(Cross(-view.to_eye, view.up));
  const float radius = 0.5f * Length(volume.extent_mm());
  const Vec3f towards_light = Normalize(right * -0.55f + view.up * 0.6f + view.to_eye * 0.6f);
  const Vec3f edge_u = Normalize(Cross(towards_light, view.up)), edge_v = Cross(edge_u, towards_light);
  const float size = 0.86f * radius;  // front face, edge_u x edge_v, towards the volume
  v1::AreaLight* key = scene.add_lights()->mutable_area();
  SetVec(key->mutable_center(), towards_light * (2.75f * radius));
  SetVec(key->mutable_edge_u(), edge_u * size);
  SetVec(key->mutable_edge_v(), edge_v * size);
  SetColor(key->mutable_color(), {1.0f, 0.95f, 0.9f});
  key->set_intensity(40);
  v1::EnvironmentLight* sky = scene.add_lights()->mutable_environment();
  SetColor(sky->mutable_gradient()->mutable_zenith(), {0.16f, 0.18f, 0.22f});
  SetColor(sky->mutable_gradient()->mutable_horizon(), {0.1f, 0.1f, 0.11f});
  SetColor(sky->mutable_gradient()->mutable_ground(), {0.03f, 0.03f, 0.03f});
  SetVec(sky->mutable_gradient()->mutable_up(), PatientToWorld(volume.metadata().direction, {0, 0, 1}));
  sky->set_intensity(1);
  CropToSubject(volume, scene);
  return scene;
}

bool AddDefaultLights(v1::Scene& scene, const Volume& volume) {
  if (scene.lights_size() > 0) return false;
  *scene.mutable_lights() = MakePresetScene(DefaultPreset(volume), volume).lights();
  return true;
}

}  // namespace cinevol
