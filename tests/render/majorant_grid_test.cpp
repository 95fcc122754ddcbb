// The majorant grid bounds extinction everywhere, and the DDA walks bricks in
// order along a ray.
#include <gtest/gtest.h>

#include <random>

#include "render/majorant_grid.h"
#include "render/scene_data.h"
#include "core/labels.h"

namespace cinevol {
namespace {

std::shared_ptr<const Volume> RandomVolume(std::mt19937& rng, Vec3i dims) {
  std::uniform_real_distribution<float> value(-1000.0f, 3000.0f);
  std::vector<float> v(std::size_t(dims.x) * dims.y * dims.z);
  // Smooth blobs plus sparse spikes: both tight and loose bricks.
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::round(value(rng) * (i % 7 == 0 ? 1.0f : 0.1f));
  VolumeMetadata meta;
  meta.source = "random";
  return std::make_shared<const Volume>(dims, Vec3f{0.7f, 1.1f, 1.9f}, std::move(v), meta);
}

TransferFunction RandomTransferFunction(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  TransferFunction tf;
  float value = -1200.0f;
  const int n = 2 + int(u(rng) * 6);
  for (int i = 0; i < n; ++i) {
    value += 50.0f + u(rng) * 1000.0f;
    tf.points.push_back({value, u(rng) < 0.3f ? 0.0f : u(rng), {0.5f, 0.5f, 0.5f}, {}, 0.5f, {}});
  }
  tf.density_scale = 0.01f + u(rng) * 10.0f;
  return tf;
}

// Labels 0..4 in slabs and speckles, each a random style: hidden, scaled,
// with a transfer function of its own or unlisted.
std::shared_ptr<const LabelVolume> RandomLabels(std::mt19937& rng, Vec3i dims) {
  auto labels = std::make_shared<LabelVolume>();
  labels->dims = dims;
  labels->labels.resize(std::size_t(dims.x) * dims.y * dims.z);
  for (std::size_t i = 0; i < labels->labels.size(); ++i) {
    labels->labels[i] = rng() % 5 == 0 ? std::uint16_t(rng() % 5) : std::uint16_t((i / (dims.x * 3)) % 5);
    ++labels->voxels[labels->labels[i]];
  }
  return labels;
}

LabelSetup RandomLabelSetup(std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  LabelSetup setup;
  setup.show_unlisted = u(rng) < 0.5f;
  for (int label = 0; label < 4; ++label) {
    LabelStyle& style = setup.styles[label];
    style.visible = u(rng) < 0.8f;
    style.opacity_scale = u(rng) * 3.0f;
    if (u(rng) < 0.5f) {
      style.transfer = int(setup.transfer_functions.size());
      setup.transfer_functions.push_back(RandomTransferFunction(rng));
    }
  }
  return setup;
}

// What the integrator takes as extinction at p (render/integrator.h).
float Extinction(const RenderScene& s, Vec3f p) {
  const float entry = s.transfer.Entry(s.volume.Sample(p));
  if (!s.labels.voxels) return s.transfer.SigmaT(entry);
  const LabelMaterial m = s.labels.At(s.volume, p);
  return std::min(m.opacity_scale * s.transfer.SigmaT(entry, m.table), s.transfer.max_sigma_t);
}

// Samples the reconstruction densely (trilinear and tricubic, with and
// without labels) and checks every value against its brick's majorant.
TEST(MajorantGrid, NeverBelowTheTrueExtinction) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 6; ++trial) {
    const Vec3i dims{19 + trial, 23, 17 + 2 * trial};  // bricks straddle the edges
    SceneData data;
    data.SetVolume(std::make_shared<const PreparedVolume>(RandomVolume(rng, dims), kDefaultBrickSize));
    const auto labels = RandomLabels(rng, dims);
    for (int edit = 0; edit < 8; ++edit) {  // transfer-function, reconstruction and label edits on the same volume
      data.SetTransferFunction(RandomTransferFunction(rng));
      data.SetReconstruction(edit % 2 ? Reconstruction::kTricubic : Reconstruction::kTrilinear);
      data.SetLabels(edit % 4 >= 2 ? VolumeCache::Get().AcquireLabels(labels, data.volume().brick_size(), kHostDevice)
                                   : nullptr,
                     RandomLabelSetup(rng));
      const RenderScene s = data.HostView();
      std::uniform_real_distribution<float> u(0.0f, 1.0f);
      for (int k = 0; k < 20000; ++k) {
        const Vec3f p = s.volume.box_min + (s.volume.box_max - s.volume.box_min) * Vec3f{u(rng), u(rng), u(rng)};
        Vec3i b;
        for (int a = 0; a < 3; ++a) {
          b[a] =
              std::min(int((p[a] - s.majorants.box_min[a]) * s.majorants.inv_brick_size[a]), s.majorants.bricks[a] - 1);
        }
        ASSERT_LE(Extinction(s, p), s.majorants.At(b)) << "trial " << trial << " edit " << edit;
      }
    }
  }
}

// Tricubic values stay within their 4^3 voxels' range, so the bound holds
// with the wider margin, and a one-voxel margin would not do: a spike next
// to a brick raises the tricubic value inside it.
TEST(MajorantGrid, TricubicBricksReachTwoVoxelsBeyond) {
  std::vector<float> v(16 * 16 * 16, 0.0f);
  v[(8 * 16 + 8) * 16 + 9] = 1000.0f;  // x = 9: two voxels past brick x 1 (voxels 4..7), in the next brick's first two
  VolumeMetadata meta;
  meta.source = "spike";
  auto volume = std::make_shared<const Volume>(Vec3i{16, 16, 16}, Vec3f{1, 1, 1}, std::move(v), meta);
  const PreparedVolume prepared(volume, kDefaultBrickSize);
  auto brick = [](const BrickRanges& r, int x, int y, int z) {
    return r.max[(std::size_t(z) * r.bricks.y + y) * r.bricks.x + x];
  };
  const std::uint16_t zero = prepared.brick_ranges(Reconstruction::kTrilinear).min[0];
  EXPECT_EQ(brick(prepared.brick_ranges(Reconstruction::kTrilinear), 1, 2, 2), zero);
  EXPECT_GT(brick(prepared.brick_ranges(Reconstruction::kTricubic), 1, 2, 2), zero);
  VolumeView view;
  view.voxels = prepared.voxels();
  view.dims = {16, 16, 16};
  view.spacing = {1, 1, 1};
  view.inv_spacing = {1, 1, 1};
  view.box_min = {-8, -8, -8};
  view.box_max = {8, 8, 8};
  view.tricubic = true;
  // 7.4 voxels in along x (world -8 + 7.9 mm) lies in brick 1, whose cubic reads reach voxel 9.
  EXPECT_GT(view.Sample({-8 + 7.9f, -8 + 8.5f, -8 + 8.5f}), float(zero));
}

TEST(MajorantGrid, EmptyBricksHaveZeroMajorant) {
  std::vector<float> v(32 * 32 * 32, 0.0f);
  v[(5 * 32 + 5) * 32 + 5] = 1000.0f;  // one dense voxel near a corner
  VolumeMetadata meta;
  meta.source = "sparse";
  SceneData data;
  data.SetVolume(std::make_shared<const PreparedVolume>(
      std::make_shared<const Volume>(Vec3i{32, 32, 32}, Vec3f{1, 1, 1}, std::move(v), meta), kDefaultBrickSize));
  TransferFunction tf;
  tf.points = {{100, 0, {}, {}, 0, {}}, {1000, 1, {}, {}, 0, {}}};
  data.SetTransferFunction(tf);
  int nonzero = 0;
  for (float m : data.majorants()) nonzero += m > 0;
  EXPECT_EQ(nonzero, 1);  // only the brick holding the voxel (margins reach one voxel)
}

TEST(MajorantIterator, VisitsBricksInOrderWithoutGaps) {
  std::vector<float> majorant(5 * 4 * 3);
  for (std::size_t i = 0; i < majorant.size(); ++i) majorant[i] = float(i);  // distinct per brick
  MajorantGridView grid{majorant.data(), {5, 4, 3}, {-10, -8, -6}, {0.25f, 0.25f, 0.25f}};  // 4 mm bricks
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int k = 0; k < 2000; ++k) {
    const Vec3f o{u(rng) * 10, u(rng) * 8, u(rng) * 6};
    Vec3f d{u(rng), u(rng), u(rng)};
    if (k % 5 == 0) d[k % 3] = 0.0f;  // axis-parallel rays
    if (Length(d) < 1e-3f) continue;
    d = Normalize(d);
    float t0, t1;
    ASSERT_TRUE(IntersectBox(o, {1 / d.x, 1 / d.y, 1 / d.z}, {-10, -8, -6}, {10, 8, 6}, t0, t1));
    MajorantIterator it(grid, o, d, t0, t1);
    MajorantSegment seg;
    float expected_start = t0;
    int segments = 0;
    while (it.Next(seg)) {
      ASSERT_NEAR(seg.t_min, expected_start, 1e-4f);
      ASSERT_GE(seg.t_max, seg.t_min);
      expected_start = seg.t_max;
      if (seg.t_max - seg.t_min < 1e-3f) continue;  // corner grazes: no reliable midpoint
      const Vec3f mid = o + d * (0.5f * (seg.t_min + seg.t_max));
      Vec3i b;
      for (int a = 0; a < 3; ++a)
        b[a] = std::clamp(int(std::floor((mid[a] - grid.box_min[a]) * 0.25f)), 0, grid.bricks[a] - 1);
      ASSERT_EQ(seg.sigma_maj, grid.At(b)) << "segment " << segments << " of ray " << k;
      ++segments;
    }
    EXPECT_NEAR(expected_start, t1, 1e-4f);
    EXPECT_LE(segments, 5 + 4 + 3);
  }
}

// Coarse scans get 2^3 bricks, others 4^3, decided by the finest axis and
// bounded by the voxel count; the cache keys the copy by the size chosen, so
// asking for it by name shares it.
TEST(MajorantGrid, BricksAreSmallerInCoarseScans) {
  auto volume_with_spacing = [](Vec3f spacing) {
    VolumeMetadata meta;
    meta.source = "spacing";
    return std::make_shared<const Volume>(Vec3i{8, 8, 8}, spacing, std::vector<float>(512, 0.0f), meta);
  };
  EXPECT_EQ(BrickSizeFor(*volume_with_spacing({1, 1, 2})), 4);           // CThead
  EXPECT_EQ(BrickSizeFor(*volume_with_spacing({0.7f, 0.7f, 3})), 4);     // thick slices, fine in-plane
  EXPECT_EQ(BrickSizeFor(*volume_with_spacing({1.25f, 1.25f, 1.25f})), 4);
  EXPECT_EQ(BrickSizeFor(*volume_with_spacing({1.5f, 1.5f, 1.5f})), 2);  // the aorta crop
  EXPECT_EQ(BrickSizeFor(*volume_with_spacing({3, 3, 3})), 2);
  // A coarse scan too large for 2^3 bricks within 4^3's memory keeps 4^3.
  EXPECT_EQ(BrickSizeFor({3, 3, 3}, kMaxVoxels / 8), 2);
  EXPECT_EQ(BrickSizeFor({3, 3, 3}, kMaxVoxels / 8 + 1), 4);
  const auto coarse = volume_with_spacing({1.5f, 1.5f, 1.5f});
  const auto chosen = VolumeCache::Get().Acquire(coarse, kAutoBrickSize, kHostDevice);
  EXPECT_EQ(chosen->prepared().brick_size(), (Vec3i{2, 2, 2}));
  EXPECT_EQ(VolumeCache::Get().Acquire(coarse, 2, kHostDevice), chosen);
  EXPECT_EQ(PreparedVolume(coarse, kAutoBrickSize).brick_size(), (Vec3i{2, 2, 2}));
}

}  // namespace
}  // namespace cinevol
