// A time series written as a 4-D NIfTI-1 file for tests: a sphere of 1000 in
// 0 that moves one voxel along index x a phase (issue 59's phantom: picks and
// slices follow it exactly).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

namespace cinevol::testing {

struct MovingSphere {
  int size = 24;  // voxels a side, 1 mm
  int phases = 5;
  float seconds_apart = 0.1f;
  float radius = 5;
  // Phase k's centre: (first_x + k / moves_every, size/2, size/2) in voxel
  // indices: with moves_every 2, phases come in pairs alike.
  int first_x = 8;
  int moves_every = 1;
  // The header's phase count where it should lie about the file (0: phases).
  int header_phases = 0;
  bool float_voxels = false;  // float32 voxels (1000.5 in the sphere), which the renderer quantises (else int16)
};

// Writes `sphere` to `path` (.nii): int16 (or float32) voxels, 1 mm, the time step in seconds.
inline void WriteMovingSphere(const std::filesystem::path& path, const MovingSphere& sphere) {
  unsigned char header[352] = {};
  const auto put = [&](int offset, auto value) { std::memcpy(header + offset, &value, sizeof value); };
  put(0, std::int32_t{348});
  const std::int16_t dims[8] = {4,
                                std::int16_t(sphere.size),
                                std::int16_t(sphere.size),
                                std::int16_t(sphere.size),
                                std::int16_t(sphere.header_phases ? sphere.header_phases : sphere.phases),
                                1,
                                1,
                                1};
  std::memcpy(header + 40, dims, sizeof dims);
  put(70, std::int16_t(sphere.float_voxels ? 16 : 4));   // datatype: float32 or int16
  put(72, std::int16_t(sphere.float_voxels ? 32 : 16));  // bitpix
  const float pixdim[8] = {1, 1, 1, 1, sphere.seconds_apart, 0, 0, 0};
  std::memcpy(header + 76, pixdim, sizeof pixdim);
  put(108, float{352});       // vox_offset
  put(112, float{1});         // scl_slope
  header[123] = 2 | 8;        // xyzt_units: mm, seconds
  put(252, std::int16_t{1});  // qform_code: scanner
  std::memcpy(header + 344, "n+1\0", 4);
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(header), sizeof header);
  const int n = sphere.size;
  std::vector<float> voxels(std::size_t(n) * n * n);
  const float inside = sphere.float_voxels ? 1000.5f : 1000.0f;  // a fraction: held as float, not 16-bit
  for (int k = 0; k < sphere.phases; ++k) {
    for (int z = 0; z < n; ++z) {
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const float dx = float(x - sphere.first_x - k / sphere.moves_every), dy = float(y - n / 2), dz = float(z - n / 2);
          voxels[(std::size_t(z) * n + y) * n + x] = std::sqrt(dx * dx + dy * dy + dz * dz) <= sphere.radius ? inside : 0.0f;
        }
      }
    }
    if (sphere.float_voxels) {
      out.write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * sizeof(float)));
      continue;
    }
    const std::vector<std::int16_t> stored(voxels.begin(), voxels.end());
    out.write(reinterpret_cast<const char*>(stored.data()), std::streamsize(stored.size() * sizeof(std::int16_t)));
  }
}

}  // namespace cinevol::testing
