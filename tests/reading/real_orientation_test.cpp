// Slices of real files agree with `cinevol info` (issue 36): for a NIfTI
// stored RAS and a DICOM series stored LPS, the orientation code the command
// prints says which end of each index axis lies towards which side of the
// patient; the library's axial, coronal and sagittal slices must carry the
// radiological letters of docs/reading.md and show, pixel for pixel, the
// voxels that code puts at each edge (the patient's right on the left, and
// so on), not a mirror image of them.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <regex>
#include <string>

#include "io/volume_loader.h"
#include "reading/slice.h"
#include "reading/window_level.h"
#include "service/server_process.h"
#include "support/test_paths.h"

namespace cinevol::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The orientation code `cinevol info PATH` prints ("RAS", "LPS", ...).
std::string InfoOrientation(const fs::path& path) {
  const fs::path log = fs::temp_directory_path() / ("cinevol-info-" + std::to_string(getpid()) + ".log");
  const auto [code, output] = RunProgram(CliPath(), {"info", path.string()}, log, 60s);
  fs::remove(log);
  EXPECT_EQ(code, 0) << output;
  std::smatch m;
  if (!std::regex_search(output, m, std::regex("orientation: +([LRAPSI]{3}) "))) {
    ADD_FAILURE() << "no orientation line: " << output;
    return "";
  }
  return m[1];
}

// A slice as docs/reading.md's table has it: the letters at its left and top
// edges; `across` names the third axis (the one the slice crosses).
struct Convention {
  SliceAxis axis;
  const char* name;
  char left, top, across;  // across: one letter of the pair the slice's position runs along
  const char* letters;     // left, right, top, bottom
};
constexpr Convention kConventions[] = {{SliceAxis::kAxial, "axial", 'R', 'A', 'S', "RLAP"},
                                       {SliceAxis::kCoronal, "coronal", 'R', 'S', 'A', "RLSI"},
                                       {SliceAxis::kSagittal, "sagittal", 'A', 'S', 'L', "APSI"}};

const std::string kLetters = "LRPASI";  // in pairs, LPS's positive side first
char Opposite(char letter) { return kLetters[kLetters.find(letter) ^ 1]; }

// Which index axis of a volume with orientation `code` runs towards patient
// side `letter` or away from it, and whether it runs towards it.
struct IndexAxis {
  int axis = -1;
  bool towards = false;
};
IndexAxis AxisTowards(const std::string& code, char letter) {
  for (int a = 0; a < 3; ++a) {
    if (code[a] == letter || code[a] == Opposite(letter)) return {a, code[a] == letter};
  }
  ADD_FAILURE() << code << " has no axis along " << letter;
  return {};
}

// The LPS position (mm) of a voxel's centre, from the volume's origin and direction cosines.
std::array<double, 3> VoxelLps(const Volume& volume, const std::array<int, 3>& index) {
  const VolumeMetadata& m = volume.metadata();
  const Vec3f s = volume.spacing_mm();
  const double mm[3] = {index[0] * double(s.x), index[1] * double(s.y), index[2] * double(s.z)};
  std::array<double, 3> p = m.origin_mm;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p[r] += m.direction[3 * r + c] * mm[c];
  }
  return p;
}

int Dim(const Volume& volume, int axis) {
  return axis == 0 ? volume.dims().x : (axis == 1 ? volume.dims().y : volume.dims().z);
}

// The LPS component a letter's pair runs along (L/R: 0, P/A: 1, S/I: 2) and
// its sign towards the letter (+1 for L, P, S).
int LpsComponent(char letter) { return int(kLetters.find(letter) / 2); }
double LpsSign(char letter) { return kLetters.find(letter) % 2 == 0 ? 1 : -1; }

// Checks one slice of `volume` against the orientation `code` that `cinevol info` printed.
void CheckSlice(const Volume& volume, const std::string& code, const Convention& c) {
  SCOPED_TRACE(std::string(c.name) + " of " + code);
  const IndexAxis across = AxisTowards(code, c.left), down = AxisTowards(code, c.top),
                  through = AxisTowards(code, c.across);
  ASSERT_EQ(across.axis + down.axis + through.axis, 3) << "three different index axes";
  // Through the middle voxel of the crossed axis: a pixel sits on a voxel centre.
  std::array<int, 3> middle{};
  middle[through.axis] = Dim(volume, through.axis) / 2;
  const double position = VoxelLps(volume, middle)[LpsComponent(c.across)];

  SliceSpec spec;
  spec.axis = c.axis;
  spec.position_mm = float(position);
  spec.nearest = true;
  spec.window = {0.5 * (volume.min_value() + volume.max_value()) + 0.5,
                 std::max(1.0, double(volume.max_value()) - volume.min_value())};
  const SliceImage slice = RenderSlice(volume, {}, nullptr, spec);
  const SliceGeometry& g = slice.geometry;
  const EdgeLetters& e = g.letters;
  EXPECT_EQ(e.left + e.right + e.top + e.bottom, c.letters) << "docs/reading.md's table";
  ASSERT_EQ(g.width, Dim(volume, across.axis)) << "one pixel per voxel across";
  ASSERT_EQ(g.height, Dim(volume, down.axis)) << "one pixel per voxel down";

  // The voxel the code puts under pixel (column, row): column 0 at the
  // `left` end of its index axis, row 0 at the `top` end; or flipped
  // left-right or top-bottom, for a check that can tell.
  auto voxel_at = [&](int column, int row, bool flip_across = false, bool flip_down = false) {
    std::array<int, 3> index = middle;
    index[across.axis] = across.towards != flip_across ? g.width - 1 - column : column;
    index[down.axis] = down.towards != flip_down ? g.height - 1 - row : row;
    return index;
  };
  auto grey_of = [&](const std::array<int, 3>& v) {
    return int(ApplyVoiLinear(volume.Value(v[0], v[1], v[2]), spec.window));
  };
  int wrong = 0, wrong_flipped_across = 0, wrong_flipped_down = 0;
  for (int row = 0; row < g.height; ++row) {
    for (int column = 0; column < g.width; ++column) {
      const int grey = slice.image.bytes[3 * (std::size_t(row) * g.width + column)];
      wrong += grey != grey_of(voxel_at(column, row));
      wrong_flipped_across += grey != grey_of(voxel_at(column, row, true, false));
      wrong_flipped_down += grey != grey_of(voxel_at(column, row, false, true));
    }
  }
  EXPECT_EQ(wrong, 0) << "pixels that are not the voxel the orientation code puts there";
  EXPECT_GT(wrong_flipped_across, g.width * g.height / 100) << "the check would not see a left-right mirror";
  EXPECT_GT(wrong_flipped_down, g.width * g.height / 100) << "the check would not see a top-bottom mirror";

  // The left edge's voxels lie furthest towards `left` of all the volume's
  // voxel centres, the top edge's furthest towards `top`; the geometry says so too.
  for (const auto& [letter, pixel] : {std::pair{c.left, std::array<int, 2>{0, g.height / 2}},
                                      std::pair{Opposite(c.left), std::array<int, 2>{g.width - 1, g.height / 2}},
                                      std::pair{c.top, std::array<int, 2>{g.width / 2, 0}},
                                      std::pair{Opposite(c.top), std::array<int, 2>{g.width / 2, g.height - 1}}}) {
    const int component = LpsComponent(letter);
    const double sign = LpsSign(letter);
    const std::array<double, 3> shown = VoxelLps(volume, voxel_at(pixel[0], pixel[1]));
    double furthest = -INFINITY;
    for (int corner = 0; corner < 8; ++corner) {
      const std::array<int, 3> index{corner & 1 ? volume.dims().x - 1 : 0, corner & 2 ? volume.dims().y - 1 : 0,
                                     corner & 4 ? volume.dims().z - 1 : 0};
      furthest = std::max(furthest, sign * VoxelLps(volume, index)[component]);
    }
    EXPECT_NEAR(sign * shown[component], furthest, 1e-3)
        << "pixel " << pixel[0] << "," << pixel[1] << " is not at the " << letter << " end of the volume";
    const Vec3f at = g.PixelToPatient(float(pixel[0]), float(pixel[1]));
    EXPECT_NEAR(at[component], shown[component], 1e-2)
        << "the geometry's position of pixel " << pixel[0] << "," << pixel[1];
  }
}

void CheckAgainstInfo(const fs::path& path, const std::string& stored) {
  const std::string code = InfoOrientation(path);
  ASSERT_EQ(code, stored) << path << ": the test assumes the file is stored " << stored;
  const Volume volume = LoadVolume(ParseVolumeSpec(path.string()));
  for (const Convention& c : kConventions) CheckSlice(volume, code, c);
}

TEST(SliceOrientation, ANiftiStoredRasAgreesWithCinevolInfo) {
  CINEVOL_REQUIRE_SHARED_DATA();
  CheckAgainstInfo(SharedData() / "mr-head-seg3d-nifti" / "MR.nii.gz", "RAS");
}

TEST(SliceOrientation, ADicomSeriesStoredLpsAgreesWithCinevolInfo) {
  CINEVOL_REQUIRE_SHARED_DATA();
  CheckAgainstInfo(SharedData() / "mr-chest-dicom-seg3d", "LPS");
}

}  // namespace
}  // namespace cinevol::testing
