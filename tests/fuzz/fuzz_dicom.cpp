// DICOM series from one input, mutated element by element: the input is a
// DICOM file (tests/fuzz/corpus/dicom/); its preamble's first byte asks for
// 1 to 3 slices, written as a folder of copies moved along the slice normal,
// and read as an upload's series through the reader cage's child entry point
// (reader::Job, as cinevol-reader and reader::ReadInProcess run it;
// DICOM_SERIES, pre-checks on, 4 Mi voxels), its answers checked as the
// parent would check them (fuzz_support.h).
// LLVMFuzzerCustomMutator parses the file into elements (dicom_model.h) and
// mutates tags, VRs, lengths, transfer syntaxes, the pixel module and the
// pixel data, JPEG 2000 codestreams included (j2k_model.h); CustomCrossOver
// moves pixel modules, payloads and elements between two files.
//
// CINEVOL_READER_PRECHECKS=off skips the pre-checks (DicomWalk), as the
// server's variable does. CINEVOL_FUZZ_VERBOSE=1 prints each outcome.
#include <cstddef>
#include <cstdint>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "dicom_model.h"
#include "fuzz_support.h"
#include "io/readers/reading.h"

namespace fs = std::filesystem;

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

constexpr std::uint64_t kMaxVoxels = std::uint64_t{1} << 22;

cinevol::fuzz::Scratch* scratch;

// The slices one input stands for: copies along the normal when it parses,
// else the bytes as one file.
std::vector<std::string> SliceFiles(const std::uint8_t* data, std::size_t size) {
  if (std::optional<cinevol::fuzz::DicomFile> file = cinevol::fuzz::ParseDicom(data, size)) {
    const int count = cinevol::fuzz::SliceCount(*file);
    if (count > 1) return cinevol::fuzz::Slices(*file, count);
  }
  return {std::string(reinterpret_cast<const char*>(data), size)};
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  scratch = new cinevol::fuzz::Scratch("cinevol-fuzz-dicom");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const fs::path folder = scratch->FreshInputDir();
  cinevol::reader::Request request =
      cinevol::fuzz::BaseRequest(cinevol::reader::Request::DICOM_SERIES, "upload:series", kMaxVoxels);
  request.set_work_dir(scratch->FreshWorkDir().string());
  std::vector<cinevol::UniqueFd> inputs;
  const std::vector<std::string> slices = SliceFiles(data, size);
  for (std::size_t i = 0; i < slices.size(); ++i) {
    const std::string name = "slice" + std::to_string(i) + ".dcm";
    cinevol::fuzz::WriteFile(folder / name, slices[i].data(), slices[i].size());
    request.add_file_names(name);
    inputs.push_back(cinevol::fuzz::OpenInput(folder / name));
  }
  try {
    cinevol::fuzz::ReadLikeTheChild(request, std::move(inputs));
  } catch (const std::bad_alloc&) {
    cinevol::fuzz::Verbose("out of memory\n");
    return 0;
  } catch (const std::exception& e) {
    cinevol::fuzz::RequireFailureWireForm(e.what());
    cinevol::fuzz::Verbose("refused (%zu slices): %s\n", slices.size(), e.what());
    return 0;
  }
  cinevol::fuzz::Verbose("loaded (%zu slices)\n", slices.size());
  return 0;
}

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
  return cinevol::fuzz::MutateDicomInPlace(data, size, max_size, seed, LLVMFuzzerMutate);
}

extern "C" std::size_t LLVMFuzzerCustomCrossOver(const std::uint8_t* data1, std::size_t size1,
                                                 const std::uint8_t* data2, std::size_t size2, std::uint8_t* out,
                                                 std::size_t max_out_size, unsigned int seed) {
  return cinevol::fuzz::CrossOverDicomInto(data1, size1, data2, size2, out, max_out_size, seed);
}
