// Volume files from an upload: the first byte picks the format, the rest is
// the file. Loaded with an upload's LoadPolicy (no references, 4 Mi voxels).
// InputError and other std::exceptions are the expected refusals; crashes,
// sanitizer reports, hangs and leaks are bugs.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <string>

#include "io/volume_loader.h"

namespace fs = std::filesystem;

namespace {

struct Format {
  const char* extension;  // "" for a DICOM file in a folder
};
constexpr Format kFormats[] = {{".nii"}, {".nii.gz"}, {".nrrd"}, {".mha"}, {".vtk"}, {""}};
constexpr std::size_t kFormatCount = sizeof kFormats / sizeof kFormats[0];

fs::path scratch;
// CINEVOL_FUZZ_VERBOSE=1: print each input's outcome (to check seeds and reproducers).
const bool verbose = std::getenv("CINEVOL_FUZZ_VERBOSE") != nullptr;

void RemoveScratch() {
  std::error_code ec;
  fs::remove_all(scratch, ec);
}

bool WriteFile(const fs::path& path, const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  const bool ok = std::fwrite(data, 1, size, f) == size;
  return std::fclose(f) == 0 && ok;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::string pattern = (fs::temp_directory_path() / "cinevol-fuzz-volume-XXXXXX").string();
  if (!mkdtemp(pattern.data())) std::abort();
  scratch = pattern;
  std::atexit(RemoveScratch);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const Format& format = kFormats[data[0] % kFormatCount];
  cinevol::LoadPolicy policy;
  policy.references = cinevol::LoadPolicy::References::kNone;
  policy.max_voxels = std::uint64_t{1} << 22;
  const bool dicom = format.extension[0] == '\0';
  policy.label = std::string("upload:fuzz") + (dicom ? ".dcm" : format.extension);
  std::error_code ec;
  fs::remove_all(scratch / "in", ec);
  fs::create_directory(scratch / "in");
  const fs::path file = scratch / "in" / (std::string("fuzz") + (dicom ? ".dcm" : format.extension));
  if (!WriteFile(file, data + 1, size - 1)) std::abort();
  try {
    if (dicom) {
      cinevol::LoadDicomSeries(scratch / "in", {}, policy);
    } else {
      cinevol::LoadVolumeFile(file, policy);
    }
  } catch (const std::exception& e) {
    if (verbose) std::fprintf(stderr, "refused: %s\n", e.what());
    return 0;
  }
  if (verbose) std::fprintf(stderr, "loaded\n");
  return 0;
}
