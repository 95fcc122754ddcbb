// The volume formats cinevol reads, told apart in one place: by name (and a
// NRRD by its magic), and the other files a volume file's header names, which
// the parent checks against the load's policy before a reader sees a byte.
// Each format's own knowledge is in its folder beside this file: what its
// header names (references.h, the parent's and the child's) and the checks in
// front of its third-party reader (checks.h, run inside the reader cage).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace cinevol::formats {

enum class Format { kUnknown, kNifti, kNrrd, kMetaImage, kVtk, kDicom };

// What messages call a format's reader: "NIfTI", "NRRD", "MetaImage", "VTK",
// "DICOM"; "" for kUnknown.
std::string ReaderName(Format format);

// A volume file's format by its name alone, any case, one ".gz" ignored: as
// the readers choose (NRRD too is read whatever the name says, by its magic).
Format FormatOfName(const std::string& name);

// The ending of `name` (as written) that the readers choose a format by:
// ".nii.gz", ".hdr", ".nrrd", ".mha", ...; "" when it has none of them.
std::string KnownEnding(const std::string& name);

// The other files a volume file's header names.
struct References {
  std::string field;                         // "data file", "ElementDataFile", ...; empty: none
  std::vector<std::filesystem::path> files;  // resolved against the header's folder
  std::string problem;                       // why `files` could not be listed; "" when they were
};

// Finds the files `file`'s header names (NRRD/NHDR "data file", MetaImage
// "ElementDataFile", a NIfTI/Analyze .hdr/.img pair), reading only `file`.
References FindReferences(const std::filesystem::path& file, const std::string& shown);

}  // namespace cinevol::formats
