// A DICOM series is a folder: the files a load of one may read, found by the
// parent before the reader cage's child sees any (the child decides which of
// them are DICOM).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "io/reader_cage.h"
#include "io/volume_loader.h"

namespace cinevol::formats::dicom {

// The regular files under `folder` (subfolders included, symlinked folders
// not followed) that the policy lets a load read, sorted by their path under
// the folder: FIFOs, sockets and devices are skipped without being opened;
// kInsideRoots keeps files inside the roots, kNone files inside the folder
// itself. Only names and types are looked at. Messages call it `shown`.
std::vector<reader_cage::Input> FolderFiles(const std::filesystem::path& folder, const LoadPolicy& policy,
                                            const std::string& shown);

}  // namespace cinevol::formats::dicom
