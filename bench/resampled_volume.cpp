#include "resampled_volume.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "core/error.h"
#include "core/parallel_for.h"
#include "io/volume_loader.h"

namespace cinevol::bench {

std::vector<std::int16_t> Resample(const Volume& source, Vec3i dims) {
  const Vec3i s = source.dims();
  std::vector<std::int16_t> out(std::size_t(dims.x) * dims.y * dims.z);
  const auto value = [&](int x, int y, int z) {
    return source.Value(std::clamp(x, 0, s.x - 1), std::clamp(y, 0, s.y - 1), std::clamp(z, 0, s.z - 1));
  };
  ParallelFor(dims.z, [&](std::int64_t z) {
    // Voxel centres map onto the source's: (i + 0.5) s / n - 0.5.
    const float fz = (float(z) + 0.5f) * float(s.z) / float(dims.z) - 0.5f;
    const int z0 = int(std::floor(fz));
    const float wz = fz - float(z0);
    for (int y = 0; y < dims.y; ++y) {
      const float fy = (float(y) + 0.5f) * float(s.y) / float(dims.y) - 0.5f;
      const int y0 = int(std::floor(fy));
      const float wy = fy - float(y0);
      for (int x = 0; x < dims.x; ++x) {
        const float fx = (float(x) + 0.5f) * float(s.x) / float(dims.x) - 0.5f;
        const int x0 = int(std::floor(fx));
        const float wx = fx - float(x0);
        float v = 0;
        for (int k = 0; k < 8; ++k) {
          const int dx = k & 1, dy = k >> 1 & 1, dz = k >> 2;
          v += (dx ? wx : 1 - wx) * (dy ? wy : 1 - wy) * (dz ? wz : 1 - wz) * value(x0 + dx, y0 + dy, z0 + dz);
        }
        out[(std::size_t(z) * dims.y + y) * dims.x + x] = std::int16_t(std::lround(std::clamp(v, -32768.0f, 32767.0f)));
      }
    }
  });
  return out;
}

void WriteNrrd(const std::filesystem::path& file, Vec3i dims, Vec3f spacing, const std::vector<std::int16_t>& voxels,
               const Volume& source) {
  const VolumeMetadata& m = source.metadata();
  const Vec3f old_spacing = source.spacing_mm();
  // The first voxel's centre moves by half the change of a voxel's size along
  // each axis, so that both grids cover the same box.
  std::array<double, 3> origin = m.origin_mm;
  std::string directions;
  for (int c = 0; c < 3; ++c) {
    const double shift = 0.5 * (double(spacing[c]) - double(old_spacing[c]));
    for (int r = 0; r < 3; ++r) origin[r] += m.direction[3 * r + c] * shift;
    directions += fmt::format(" ({},{},{})", m.direction[c] * spacing[c], m.direction[3 + c] * spacing[c],
                              m.direction[6 + c] * spacing[c]);
  }
  std::ofstream out(file, std::ios::binary);
  out << fmt::format("NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: {} {} {}\n"
                     "space directions:{}\nspace origin: ({},{},{})\nencoding: raw\nendian: little\n\n",
                     dims.x, dims.y, dims.z, directions, origin[0], origin[1], origin[2]);
  out.write(reinterpret_cast<const char*>(voxels.data()), std::streamsize(voxels.size() * sizeof(std::int16_t)));
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

void RunResample(const std::string& spec, Vec3i dims, const std::filesystem::path& file) {
  const double voxels = double(dims.x) * dims.y * dims.z;
  if (!(dims.x > 0 && dims.y > 0 && dims.z > 0) || voxels > double(1u << 31)) {
    throw InputError(fmt::format("--size {}x{}x{}: each side at least 1, at most 2^31 voxels", dims.x, dims.y, dims.z));
  }
  const Volume source = LoadVolume(ParseVolumeSpec(spec));
  if (source.min_value() < -32768.0f || source.max_value() > 32767.0f) {
    throw InputError(fmt::format("{}: values {} to {} do not fit a 16-bit NRRD", spec, source.min_value(),
                                 source.max_value()));
  }
  const Vec3f spacing = source.extent_mm() / ToFloat(dims);
  WriteNrrd(file, dims, spacing, Resample(source, dims), source);
  std::printf("%s: %dx%dx%d, %.3fx%.3fx%.3f mm (from %dx%dx%d)\n", file.c_str(), dims.x, dims.y, dims.z, spacing.x,
              spacing.y, spacing.z, source.dims().x, source.dims().y, source.dims().z);
}

}  // namespace cinevol::bench
