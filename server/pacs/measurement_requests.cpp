// A source series described, and one instance retrieved into memory.
#include "pacs/measurement_requests.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <set>

#include "core/error.h"
#include "pacs/dicomweb_requests.h"
#include "pacs/multipart.h"
#include "pacs/pacs_error.h"

namespace cinevol::pacs {
namespace {

constexpr std::uint32_t kSopClassUid = 0x00080016;
constexpr std::uint32_t kFrameOfReferenceUid = 0x00200052;
constexpr std::uint32_t kImagePositionPatient = 0x00200032;
constexpr std::uint32_t kImageOrientationPatient = 0x00200037;
constexpr std::uint32_t kPixelSpacing = 0x00280030;
// Room for a multipart answer's delimiters and part headers around the instance.
constexpr std::size_t kMultipartOverhead = 64 << 10;

}  // namespace

ReportSource DescribeSourceSeries(const DicomWebClient& pacs, const std::string& study_uid,
                                    const std::string& series_uid, const std::string& known_frame,
                                    const std::atomic<bool>* cancel) {
  const PacsConfig& config = pacs.config();
  const std::string series_url = SeriesUrl(config, study_uid, series_uid);
  const std::string what = "a listing of the source series' images";
  JsonDocument storage;
  const auto datasets =
      FetchDicomJson(config, what,
                     series_url + fmt::format("/instances?limit={}&includefield=00200052&includefield=00080016",
                                              config.max_instances + 1),
                     cancel, storage);
  ReportSource source;
  std::set<std::string> frames, seen;
  for (const DicomJsonDataset& dataset : datasets) {
    ReportImage image{dataset.Text(kSopClassUid), dataset.Text(tag::kSopInstanceUid)};
    if (!IsValidUid(image.sop_class_uid) || !IsValidUid(image.sop_instance_uid)) {
      throw PacsError(fmt::format("PACS '{}' answered {} with an instance whose SOP class or instance UID is not a UID",
                                  config.name, what));
    }
    if (!seen.insert(image.sop_instance_uid).second) continue;
    if (source.images.size() == config.max_instances) {
      throw OverLimit("pacs-max-instances", fmt::format("PACS '{}': the series has more than {} instances, the limit "
                                                        "(max_instances)",
                                                        config.name, config.max_instances));
    }
    const std::string frame = dataset.Text(kFrameOfReferenceUid);
    if (IsValidUid(frame)) frames.insert(frame);
    source.images.push_back(std::move(image));
  }
  if (source.images.empty()) {
    throw PacsError(fmt::format("PACS '{}' lists no instances of the source series", config.name), 404);
  }
  if (frames.empty() && IsValidUid(known_frame)) frames.insert(known_frame);
  if (frames.empty()) {  // a PACS need not answer every includefield: one instance's metadata says it
    JsonDocument metadata_storage;
    const auto metadata = FetchDicomJson(
        config, "a retrieve of an instance's metadata",
        series_url + "/instances/" + EscapeUrlComponent(source.images.front().sop_instance_uid) + "/metadata", cancel,
        metadata_storage);
    for (const DicomJsonDataset& dataset : metadata) {
      const std::string frame = dataset.Text(kFrameOfReferenceUid);
      if (IsValidUid(frame)) frames.insert(frame);
    }
  }
  if (frames.empty()) {
    throw PacsError(
        fmt::format("PACS '{}': the source series names no Frame of Reference UID (0020,0052), so its "
                    "patient coordinates have no frame a report could name",
                    config.name));
  }
  if (frames.size() > 1) {
    throw PacsError(
        fmt::format("PACS '{}': the source series' instances name {} frames of reference; a report "
                    "names one",
                    config.name, frames.size()));
  }
  if (IsValidUid(known_frame) && *frames.begin() != known_frame) {
    throw PacsError(
        fmt::format("PACS '{}' names frame of reference {} for the source series, whose files named {} "
                    "when it was read",
                    config.name, *frames.begin(), known_frame));
  }
  source.frame_of_reference_uid = *frames.begin();
  return source;
}

ImagePlane FetchImagePlane(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                           const std::string& sop_instance_uid, const std::atomic<bool>* cancel) {
  const PacsConfig& config = pacs.config();
  CheckUid(sop_instance_uid, "the image's SOP Instance UID");
  JsonDocument storage;
  const auto datasets = FetchDicomJson(
      config, "a retrieve of an image's metadata",
      SeriesUrl(config, study_uid, series_uid) + "/instances/" + EscapeUrlComponent(sop_instance_uid) + "/metadata",
      cancel, storage);
  // Numbers as DICOM JSON gives them (JSON numbers, or DS strings), each finite.
  const auto numbers = [](const DicomJsonDataset& dataset, std::uint32_t tag, std::size_t count) {
    std::vector<double> values;
    for (std::string_view text : dataset.Texts(tag, count + 1)) {
      while (!text.empty() && text.front() == ' ') text.remove_prefix(1);  // DS may be padded, and signed
      while (!text.empty() && text.back() == ' ') text.remove_suffix(1);
      if (!text.empty() && text.front() == '+') text.remove_prefix(1);
      double value = 0;
      const char* end = text.data() + text.size();
      const auto [at, error] = std::from_chars(text.data(), end, value);
      if (error != std::errc() || at != end || !std::isfinite(value)) return std::vector<double>{};
      values.push_back(value);
    }
    return values.size() == count ? values : std::vector<double>{};
  };
  if (datasets.size() == 1) {
    const DicomJsonDataset& image = datasets.front();
    const std::vector<double> position = numbers(image, kImagePositionPatient, 3);
    const std::vector<double> orientation = numbers(image, kImageOrientationPatient, 6);
    const std::vector<double> spacing = numbers(image, kPixelSpacing, 2);
    if (!position.empty() && !orientation.empty() && !spacing.empty()) {
      ImagePlane plane;
      std::copy(position.begin(), position.end(), plane.position.begin());
      std::copy(orientation.begin(), orientation.end(), plane.orientation.begin());
      std::copy(spacing.begin(), spacing.end(), plane.spacing.begin());
      plane.frame_of_reference_uid = image.Text(kFrameOfReferenceUid);
      return plane;
    }
  }
  throw PacsError(
      fmt::format("PACS '{}': image {} has no plane in its metadata (Image Position and Orientation "
                  "(Patient), Pixel Spacing), so 2D coordinates on it have no place in the patient",
                  config.name, sop_instance_uid));
}

InstanceLocation FindInstance(const DicomWebClient& pacs, const std::string& sop_instance_uid,
                              const std::atomic<bool>* cancel) {
  const PacsConfig& config = pacs.config();
  CheckUid(sop_instance_uid, "sop_instance_uid");
  JsonDocument storage;
  const auto found = FetchDicomJson(config, "a search for an instance",
                                    config.base_url + "/instances?limit=2&includefield=0020000D&includefield=0020000E"
                                                      "&SOPInstanceUID=" + EscapeUrlComponent(sop_instance_uid),
                                    cancel, storage);
  if (found.empty()) {
    throw PacsError(fmt::format("PACS '{}' holds no instance {}", config.name, sop_instance_uid), 404);
  }
  const InstanceLocation place{found.front().Text(tag::kStudyInstanceUid), found.front().Text(tag::kSeriesInstanceUid)};
  if (found.size() > 1 || !IsValidUid(place.study_uid) || !IsValidUid(place.series_uid)) {
    throw PacsError(fmt::format("PACS '{}' answered a search for instance {} with {} places or no valid study and "
                                "series UIDs",
                                config.name, sop_instance_uid, found.size()));
  }
  return place;
}

std::string RetrieveInstance(const DicomWebClient& pacs, const std::string& study_uid, const std::string& series_uid,
                             const std::string& sop_instance_uid, std::size_t max_bytes,
                             const std::atomic<bool>* cancel) {
  const PacsConfig& config = pacs.config();
  CheckUid(sop_instance_uid, "sop_instance_uid");
  HttpRequest request;
  request.what = "a retrieve of an instance";
  request.url = SeriesUrl(config, study_uid, series_uid) + "/instances/" + EscapeUrlComponent(sop_instance_uid);
  request.headers = {"Accept: multipart/related; type=\"application/dicom\"; transfer-syntax=*"};
  request.max_body_bytes = std::min<std::uint64_t>(config.max_response_bytes, max_bytes + kMultipartOverhead);
  request.cancel = cancel;
  HttpResponse response;
  try {
    response = HttpSession(config).Perform(request);
  } catch (const OverLimit&) {
    throw InputError(fmt::format("PACS '{}': the instance is larger than {} bytes, the most cinevol reads of one",
                                 config.name, max_bytes));
  }
  CheckStatus(config, response, request.what, {200});
  std::string_view part;
  try {
    const std::vector<MultipartPart> parts = SplitMultipart(response.body, MultipartBoundary(response.content_type), 1);
    if (parts.empty()) throw MultipartError("the body has no part");
    const std::string type = PartMediaType(parts.front().headers);
    if (!type.empty() && type != "application/dicom") throw MultipartError("its part is not application/dicom");
    if (!IsPart10(parts.front().body)) throw MultipartError("its part is not a DICOM Part 10 file");
    part = parts.front().body;
  } catch (const MultipartError& e) {
    throw PacsError(fmt::format("PACS '{}' answered {} with a malformed body: {}", config.name, request.what, e.what()),
                    response.status);
  }
  if (part.size() > max_bytes) {
    throw InputError(
        fmt::format("PACS '{}': the instance is {} bytes, larger than {} bytes, the most cinevol reads "
                    "of one",
                    config.name, part.size(), max_bytes));
  }
  return std::string(part);
}

}  // namespace cinevol::pacs
