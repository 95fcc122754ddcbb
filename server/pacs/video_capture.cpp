// The movie's DICOM object, written with DCMTK's dcmdata: its encapsulated Pixel Data holds the H.264 stream as it is.
#include "pacs/video_capture.h"

#include <dcmtk/config/osconfig.h>  // first, as DCMTK asks
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcpixel.h>
#include <dcmtk/dcmdata/dcpixseq.h>
#include <dcmtk/dcmdata/dcpxitem.h>
#include <fmt/format.h>

#include <memory>

#include "core/error.h"
#include "pacs/dcmtk_writing.h"
#include "pacs/dicom_json.h"

namespace cinevol::pacs {
namespace {

constexpr std::string_view kDocument = "the movie";

void Put(DcmItem& item, const DcmTagKey& tag, const std::string& value, const char* what) {
  Require(item.putAndInsertString(tag, value.c_str()), kDocument, what);
}

// The stream opens with a start code and, after any access unit delimiter, a sequence parameter set (NAL type 7).
bool LooksLikeAnnexB(const std::string& h264) {
  std::size_t at = 0;
  for (int units = 0; units < 4; ++units) {
    const std::size_t start = h264.find(std::string_view("\0\0\1", 3), at);
    if (start == std::string::npos || start + 3 >= h264.size()) return false;
    if (units == 0 && start > 1) return false;  // the first unit starts the stream (00 00 01 or 00 00 00 01)
    const int type = static_cast<unsigned char>(h264[start + 3]) & 0x1f;
    if (type == 7) return true;
    if (type != 9 && type != 6) return false;  // an access unit delimiter or SEI may come first
    at = start + 3;
  }
  return false;
}

void CheckMovie(const MovieStream& m) {
  const auto side = [](int n, int most) { return n >= 16 && n <= most && n % 2 == 0; };
  if (!side(m.width, 1920) || !side(m.height, 1080)) {
    Refuse("movie size", fmt::format("{}x{}: even sides, at most 1920x1080 (H.264 level 4.1)", m.width, m.height));
  }
  if (m.fps < 1 || m.fps > 30) Refuse("movie rate", fmt::format("{} frames/s: 1 to 30 (H.264 level 4.1)", m.fps));
  if (m.frames < 1 || m.frames > 36000) Refuse("movie frames", fmt::format("{}: 1 to 36000", m.frames));
  if (m.h264.size() > kMaxMovieBytes) Refuse("movie stream", fmt::format("is longer than {} bytes", kMaxMovieBytes));
  if (!LooksLikeAnnexB(m.h264)) Refuse("movie stream", "is not an H.264 Annex B stream opening with its parameters");
  if (m.description.size() > 48) Refuse("movie description", "is longer than 48 characters");
}

// The stream in one fragment after an empty offset table (PS3.5 8.2.8, A.4).
void PutPixelData(DcmDataset& d, const std::string& h264) {
  auto sequence = std::make_unique<DcmPixelSequence>(DCM_PixelSequenceTag);
  Require(sequence->insert(new DcmPixelItem(DCM_PixelItemTag)), kDocument, "the offset table");
  auto fragment = std::make_unique<DcmPixelItem>(DCM_PixelItemTag);
  std::string even = h264;
  if (even.size() % 2 == 1) even.push_back('\0');  // items have even lengths
  Require(fragment->putUint8Array(reinterpret_cast<const Uint8*>(even.data()), Uint32(even.size())), kDocument,
          "the stream");
  Require(sequence->insert(fragment.release()), kDocument, "the stream");
  auto pixels = std::make_unique<DcmPixelData>(DCM_PixelData);
  pixels->putOriginalRepresentation(EXS_MPEG4HighProfileLevel4_1, nullptr, sequence.release());
  Require(d.insert(pixels.release(), true), kDocument, "Pixel Data");
}

}  // namespace

std::string MakeMovieCapture(const SourceStudy& study, const MovieStream& movie, const std::string& version,
                             SecondaryCaptureUids* uids_out) {
  QuietDcmtk();
  CheckMovie(movie);
  const std::string study_uid = WithoutTrailingSpaces(study.study_uid);
  if (!IsValidUid(study_uid)) Refuse("source.study_uid", "is not a DICOM UID (1 to 64 digits and dots)");
  if (version.empty() || version.size() > 64 || !IsAscii(version)) Refuse("version", "is not 1 to 64 ASCII characters");
  if (!IsAscii(movie.description)) Refuse("movie description", "is not ASCII");

  DcmFileFormat file;
  DcmDataset& d = *file.getDataset();
  const bool ascii = IsAscii(study.patient_name) && IsAscii(study.patient_id) && IsAscii(study.study_id) &&
                     IsAscii(study.accession_number) && IsAscii(study.referring_physician) &&
                     IsAscii(study.study_description);
  if (!ascii) Put(d, DCM_SpecificCharacterSet, "ISO_IR 192", "Specific Character Set");
  const SecondaryCaptureUids uids{study_uid, NewUid(), NewUid()};
  const DicomNow now = CurrentDateTime();
  Put(d, DCM_SOPClassUID, kMultiFrameTrueColorSopClass, "SOP Class UID");
  Put(d, DCM_SOPInstanceUID, uids.sop_instance_uid, "SOP Instance UID");
  Put(d, DCM_InstanceCreationDate, now.date, "Instance Creation Date");
  Put(d, DCM_InstanceCreationTime, now.time, "Instance Creation Time");
  Put(d, DCM_StudyInstanceUID, study_uid, "Study Instance UID");
  PutStudyAttributes(d, study);
  // General Series, SC Equipment, General Image.
  Put(d, DCM_Modality, "OT", "Modality");
  Put(d, DCM_SeriesInstanceUID, uids.series_uid, "Series Instance UID");
  Put(d, DCM_SeriesNumber, std::to_string(kMovieSeriesNumber), "Series Number");
  Put(d, DCM_SeriesDescription,
      movie.description.empty() ? std::string("cinevol movie") : "cinevol movie: " + movie.description,
      "Series Description");
  Put(d, DCM_Laterality, "", "Laterality");  // 2C: unknown, as for a render (docs/pacs.md)
  Put(d, DCM_ConversionType, "WSD", "Conversion Type");  // a workstation's render
  Put(d, DCM_Manufacturer, "cinevol", "Manufacturer");
  Put(d, DCM_SoftwareVersions, version, "Software Versions");
  Put(d, DCM_InstanceNumber, "1", "Instance Number");
  Put(d, DCM_PatientOrientation, "", "Patient Orientation");
  Put(d, DCM_ContentDate, now.date, "Content Date");
  Put(d, DCM_ContentTime, now.time, "Content Time");
  Put(d, DCM_ImageType, "DERIVED\\SECONDARY", "Image Type");
  Put(d, DCM_BurnedInAnnotation, "NO", "Burned In Annotation");
  Put(d, DCM_DerivationDescription, "Volume rendered by cinevol (path traced), encoded as H.264", "Derivation");
  Put(d, DCM_LossyImageCompression, "01", "Lossy Image Compression");
  Put(d, DCM_LossyImageCompressionMethod, "ISO_14496_10", "Lossy Image Compression Method");
  // Image Pixel: what the stream decodes to (PS3.5 8.2.8).
  Require(d.putAndInsertUint16(DCM_SamplesPerPixel, 3), kDocument, "Samples per Pixel");
  Put(d, DCM_PhotometricInterpretation, "YBR_PARTIAL_420", "Photometric Interpretation");
  Require(d.putAndInsertUint16(DCM_PlanarConfiguration, 0), kDocument, "Planar Configuration");
  Require(d.putAndInsertUint16(DCM_Rows, Uint16(movie.height)), kDocument, "Rows");
  Require(d.putAndInsertUint16(DCM_Columns, Uint16(movie.width)), kDocument, "Columns");
  Require(d.putAndInsertUint16(DCM_BitsAllocated, 8), kDocument, "Bits Allocated");
  Require(d.putAndInsertUint16(DCM_BitsStored, 8), kDocument, "Bits Stored");
  Require(d.putAndInsertUint16(DCM_HighBit, 7), kDocument, "High Bit");
  Require(d.putAndInsertUint16(DCM_PixelRepresentation, 0), kDocument, "Pixel Representation");
  // Multi-frame and Cine: frames at a constant rate.
  Put(d, DCM_NumberOfFrames, std::to_string(movie.frames), "Number of Frames");
  Require(d.putAndInsertTagKey(DCM_FrameIncrementPointer, DCM_FrameTime), kDocument, "Frame Increment Pointer");
  Put(d, DCM_FrameTime, fmt::format("{:.4g}", 1000.0 / movie.fps), "Frame Time");
  Put(d, DCM_CineRate, std::to_string(movie.fps), "Cine Rate");
  Put(d, DCM_RecommendedDisplayFrameRate, std::to_string(movie.fps), "Recommended Display Frame Rate");
  PutPixelData(d, movie.h264);
  const std::string bytes = ToPart10(file, kDocument, EXS_MPEG4HighProfileLevel4_1);
  if (uids_out != nullptr) *uids_out = uids;
  return bytes;
}

}  // namespace cinevol::pacs
