// The VTK legacy reader's payload check.
#include "io/formats/vtk/checks.h"

#include <itkImageIOBase.h>

#include <cstdint>

#include "io/formats/payload.h"

namespace cinevol::formats::vtk {

std::string PayloadProblem(itk::ImageIOBase& io, const std::filesystem::path& path) {
  if (io.GetFileType() != itk::IOFileEnum::Binary) return "";
  return UncompressedPayloadProblem(path, path, 0, std::int64_t(io.GetImageSizeInBytes()));
}

}  // namespace cinevol::formats::vtk
