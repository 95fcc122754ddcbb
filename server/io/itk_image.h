// Internal to server/io: converting an ITK float image into a Volume.
#pragma once

#include <itkImage.h>
#include <itkImageIOBase.h>

#include <filesystem>
#include <string>
#include <vector>

#include "core/volume.h"

namespace cinevol::itk_image {

using FloatImage = itk::Image<float, 3>;

// Registers the image formats cinevol reads and routes ITK/GDCM warnings away
// from stderr (failures still throw). Safe to call from any thread, often.
void InitToolkits();

// "int16", "uint8", "float32", ... for a file's voxel type.
std::string ComponentName(itk::IOComponentEnum type);

// ITK's message without its source location and class prefix ("file.cxx:123:
// ITK ERROR: Class(0x...): "), with each of `paths` replaced by `shown`: ITK,
// teem and GDCM quote the paths they open, and messages must not.
std::string ItkMessage(const itk::ExceptionObject& e, const std::vector<std::filesystem::path>& paths,
                       const std::string& shown);

// Moves the pixels of `image` into a Volume with its spacing, origin and
// direction; `meta` supplies the rest.
Volume ToVolume(FloatImage* image, VolumeMetadata meta);

}  // namespace cinevol::itk_image
