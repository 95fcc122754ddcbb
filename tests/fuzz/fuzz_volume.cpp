// Volume files from an upload: the first byte picks the format, the rest is
// the file. What the server does with an upload, in this process: the
// parent's checks (the header may name no other file), then the reader
// cage's child entry point (reader::Job, as cinevol-reader and
// reader::ReadInProcess run it) with an upload's request (4 Mi voxels at
// most), the readers' pre-checks on, and between its steps the parent's
// checks of what it would receive (fuzz_support.h). InputError and other
// std::exceptions are the expected refusals; crashes, sanitizer reports,
// hangs, leaks in cinevol's code and answers that would not reach the parent
// are bugs.
//
// CINEVOL_READER_PRECHECKS=off skips the pre-checks, as the server's
// variable does: the committed regression inputs then crash this process.
// CINEVOL_FUZZ_VERBOSE=1 prints each input's outcome.
#include <fcntl.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "fuzz_support.h"
#include "io/file_checks.h"
#include "io/formats/format.h"
#include "io/readers/reading.h"

namespace fs = std::filesystem;

namespace {

using cinevol::fuzz::Scratch;

struct Format {
  const char* extension;  // "" for a DICOM file in a folder
};
constexpr Format kFormats[] = {{".nii"}, {".nii.gz"}, {".nrrd"}, {".mha"}, {".vtk"}, {""}};
constexpr std::size_t kFormatCount = sizeof kFormats / sizeof kFormats[0];
constexpr std::uint64_t kMaxVoxels = std::uint64_t{1} << 22;

Scratch* scratch;

// The parent's checks before any reader: the header may name no other file.
void CheckUpload(const fs::path& file, const std::string& shown) {
  cinevol::LoadPolicy policy;
  policy.references = cinevol::LoadPolicy::References::kNone;
  policy.label = shown;
  const cinevol::formats::References refs = cinevol::formats::FindReferences(file, shown);
  cinevol::file_checks::CheckReferences(refs, policy, shown);
}

// The child's work on the file's descriptor.
void ReadUpload(const fs::path& file, const std::string& shown) {
  cinevol::reader::Request request = cinevol::fuzz::BaseRequest(cinevol::reader::Request::VOLUME, shown, kMaxVoxels);
  request.add_file_names(file.filename().string());
  request.set_work_dir(scratch->FreshWorkDir().string());
  std::vector<cinevol::UniqueFd> inputs;
  inputs.emplace_back(cinevol::fuzz::OpenInput(file));
  cinevol::fuzz::ReadLikeTheChild(request, std::move(inputs));
}

// One DICOM file in a folder, read as a series.
void ReadDicomUpload(const fs::path& file, const std::string& shown) {
  cinevol::reader::Request request =
      cinevol::fuzz::BaseRequest(cinevol::reader::Request::DICOM_SERIES, shown, kMaxVoxels);
  request.add_file_names(file.filename().string());
  request.set_work_dir(scratch->FreshWorkDir().string());
  std::vector<cinevol::UniqueFd> inputs;
  inputs.emplace_back(cinevol::fuzz::OpenInput(file));
  cinevol::fuzz::ReadLikeTheChild(request, std::move(inputs));
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  scratch = new Scratch("cinevol-fuzz-volume");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const Format& format = kFormats[data[0] % kFormatCount];
  const bool dicom = format.extension[0] == '\0';
  const std::string name = std::string("fuzz") + (dicom ? ".dcm" : format.extension);
  const fs::path folder = scratch->FreshInputDir();
  const fs::path file = folder / name;
  cinevol::fuzz::WriteFile(file, data + 1, size - 1);
  if (!dicom) {
    try {
      CheckUpload(file, "upload:" + name);
    } catch (const std::exception& e) {
      cinevol::fuzz::Verbose("refused before the reader: %s\n", e.what());
      return 0;
    }
  }
  try {
    if (dicom) {
      ReadDicomUpload(file, "upload:" + name);
    } else {
      ReadUpload(file, "upload:" + name);
    }
  } catch (const std::bad_alloc&) {
    cinevol::fuzz::Verbose("out of memory\n");
    return 0;
  } catch (const std::exception& e) {
    cinevol::fuzz::RequireFailureWireForm(e.what());
    cinevol::fuzz::Verbose("refused: %s\n", e.what());
    return 0;
  }
  cinevol::fuzz::Verbose("loaded\n");
  return 0;
}
