// Internal to the readers: what the ITK-based readers (volume files, DICOM
// series) share.
#pragma once

#include <itkImageIOBase.h>

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "cinevol/reader/reader.pb.h"

namespace cinevol::itk_image {

// Registers the image formats cinevol reads and routes ITK/GDCM warnings away
// from stderr (failures still throw). Safe to call from any thread, often.
void InitToolkits();

// InitToolkits, and what the readers would otherwise set up at their first
// file (GDCM's dictionary, each format's reader): a child does it while it
// waits for its request, so that a load does not wait for it.
void WarmUp();

// "int16", "uint8", "float32", ... for a file's voxel type.
std::string ComponentName(itk::IOComponentEnum type);

// The VoxelType name (core/voxel_memory.h) of an ITK component; "" for one
// cinevol does not read.
std::string VoxelTypeOf(itk::IOComponentEnum type);

// ITK's message without its source location and class prefix ("file.cxx:123:
// ITK ERROR: Class(0x...): "), with each of `paths` replaced by `shown`: ITK,
// teem and GDCM quote the paths they open, and messages must not.
std::string ItkMessage(const itk::ExceptionObject& e, const std::vector<std::filesystem::path>& paths,
                       const std::string& shown);

// Sets `header`'s grid: `direction` row-major, column c is index axis c.
void SetGeometry(reader::Header& header, const std::array<int, 3>& dims, std::array<double, 3> spacing,
                 const std::array<double, 3>& origin, std::array<double, 9> direction);

}  // namespace cinevol::itk_image
