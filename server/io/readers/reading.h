// Inside the reader cage: what cinevol-reader does with one request
// (cinevol/reader/reader.proto). The fuzz targets and the in-process
// benchmark call the same, without the process and its sandbox around it.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "cinevol/reader/reader.pb.h"
#include "io/reader_channel.h"

namespace cinevol::reader {

class VolumeRead;  // a volume whose header is read and voxels are not yet

class Job {
 public:
  // Takes the request and its inputs' descriptors (one per file name) and
  // places what the readers open by name in the request's work folder: links
  // to the inputs and an empty file for a rewritten header. These are the
  // job's only writes; the sandbox comes after.
  Job(Request request, std::vector<UniqueFd> inputs);
  ~Job();
  Job(const Job&) = delete;
  Job& operator=(const Job&) = delete;

  // Reads up to the first answer: a header (then Write), a series list or a
  // label table. Throws InputError for a bad input, std::bad_alloc when out
  // of memory.
  Reply Answer();
  // Writes the voxels (or pixels) Answer's header announced into `memory`,
  // `bytes` long: of phase `phase` of a time series (from 0, in order; one
  // call a phase).
  void Write(void* memory, std::size_t bytes, int phase = 0);

 private:
  std::string InputPath(std::size_t i) const;  // what the readers open for input i

  Request request_;
  std::vector<UniqueFd> inputs_;
  UniqueFd scratch_;  // the rewritten header's file, when one may be needed
  std::filesystem::path scratch_path_;
  std::unique_ptr<VolumeRead> volume_;
  std::vector<float> pixels_;  // EXR_IMAGE: RGB, read with the header
};

// The answer to a request and its voxels in this process: what a child
// would do, for fuzzing and for measuring the cage's cost. `memory` receives
// the voxels (resized; a time series' phases one after another); exceptions
// as Job's.
Reply ReadInProcess(const Request& request, std::vector<UniqueFd> inputs, std::vector<unsigned char>& memory);

}  // namespace cinevol::reader
