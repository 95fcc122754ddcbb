// Volumes on grids the shared data lack (a clinical CT's 2,000 slices, an MR
// head's 256x256x120): a volume resampled (trilinear) over its own box and
// written as a raw 16-bit NRRD that keeps its patient orientation.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/volume.h"

namespace cinevol::bench {

// `source`'s values at the centres of a `dims` grid over the same box.
std::vector<std::int16_t> Resample(const Volume& source, Vec3i dims);

// Writes `voxels` (`dims`, x fastest) `spacing` mm apart, placed and oriented
// as `source` was: the same first corner, the same patient directions.
void WriteNrrd(const std::filesystem::path& file, Vec3i dims, Vec3f spacing, const std::vector<std::int16_t>& voxels,
               const Volume& source);

// `cinevol-bench resample`: the volume `spec` names, resampled to `dims` over
// its box, written to `file`.
void RunResample(const std::string& spec, Vec3i dims, const std::filesystem::path& file);

}  // namespace cinevol::bench
