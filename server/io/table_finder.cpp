// The table search: thresholds from the volume's kind, the body as the thick
// part of what is above the body threshold (holes filled per axial slice),
// and the table as the thin components outside it that run along the scan.
#include "io/table_finder.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>

#include "core/error.h"
#include "core/parallel_for.h"
#include "scene/volume_kind.h"

namespace cinevol {
namespace {

using Mask = std::vector<std::uint8_t>;

// Working bits, one byte per voxel; TableMaskBits replace them at the end.
enum : std::uint8_t {
  kSolid = 1u << 0,      // above the body threshold, axial holes filled; later the body's margin
  kTemp = 1u << 1,
  kCore = 1u << 2,       // the solid eroded: its thick parts, then only the body's
  kBody = 1u << 3,
  kCandidate = 1u << 4,  // above the table threshold, off the body's margin
  kThick = 1u << 5,      // a candidate in a region thicker than twice the opening
  kVisited = 1u << 6,
  kTable = 1u << 7,
};
constexpr std::uint8_t kMargin = kSolid;  // the body dilated by one voxel, once the solid is done with

// HU: air is -1000, fat -100, the lungs -900..-700; a table's foam core is
// near air, its shells and pads far above. -500 keeps fat in the body and
// the lungs as holes; -900 is what the lung preset starts to show.
constexpr float kBodyHu = -500.0f, kTableHu = -900.0f;
// Other CT-like data (scaled, or 8-bit exports whose window clips fat to
// air): fractions of the way from the air peak to the median of what is
// above Otsu's threshold (soft tissue). Low, for fat may be as dark as air:
// the body is then its skin and what it encloses.
constexpr float kBodyFraction = 0.1f, kTableFraction = 0.05f;

class Searcher {
 public:
  // `clipped`: air and fat clipped to one value (an 8-bit export's window floor).
  Searcher(const Volume& volume, const TableSettings& settings, bool clipped)
      : volume_(volume), settings_(settings), dims_(volume.dims()), mask_(volume.voxel_count(), 0), clipped_(clipped) {}

  TableMask Run(TableMask result);

 private:
  std::size_t Index(int x, int y, int z) const { return (std::size_t(z) * dims_.y + y) * dims_.x + x; }
  void CheckCancel() const {
    if (settings_.cancel && settings_.cancel->load()) throw Cancelled("the table search was cancelled");
  }
  // Voxels above `threshold` get `bit`.
  void Threshold(float threshold, std::uint8_t bit);
  // Box erosion (every voxel within `k` per axis has `from`) or dilation (any
  // has), written to `to`; windows are clipped at the volume's faces, so the
  // faces do not erode.
  void Box(Vec3i k, std::uint8_t from, std::uint8_t to, bool erode);
  void BoxRows(int k, std::uint8_t from, std::uint8_t to, bool erode);
  void BoxColumns(int axis, int k, std::uint8_t from, std::uint8_t to, bool erode);
  // Sets `out` in every axial slice's holes of `wall`: regions without it
  // that the slice's border cannot reach.
  void FillAxialHoles(std::uint8_t wall, std::uint8_t out);
  // Keeps the core's components of at least 2% of the largest: the body
  // and limbs apart from it; thin bits that survived erosion go.
  std::uint64_t KeepLargeCores();
  // Marks the thin candidate components that run along the scan as table.
  int MarkTable();
  // The table lies where it lies in every slice (the patient moves with it):
  // marks its profile, where most of its slices have it, through every slice
  // it spans, also where the body touches it and the opening gave it to the
  // body; never in the body's core.
  void ExtrudeTable(float threshold);
  template <class Visit>
  void Bfs(std::size_t seed, std::uint8_t member, std::uint8_t mark, bool diagonals, Visit visit);
  Vec3i Radius(float mm) const;

  const Volume& volume_;
  const TableSettings& settings_;
  Vec3i dims_;
  Mask mask_;
  int axial_ = 2;
  bool clipped_ = false;
};

void Searcher::Threshold(float threshold, std::uint8_t bit) {
  const std::int64_t n = std::int64_t(mask_.size());
  ParallelFor((n + 65535) / 65536, [&](std::int64_t block) {
    const std::size_t end = std::min<std::size_t>(mask_.size(), std::size_t(block + 1) << 16);
    for (std::size_t i = std::size_t(block) << 16; i < end; ++i) {
      if (volume_.ValueAtIndex(i) > threshold) mask_[i] |= bit;
    }
  });
}

// Voxels within `mm` along each axis; never more than the axis holds (a
// window wider than the volume is clipped at its faces anyway).
Vec3i Searcher::Radius(float mm) const {
  Vec3i r;
  for (int a = 0; a < 3; ++a) r[a] = int(std::min(std::round(double(mm) / volume_.spacing_mm()[a]), double(dims_[a])));
  return r;
}

void Searcher::Box(Vec3i k, std::uint8_t from, std::uint8_t to, bool erode) {
  BoxRows(k.x, from, to, erode);
  BoxColumns(1, k.y, to, to, erode);
  BoxColumns(2, k.z, to, to, erode);
  CheckCancel();
}

// One line's window test from its prefix counts: erosion wants every voxel, dilation one.
inline bool WindowHas(const std::uint16_t* prefix, int n, int i, int k, bool erode, int step) {
  const int lo = std::max(0, i - k), hi = std::min(n, i + k + 1);
  const int count = prefix[hi * step] - prefix[lo * step];
  return erode ? count == hi - lo : count > 0;
}

void Searcher::BoxRows(int k, std::uint8_t from, std::uint8_t to, bool erode) {
  const int n = dims_.x;
  ParallelFor(std::int64_t(dims_.y) * dims_.z, [&](std::int64_t row) {
    thread_local std::vector<std::uint16_t> prefix;
    prefix.assign(std::size_t(n) + 1, 0);
    std::uint8_t* line = mask_.data() + std::size_t(row) * n;
    for (int i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + ((line[i] & from) != 0);
    for (int i = 0; i < n; ++i) {
      line[i] = WindowHas(prefix.data(), n, i, k, erode, 1) ? (line[i] | to) : (line[i] & ~to);
    }
  }, 0, 64);
}

// Columns along y or z, a tile of up to 64 neighbouring x at once, so every
// cache line read serves 64 columns.
void Searcher::BoxColumns(int axis, int k, std::uint8_t from, std::uint8_t to, bool erode) {
  constexpr int kTile = 64;
  const int n = dims_[axis];
  const std::size_t stride = axis == 1 ? std::size_t(dims_.x) : std::size_t(dims_.x) * dims_.y;
  const int others = axis == 1 ? dims_.z : dims_.y;
  const std::size_t other_stride = axis == 1 ? std::size_t(dims_.x) * dims_.y : std::size_t(dims_.x);
  const int tiles = (dims_.x + kTile - 1) / kTile;
  ParallelFor(std::int64_t(others) * tiles, [&](std::int64_t t) {
    thread_local std::vector<std::uint16_t> prefix;
    prefix.assign((std::size_t(n) + 1) * kTile, 0);
    const int x0 = int(t % tiles) * kTile, width = std::min(kTile, dims_.x - x0);
    std::uint8_t* base = mask_.data() + std::size_t(t / tiles) * other_stride + x0;
    for (int i = 0; i < n; ++i) {
      const std::uint8_t* line = base + i * stride;
      for (int j = 0; j < width; ++j) prefix[(i + 1) * kTile + j] = prefix[i * kTile + j] + ((line[j] & from) != 0);
    }
    for (int i = 0; i < n; ++i) {
      std::uint8_t* line = base + i * stride;
      for (int j = 0; j < width; ++j) {
        line[j] = WindowHas(prefix.data() + j, n, i, k, erode, kTile) ? (line[j] | to) : (line[j] & ~to);
      }
    }
  });
}

void Searcher::FillAxialHoles(std::uint8_t wall, std::uint8_t out) {
  // The slice's two in-plane axes u, v and the strides of all three.
  const int u_axis = axial_ == 0 ? 1 : 0, v_axis = axial_ == 2 ? 1 : 2;
  const std::size_t strides[3] = {1, std::size_t(dims_.x), std::size_t(dims_.x) * dims_.y};
  const int nu = dims_[u_axis], nv = dims_[v_axis];
  ParallelFor(dims_[axial_], [&](std::int64_t s) {
    std::uint8_t* base = mask_.data() + std::size_t(s) * strides[axial_];
    auto at = [&](int u, int v) -> std::uint8_t& { return base[u * strides[u_axis] + v * strides[v_axis]]; };
    std::vector<std::pair<int, int>> stack;
    auto reach = [&](int u, int v) {
      std::uint8_t& m = at(u, v);
      if (m & (wall | kTemp)) return;
      m |= kTemp;
      stack.emplace_back(u, v);
    };
    for (int u = 0; u < nu; ++u) reach(u, 0), reach(u, nv - 1);
    for (int v = 0; v < nv; ++v) reach(0, v), reach(nu - 1, v);
    while (!stack.empty()) {
      const auto [u, v] = stack.back();
      stack.pop_back();
      if (u > 0) reach(u - 1, v);
      if (u + 1 < nu) reach(u + 1, v);
      if (v > 0) reach(u, v - 1);
      if (v + 1 < nv) reach(u, v + 1);
    }
    for (int v = 0; v < nv; ++v) {
      for (int u = 0; u < nu; ++u) {
        std::uint8_t& m = at(u, v);
        m = (m & kTemp) ? (m & ~kTemp) : ((m & wall) ? m : (m | out));
      }
    }
  });
  CheckCancel();
}

// Breadth first from `seed` over voxels with `member`, marking them `mark`
// (which must start clear on them); visit() sees each once.
template <class Visit>
void Searcher::Bfs(std::size_t seed, std::uint8_t member, std::uint8_t mark, bool diagonals, Visit visit) {
  std::deque<std::uint32_t> queue{std::uint32_t(seed)};
  mask_[seed] |= mark;
  const std::size_t sx = dims_.x, sxy = std::size_t(dims_.x) * dims_.y;
  while (!queue.empty()) {
    const std::size_t i = queue.front();
    queue.pop_front();
    visit(i);
    const int x = int(i % sx), y = int(i / sx % dims_.y), z = int(i / sxy);
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int away = std::abs(dx) + std::abs(dy) + std::abs(dz);
          if (away == 0 || (!diagonals && away > 1)) continue;
          const int nx = x + dx, ny = y + dy, nz = z + dz;
          if (nx < 0 || ny < 0 || nz < 0 || nx >= dims_.x || ny >= dims_.y || nz >= dims_.z) continue;
          const std::size_t j = Index(nx, ny, nz);
          if ((mask_[j] & member) && !(mask_[j] & mark)) {
            mask_[j] |= mark;
            queue.push_back(std::uint32_t(j));
          }
        }
      }
    }
  }
}

std::uint64_t Searcher::KeepLargeCores() {
  struct Component {
    std::size_t seed;
    std::uint64_t size = 0;
  };
  std::vector<Component> components;
  for (std::size_t i = 0; i < mask_.size(); ++i) {
    if ((mask_[i] & kCore) && !(mask_[i] & kVisited)) {
      Component c{i};
      Bfs(i, kCore, kVisited, false, [&](std::size_t) { ++c.size; });
      components.push_back(c);
    }
  }
  std::uint64_t largest = 0;
  for (const Component& c : components) largest = std::max(largest, c.size);
  std::uint64_t kept = 0;
  for (const Component& c : components) {
    if (c.size * 50 >= largest) {
      kept += c.size;
      continue;
    }
    // Dropped: cleared by a second pass (kTemp marks it, then both go).
    Bfs(c.seed, kCore, kTemp, false, [&](std::size_t j) { mask_[j] &= ~kCore; });
  }
  for (std::uint8_t& m : mask_) m &= ~(kVisited | kTemp);
  CheckCancel();
  return kept;
}

int Searcher::MarkTable() {
  const int slices = dims_[axial_];
  const Vec3f spacing = volume_.spacing_mm();
  const double voxel_mm3 = double(spacing.x) * spacing.y * spacing.z;
  const std::size_t strides[3] = {1, std::size_t(dims_.x), std::size_t(dims_.x) * dims_.y};
  int tables = 0;
  for (std::size_t i = 0; i < mask_.size(); ++i) {
    if (!(mask_[i] & kCandidate) || (mask_[i] & kVisited)) continue;
    std::uint64_t size = 0, thick = 0;
    int first = slices, last = -1;
    Bfs(i, kCandidate, kVisited, true, [&](std::size_t j) {
      ++size;
      thick += (mask_[j] & kThick) != 0;
      const int s = int(j / strides[axial_] % std::size_t(slices));
      first = std::min(first, s);
      last = std::max(last, s);
    });
    const bool runs_along = float(last - first + 1) >= settings_.min_axial_span * float(slices);
    const bool thin = float(thick) <= settings_.max_thick_fraction * float(size);
    const bool large = double(size) * voxel_mm3 >= settings_.min_table_ml * 1000.0;
    if (runs_along && thin && large) {
      Bfs(i, kCandidate, kTable, true, [](std::size_t) {});
      ++tables;
    }
  }
  CheckCancel();
  return tables;
}

void Searcher::ExtrudeTable(float threshold) {
  const int u_axis = axial_ == 0 ? 1 : 0, v_axis = axial_ == 2 ? 1 : 2;
  const std::size_t strides[3] = {1, std::size_t(dims_.x), std::size_t(dims_.x) * dims_.y};
  const int nu = dims_[u_axis], nv = dims_[v_axis], slices = dims_[axial_];
  auto index = [&](int s, int u, int v) { return s * strides[axial_] + u * strides[u_axis] + v * strides[v_axis]; };
  // Per in-plane position, the slices that have the table there.
  std::vector<std::uint32_t> count(std::size_t(nu) * nv, 0);
  int first = slices, last = -1;
  for (int s = 0; s < slices; ++s) {
    for (int v = 0; v < nv; ++v) {
      for (int u = 0; u < nu; ++u) {
        if (!(mask_[index(s, u, v)] & kTable)) continue;
        ++count[std::size_t(v) * nu + u];
        first = std::min(first, s);
        last = std::max(last, s);
      }
    }
  }
  const std::uint32_t most = std::uint32_t(last - first + 2) / 2;  // half, rounded up
  ParallelFor(last - first + 1, [&](std::int64_t k) {
    const int s = first + int(k);
    for (int v = 0; v < nv; ++v) {
      for (int u = 0; u < nu; ++u) {
        if (count[std::size_t(v) * nu + u] < most) continue;
        const std::size_t i = index(s, u, v);
        if (!(mask_[i] & (kCore | kTable)) && volume_.ValueAtIndex(i) > threshold)
          mask_[i] = (mask_[i] & ~kBody) | kTable;
      }
    }
  });
  CheckCancel();
}

TableMask Searcher::Run(TableMask result) {
  // The axial axis: the index axis nearest the patient's S (row 2 of the cosines).
  const auto& d = volume_.metadata().direction;
  for (int c = 0; c < 3; ++c) {
    if (std::abs(d[6 + c]) > std::abs(d[6 + axial_])) axial_ = c;
  }
  result.axial_axis = axial_;
  const Vec3i open = Radius(settings_.opening_mm);

  // The body: what is above the body threshold, its axial holes (lungs,
  // bowel gas) filled, opened so that thin things touching it come off,
  // then given back what the opening took from its own surface.
  Threshold(result.body_threshold, kSolid);
  if (settings_.closing_mm > 0 && clipped_) {
    // Where fat is as dark as air (8-bit exports), the body's outline is its
    // skin, a thin ring with gaps, and speckle lies inside: closed, it
    // encloses the body.
    Box(Radius(settings_.closing_mm), kSolid, kTemp, false);
    Box(Radius(settings_.closing_mm), kTemp, kSolid, true);
    for (std::uint8_t& m : mask_) m &= ~kTemp;
  }
  FillAxialHoles(kSolid, kSolid);
  Box(open, kSolid, kCore, true);
  if (KeepLargeCores() == 0) {
    result.note = "no body found: nothing is thicker than " + fmt::format("{:g}", 2 * settings_.opening_mm) + " mm";
    return result;
  }
  Box({open.x + 1, open.y + 1, open.z + 1}, kCore, kTemp, false);
  for (std::uint8_t& m : mask_) {
    const bool body = (m & kSolid) && (m & kTemp);
    m = (body ? kBody : 0) | (m & kCore);  // the core stays: ExtrudeTable must not reach it
  }

  // Candidates: above the table threshold, clear of the body and the one
  // voxel of partial volume around it; their thick parts are not table.
  Box({1, 1, 1}, kBody, kMargin, false);
  const float table_threshold = result.table_threshold;
  ParallelFor(std::int64_t(mask_.size() + 65535) / 65536, [&](std::int64_t block) {
    const std::size_t end = std::min<std::size_t>(mask_.size(), std::size_t(block + 1) << 16);
    for (std::size_t i = std::size_t(block) << 16; i < end; ++i) {
      if (!(mask_[i] & kMargin) && volume_.ValueAtIndex(i) > table_threshold) mask_[i] |= kCandidate;
    }
  });
  Box(open, kCandidate, kThick, true);
  result.table_components = MarkTable();
  if (result.table_components > 0) ExtrudeTable(result.table_threshold);

  // The table's rim: voxels touching it, off the body's margin, whose values
  // its partial volume raised (and which trilinear lookups blend with it).
  Box({1, 1, 1}, kTable, kTemp, false);
  for (std::uint8_t& m : mask_) {
    const std::uint8_t out = ((m & kBody) && !(m & kTable) ? kBodyVoxel : 0) | ((m & kTable) ? kTableVoxel : 0) |
                             ((m & kTemp) && !(m & (kTable | kMargin)) ? kTableRimVoxel : 0);
    m = out;
    result.body_voxels += (out & kBodyVoxel) != 0;
    result.table_voxels += (out & kTableVoxel) != 0;
    result.rim_voxels += (out & kTableRimVoxel) != 0;
  }
  if (result.found()) result.voxels = std::move(mask_);
  return result;
}

// The fullest histogram bin's centre in [from, to) bins.
float PeakIn(const ValueHistogram& h, int from, int to) {
  int best = from;
  for (int b = from; b < to; ++b) {
    if (h.counts[b] > h.counts[best]) best = b;
  }
  return h.BinStart(best) + 0.5f * h.BinWidth();
}

// Body and table thresholds for the volume's kind, and whether its air is
// clipped to one value; false for MR and data too flat to tell air from tissue.
bool Thresholds(const Volume& volume, TableMask& result, bool& clipped) {
  const VolumeKindJudgement kind = JudgeVolumeKind(volume);
  if (kind.kind == v1::MR) {
    result.note = "MR: no table search (a table gives no MR signal)";
    return false;
  }
  if (kind.kind == v1::CT_HU) {
    result.body_threshold = kBodyHu;
    result.table_threshold = kTableHu;
    return true;
  }
  // Air below Otsu's threshold, soft tissue above it.
  const ValueHistogram& h = volume.histogram();
  if (h.counts.empty() || !(h.max_value > h.min_value)) {
    result.note = "one value throughout: no table";
    return false;
  }
  // Air clipped to one value (an export's window floor, fat clipped with it):
  // anything above it is the subject.
  std::size_t at_min = 0;
  for (std::size_t i = 0; i < volume.voxel_count(); ++i) at_min += volume.ValueAtIndex(i) == volume.min_value();
  clipped = at_min >= volume.voxel_count() / 5;
  if (clipped) {
    result.body_threshold = result.table_threshold = volume.min_value();
    return true;
  }
  const float otsu = h.OtsuThreshold();
  const int split = std::clamp(h.BinOf(otsu), 1, ValueHistogram::kBins - 1);
  const float air = PeakIn(h, 0, split), tissue = h.Percentile(0.5, otsu);
  result.body_threshold = air + kBodyFraction * (tissue - air);
  result.table_threshold = air + kTableFraction * (tissue - air);
  return true;
}

}  // namespace

std::uint64_t TableSearchBytes(std::uint64_t voxels) { return voxels; }

TableMask FindTable(const Volume& volume, const TableSettings& settings) {
  const auto start = std::chrono::steady_clock::now();
  TableMask result;
  result.dims = volume.dims();
  bool clipped = false;
  if (Thresholds(volume, result, clipped)) {
    result = Searcher(volume, settings, clipped).Run(std::move(result));
    if (result.note.empty()) {
      result.note = result.found()
                        ? fmt::format("table: {} component(s), {} voxels and {} of rim, outside a body of {} voxels",
                                      result.table_components, result.table_voxels, result.rim_voxels,
                                      result.body_voxels)
                        : fmt::format("no table: nothing thin outside the body runs along the scan (body {} voxels)",
                                      result.body_voxels);
    }
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace cinevol
