// What a PACS sends that the server itself parses, outside the reader cage: a
// DICOMweb answer's multipart/related body (multipart.h), and the Part 10
// objects cinevol reads with its own bounded parser (part10_reader.h): a
// measurement report (TID 1500 SR) and a presentation state, made a scene as
// LoadPresentation makes it. The first byte picks which (for a Part 10 file,
// the preamble's first byte, which the parser skips): 0 an SR, 1 a
// presentation state, 2 a multipart body (its first line the Content-Type,
// the rest the body). InputError and MultipartError are the expected
// refusals; a crash, a sanitizer report, a hang, or an accepted object that
// breaks the readers' documented limits is a bug. Part 10 inputs are mutated
// element by element, as fuzz_dicom's are (dicom_model.h): tags, VRs, lengths,
// sequences and items, nesting, elements moved between a report and a state.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "dicom_model.h"
#include "pacs/measurement_report.h"
#include "pacs/multipart.h"
#include "pacs/presentation_state.h"
#include "runtime/presentation_store.h"

namespace cv = cinevol;

extern "C" std::size_t LLVMFuzzerMutate(std::uint8_t* data, std::size_t size, std::size_t max_size);

namespace {

enum Kind { kReport = 0, kPresentation = 1, kMultipart = 2 };
Kind KindOf(const std::uint8_t* data) { return Kind(data[0] % 3); }

bool Placed(double v) { return std::isfinite(v) && std::abs(v) <= 1e6; }

void Report(std::string bytes) {
  cv::pacs::ReadReport report;
  try {
    report = cv::pacs::ReadMeasurementReport(std::move(bytes));
  } catch (const cv::InputError&) {
    return;
  }
  if (report.measurements.size() > cv::pacs::kMaxReportMeasurements) std::abort();
  for (cv::pacs::ReportMeasurement& m : report.measurements) {
    if (m.points.size() < 2 || m.points.size() > 3 || m.name.size() > 64) std::abort();
    if (!m.image_uid.empty()) {  // on an image: placed as the measurement store places it
      try {
        cv::pacs::PlaceOnImage(m, {{-100, -200, 50}, {1, 0, 0, 0, 1, 0}, {0.5, 0.75}, report.frame_of_reference_uid});
      } catch (const cv::InputError&) {
        continue;
      }
    }
    for (const auto& p : m.points) {
      for (double v : p) {
        if (!Placed(v)) std::abort();
      }
    }
  }
}

void Presentation(std::string bytes) {
  cv::pacs::ReadPresentation read;
  try {
    read = cv::pacs::ReadPresentationState(std::move(bytes));
  } catch (const cv::InputError&) {
    return;
  }
  if (read.input_images.empty()) std::abort();
  try {
    (void)cv::service::SceneOf(read, {1, 0, 0, 0, 1, 0});  // an axial series' row and column directions
  } catch (const cv::InputError&) {
  }
}

void Multipart(std::string_view text) {
  const std::size_t line_end = text.find('\n');
  if (line_end == std::string_view::npos) return;
  const std::string_view body = text.substr(line_end + 1);
  try {
    const std::string boundary = cv::pacs::MultipartBoundary(text.substr(0, line_end));
    constexpr std::size_t kMaxParts = 16;
    const auto parts = cv::pacs::SplitMultipart(body, boundary, kMaxParts);
    if (parts.size() > kMaxParts) std::abort();
    for (const cv::pacs::MultipartPart& part : parts) {
      // Every part is a view into the body it came from (an empty one may be a view of nothing).
      for (std::string_view view : {part.headers, part.body}) {
        if (view.empty()) continue;
        if (view.data() < body.data() || view.data() + view.size() > body.data() + body.size()) std::abort();
      }
      (void)cv::pacs::PartMediaType(part.headers);
    }
  } catch (const cv::pacs::MultipartError&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1 << 20)) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  switch (KindOf(data)) {
    case kReport:
      Report(std::string(text));
      break;
    case kPresentation:
      Presentation(std::string(text));
      break;
    case kMultipart:
      Multipart(text.substr(1));
      break;
  }
  return 0;
}

extern "C" std::size_t LLVMFuzzerCustomMutator(std::uint8_t* data, std::size_t size, std::size_t max_size,
                                               unsigned int seed) {
  if (size == 0 || KindOf(data) == kMultipart) return LLVMFuzzerMutate(data, size, max_size);
  return cv::fuzz::MutateDicomInPlace(data, size, max_size, seed, LLVMFuzzerMutate);
}

extern "C" std::size_t LLVMFuzzerCustomCrossOver(const std::uint8_t* data1, std::size_t size1,
                                                 const std::uint8_t* data2, std::size_t size2, std::uint8_t* out,
                                                 std::size_t max_out_size, unsigned int seed) {
  return cv::fuzz::CrossOverDicomInto(data1, size1, data2, size2, out, max_out_size, seed);
}
