// Label volumes and label tables.
#include "io/label_volume.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "core/error.h"
#include "core/parallel_for.h"
#include "io/dicom_seg.h"
#include "io/file_checks.h"
#include "io/reader_cage.h"
#include "io/table_finder.h"

namespace cinevol {

namespace {

using Matrix3 = std::array<double, 9>;  // row-major

// Voxel index (continuous) to patient LPS mm: origin + direction * (spacing * index).
struct IndexToPatient {
  Matrix3 m;  // direction with spacing folded into its columns
  std::array<double, 3> origin;

  explicit IndexToPatient(const Volume& v) : origin(v.metadata().origin_mm) {
    const auto& d = v.metadata().direction;
    const Vec3f s = v.spacing_mm();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) m[3 * r + c] = d[3 * r + c] * s[c];
    }
  }
};

Matrix3 Inverse(const Matrix3& a) {
  const double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
                     a[2] * (a[3] * a[7] - a[4] * a[6]);
  const double k = 1.0 / det;
  return {(a[4] * a[8] - a[5] * a[7]) * k, (a[2] * a[7] - a[1] * a[8]) * k, (a[1] * a[5] - a[2] * a[4]) * k,
          (a[5] * a[6] - a[3] * a[8]) * k, (a[0] * a[8] - a[2] * a[6]) * k, (a[2] * a[3] - a[0] * a[5]) * k,
          (a[3] * a[7] - a[4] * a[6]) * k, (a[1] * a[6] - a[0] * a[7]) * k, (a[0] * a[4] - a[1] * a[3]) * k};
}

// Whether two grids are the same: voxel centres within a hundredth of a voxel.
bool SameGrid(const Volume& a, const Volume& b) {
  if (a.dims() != b.dims()) return false;
  const IndexToPatient pa(a), pb(b);
  const double tolerance = 0.01 * MinComponent(a.spacing_mm());
  for (int i = 0; i < 3; ++i) {
    if (std::abs(pa.origin[i] - pb.origin[i]) > tolerance) return false;
  }
  // The far corner, index (dims - 1), and the two other axis ends.
  for (int axis = 0; axis < 3; ++axis) {
    const double n = a.dims()[axis] - 1;
    for (int r = 0; r < 3; ++r) {
      if (std::abs(pa.m[3 * r + axis] - pb.m[3 * r + axis]) * std::max(n, 1.0) > tolerance) return false;
    }
  }
  return true;
}

std::string GridText(const Volume& v) {
  std::ostringstream out;
  const Vec3f s = v.spacing_mm();
  const auto& o = v.metadata().origin_mm;
  out << v.dims().x << "x" << v.dims().y << "x" << v.dims().z << " voxels of " << s.x << "x" << s.y << "x" << s.z
      << " mm at (" << o[0] << ", " << o[1] << ", " << o[2] << ")";
  return out.str();
}

// The stored labels, checked to be integers in [0, 65535].
std::vector<std::uint16_t> IntegerLabels(const Volume& v, const std::string& shown) {
  std::vector<std::uint16_t> out(v.voxel_count());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const float value = v.ValueAtIndex(i);
    if (!(value >= 0.0f && value <= 65535.0f) || value != std::floor(value)) {
      throw InputError(fmt::format("{}: voxel {} holds {:g}, not an integer label in [0, 65535]", shown, i, value));
    }
    out[i] = static_cast<std::uint16_t>(value);
  }
  return out;
}

}  // namespace

std::map<int, std::string> ParseLabelTable(std::string_view text, const std::string& shown) {
  std::map<int, std::string> names;
  int line_number = 0;
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    std::string_view line = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view{} : text.substr(end + 1);
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = shown + " line " + std::to_string(line_number) + ": ";
    const std::size_t tab = line.find('\t');
    int value = -1;
    const std::string_view number = line.substr(0, tab);
    const auto [rest, ec] = std::from_chars(number.data(), number.data() + number.size(), value);
    if (tab == std::string_view::npos || ec != std::errc() || rest != number.data() + number.size() || value < 0 ||
        value > 65535) {
      throw InputError(where + "expected 'value<TAB>name' with an integer value in [0, 65535], got '" +
                       std::string(line.substr(0, 80)) + "'");
    }
    const std::string_view name = line.substr(tab + 1);
    if (name.empty() || name.size() > 256) throw InputError(where + "the name must have 1 to 256 characters");
    if (!names.emplace(value, std::string(name)).second) {
      throw InputError(where + "label " + std::to_string(value) + " is named twice");
    }
  }
  return names;
}

std::map<int, std::string> LoadLabelTable(const std::filesystem::path& path, const std::string& shown) {
  file_checks::RequireRegularFile(path, shown);
  return reader_cage::ReadLabelTable(path, shown, {});
}

LabelVolume FitLabels(const Volume& labels, const Volume& image, const std::string& shown) {
  LabelVolume out;
  out.dims = image.dims();
  out.source = shown;
  const std::vector<std::uint16_t> own = IntegerLabels(labels, shown);
  if (SameGrid(labels, image)) {
    out.labels = own;
  } else {
    // Image index -> patient -> label index, as one affine map.
    const IndexToPatient to_patient(image), label_to_patient(labels);
    const Matrix3 inv = Inverse(label_to_patient.m);
    Matrix3 a{};
    std::array<double, 3> b{};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        for (int k = 0; k < 3; ++k) a[3 * r + c] += inv[3 * r + k] * to_patient.m[3 * k + c];
        b[r] += inv[3 * r + c] * (to_patient.origin[c] - label_to_patient.origin[c]);
      }
    }
    bool finite = std::isfinite(b[0]) && std::isfinite(b[1]) && std::isfinite(b[2]);
    for (double e : a) finite &= std::isfinite(e);
    if (!finite) throw InputError(shown + ": its direction cosines are singular");
    const Vec3i n = image.dims(), m = labels.dims();
    out.labels.assign(image.voxel_count(), 0);
    std::vector<std::size_t> inside_per_slice(n.z, 0);
    ParallelFor(n.z, [&](std::int64_t z) {
      for (int y = 0; y < n.y; ++y) {
        for (int x = 0; x < n.x; ++x) {
          int q[3];
          bool inside = true;
          for (int r = 0; r < 3 && inside; ++r) {
            // Compared as a double first: grids far apart or of very
            // different spacings map to indices no int holds.
            const double v = std::floor(a[3 * r] * x + a[3 * r + 1] * y + a[3 * r + 2] * double(z) + b[r] + 0.5);
            inside = v >= 0.0 && v < double(m[r]);
            if (inside) q[r] = static_cast<int>(v);
          }
          if (!inside) continue;
          ++inside_per_slice[z];
          out.labels[(std::size_t(z) * n.y + y) * n.x + x] = own[(std::size_t(q[2]) * m.y + q[1]) * m.x + q[0]];
        }
      }
    });
    std::size_t inside = 0;
    for (std::size_t c : inside_per_slice) inside += c;
    if (inside == 0) {
      throw InputError(shown + ": its grid (" + GridText(labels) + ") does not overlap the image's (" +
                       GridText(image) + ")");
    }
    out.note = "resampled nearest-neighbour from " + GridText(labels) + " onto the image's " + GridText(image) +
               (inside < image.voxel_count() ? "; voxels outside it are label 0" : "");
    // Debug only: `shown` is a path or a client's file name, patient data for an info log.
    spdlog::debug("{}: {}", shown, out.note);
  }
  for (std::uint16_t label : out.labels) ++out.voxels[label];
  AddShells(out);
  return out;
}

void FollowImageOrientation(Volume& labels, const Volume& image) {
  ApplyOrientation(labels, image.metadata().orientation_override, "the image's orientation");
}

void AddShells(LabelVolume& labels) {
  const Vec3i d = labels.dims;
  const std::size_t sx = d.x, sxy = std::size_t(d.x) * d.y;
  labels.first_derived = labels.max_label() + 1;
  // Per slice: the unlabelled voxels touching labels, each with the index of
  // the set of labels it touches among the slice's sets.
  struct Slice {
    std::vector<std::vector<std::uint16_t>> sets;
    std::vector<std::pair<std::size_t, int>> shells;  // voxel, set
  };
  std::vector<Slice> slices(d.z);
  ParallelFor(d.z, [&](std::int64_t z) {
    Slice& slice = slices[z];
    std::map<std::vector<std::uint16_t>, int> index;
    std::vector<std::uint16_t> touches;
    const int z0 = std::max(0, int(z) - 1), z1 = std::min(d.z - 1, int(z) + 1);
    for (int y = 0; y < d.y; ++y) {
      const int y0 = std::max(0, y - 1), y1 = std::min(d.y - 1, y + 1);
      for (int x = 0; x < d.x; ++x) {
        const std::size_t i = z * sxy + y * sx + x;
        if (labels.labels[i] != 0) continue;
        touches.clear();
        for (int nz = z0; nz <= z1; ++nz) {
          for (int ny = y0; ny <= y1; ++ny) {
            const std::uint16_t* row = labels.labels.data() + nz * sxy + ny * sx;
            for (int nx = std::max(0, x - 1); nx <= std::min(d.x - 1, x + 1); ++nx) {
              if (row[nx] != 0) touches.push_back(row[nx]);
            }
          }
        }
        if (touches.empty()) continue;
        std::sort(touches.begin(), touches.end());
        touches.erase(std::unique(touches.begin(), touches.end()), touches.end());
        const auto [it, added] = index.emplace(touches, int(slice.sets.size()));
        if (added) slice.sets.push_back(touches);
        slice.shells.emplace_back(i, it->second);
      }
    }
  });
  // One value per set of labels touched, in slice order, while values last.
  std::map<std::vector<std::uint16_t>, int> value_of;
  std::uint64_t left = 0;
  for (const Slice& slice : slices) {
    std::vector<int> values(slice.sets.size(), -1);
    for (std::size_t k = 0; k < slice.sets.size(); ++k) {
      auto it = value_of.find(slice.sets[k]);
      if (it == value_of.end()) {
        const int value = labels.first_derived + int(labels.derived.size());
        if (value > 65534) continue;  // 65535 stays for the table
        labels.derived.push_back({DerivedLabel::Kind::kShell, slice.sets[k]});
        it = value_of.emplace(slice.sets[k], value).first;
      }
      values[k] = it->second;
    }
    for (const auto& [voxel, set] : slice.shells) {
      if (values[set] < 0) {
        ++left;
      } else {
        labels.labels[voxel] = std::uint16_t(values[set]);
      }
    }
  }
  if (left > 0) {
    labels.note += fmt::format("{}{} voxels of partial-volume shell stay label 0: no 16-bit values left for them",
                               labels.note.empty() ? "" : "; ", left);
  }
}

namespace {

// Marks voxels `is_table` says are the table, where the segmentation leaves
// them unlabelled, with a value of its own; none left (a label 65535): not at all.
template <class IsTable>
void MarkTable(LabelVolume& labels, IsTable is_table) {
  if (labels.derived.empty()) labels.first_derived = labels.max_label() + 1;
  const int value = labels.first_derived + int(labels.derived.size());
  if (value > 65535) {
    labels.table_note += "; not marked: the segmentation uses every 16-bit value";
    return;
  }
  labels.derived.push_back({DerivedLabel::Kind::kTable, {}});
  const auto table = std::uint16_t(value);
  std::uint64_t marked = 0;
  for (std::size_t i = 0; i < labels.labels.size(); ++i) {
    if (is_table(i) && labels.LabelOf(labels.labels[i]) == 0) {
      labels.labels[i] = table;
      ++marked;
    }
  }
  labels.table_voxels = marked;
}

}  // namespace

void AddTable(LabelVolume& labels, const TableMask& table) {
  labels.table_note = table.note;
  if (!table.found()) return;
  if (labels.dims != table.dims) throw std::invalid_argument("AddTable: the table is not on the labels' grid");
  MarkTable(labels, [&](std::size_t i) { return (table.voxels[i] & (kTableVoxel | kTableRimVoxel)) != 0; });
}

LabelVolume TableLabels(const TableMask& table) {
  LabelVolume labels;
  labels.dims = table.dims;
  labels.segmentation = false;
  const std::size_t n = std::size_t(table.dims.x) * table.dims.y * table.dims.z;
  labels.labels.assign(n, 0);
  labels.voxels[0] = n;
  AddTable(labels, table);
  return labels;
}

void CopyTable(const LabelVolume& from, LabelVolume& to) {
  to.table_note = from.table_note;
  const int table = from.table_value();
  if (table < 0) return;
  if (from.dims != to.dims) throw std::invalid_argument("CopyTable: the label volumes' grids differ");
  MarkTable(to, [&](std::size_t i) { return from.labels[i] == table; });
}

LabelVolume LoadLabelVolume(const std::filesystem::path& path, const Volume& image, const LoadPolicy& policy) {
  if (IsDicomSegmentation(path)) return LoadSegmentation(path, image, policy);
  const std::string shown = file_checks::Shown(path, policy);
  Volume labels = LoadVolumeFile(path, policy);
  FollowImageOrientation(labels, image);
  return FitLabels(labels, image, shown);
}

v1::LabelSet ToLabelSet(const LabelVolume& labels) {
  v1::LabelSet set;
  set.set_source(labels.source);
  set.set_note(labels.note);
  std::map<int, v1::LabelName> names;
  for (const auto& [value, voxels] : labels.voxels) names[value].set_voxels(voxels);
  for (const auto& [value, name] : labels.names) names[value].set_name(name);
  for (const auto& [value, color] : labels.colors) {
    v1::Color& c = *names[value].mutable_color();
    c.set_r(color.x);
    c.set_g(color.y);
    c.set_b(color.z);
  }
  for (auto& [value, n] : names) {
    n.set_value(std::uint32_t(value));
    *set.add_names() = std::move(n);
  }
  return set;
}

std::shared_ptr<const LabelVolume> LoadSceneLabels(const v1::VolumeSource& source, const Volume& image,
                                                   const std::filesystem::path& base_dir) {
  if (source.labels().empty()) return nullptr;
  auto resolve = [&](const std::string& p) {
    return std::filesystem::path(p).is_relative() ? base_dir / p : std::filesystem::path(p);
  };
  LabelVolume labels = LoadLabelVolume(resolve(source.labels()), image);
  if (!source.label_table().empty()) labels.names = LoadLabelTable(resolve(source.label_table()), source.label_table());
  return std::make_shared<const LabelVolume>(std::move(labels));
}

std::shared_ptr<const LabelVolume> LoadSceneLabels(const v1::Scene& scene, const Volume& image,
                                                   const std::filesystem::path& base_dir) {
  std::shared_ptr<const LabelVolume> segmentation = LoadSceneLabels(scene.volume(), image, base_dir);
  if (!scene.labels().remove_table()) return segmentation;
  const TableMask table = FindTable(image);
  spdlog::debug("table search: {} ({:.2f} s)", table.note, table.seconds);
  if (!segmentation) return std::make_shared<const LabelVolume>(TableLabels(table));
  LabelVolume both = *segmentation;
  AddTable(both, table);
  return std::make_shared<const LabelVolume>(std::move(both));
}

}  // namespace cinevol
