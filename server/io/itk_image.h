// Internal to server/io: converting an ITK float image into a Volume.
#pragma once

#include <itkImage.h>
#include <itkImageIOBase.h>

#include <string>

#include "core/volume.h"

namespace cinevol::itk_image {

using FloatImage = itk::Image<float, 3>;

// Registers the image formats cinevol reads and routes ITK/GDCM warnings away
// from stderr (failures still throw). Safe to call from any thread, often.
void InitToolkits();

// "int16", "uint8", "float32", ... for a file's voxel type.
std::string ComponentName(itk::IOComponentEnum type);

// Moves the pixels of `image` into a Volume with its spacing, origin and
// direction; `meta` supplies the rest.
Volume ToVolume(FloatImage* image, VolumeMetadata meta);

}  // namespace cinevol::itk_image
