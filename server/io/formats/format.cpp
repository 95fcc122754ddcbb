// The formats by name and magic, and which format's header names which files.
#include "io/formats/format.h"

#include <cctype>
#include <string_view>

#include "io/formats/metaimage/references.h"
#include "io/formats/nifti/references.h"
#include "io/formats/nrrd/references.h"

namespace fs = std::filesystem;

namespace cinevol::formats {
namespace {

// The name endings the readers choose a format by (lower case), and whether
// the reader takes the gzipped name (".nii.gz") as its own too.
struct Ending {
  std::string_view ending;
  Format format;
  bool gzipped_too;
};
constexpr Ending kEndings[] = {
    {".nii", Format::kNifti, true},       {".hdr", Format::kNifti, true},       {".img", Format::kNifti, true},
    {".nia", Format::kNifti, false},      {".nrrd", Format::kNrrd, true},       {".nhdr", Format::kNrrd, false},
    {".mha", Format::kMetaImage, false},  {".mhd", Format::kMetaImage, false},  {".vtk", Format::kVtk, false},
};

std::string Lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::string ReaderName(Format format) {
  switch (format) {
    case Format::kNifti: return "NIfTI";
    case Format::kNrrd: return "NRRD";
    case Format::kMetaImage: return "MetaImage";
    case Format::kVtk: return "VTK";
    case Format::kDicom: return "DICOM";
    default: return "";
  }
}

Format FormatOfName(const std::string& name) {
  std::string lower = Lower(name);
  if (lower.ends_with(".gz")) lower.resize(lower.size() - 3);
  for (const Ending& e : kEndings) {
    if (lower.ends_with(e.ending)) return e.format;
  }
  return Format::kUnknown;
}

std::string KnownEnding(const std::string& name) {
  const std::string lower = Lower(name);
  for (const Ending& e : kEndings) {
    const std::string gzipped = std::string(e.ending) + ".gz";
    const std::size_t n = e.gzipped_too && lower.ends_with(gzipped) ? gzipped.size()
                          : lower.ends_with(e.ending)               ? e.ending.size()
                                                                    : 0;
    if (n > 0) return name.substr(name.size() - n);
  }
  return "";
}

References FindReferences(const fs::path& file, const std::string& shown) {
  const std::string ending = Lower(KnownEnding(file.filename().string()));
  switch (FormatOfName(ending)) {
    case Format::kNifti:
      return nifti::IsPairName(ending) ? nifti::PairReferences(file) : nifti::FindReferences(file);
    case Format::kMetaImage:
      return metaimage::FindReferences(file, shown);
    default:
      break;
  }
  // teem reads any file that starts with the magic, whatever the name says.
  if (nrrd::HasMagic(file, shown)) return nrrd::ParseHeader(file, shown).references;
  return {};
}

}  // namespace cinevol::formats
