// Inside the reader cage: what stands in front of ITK's VTK legacy reader.
// VTK headers name no other file; a binary payload must be whole.
#pragma once

#include <filesystem>
#include <string>

namespace itk {
class ImageIOBase;
}

namespace cinevol::formats::vtk {

// "" when a binary file holds every voxel `io` (the header as ITK read it)
// expects, or the file is ASCII; else what is wrong.
std::string PayloadProblem(itk::ImageIOBase& io, const std::filesystem::path& path);

}  // namespace cinevol::formats::vtk
