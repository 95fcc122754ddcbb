// Movies sent back (issue 58): an H.264 stream as a DICOM Multi-frame True Color Secondary Capture in the MPEG-4
// AVC/H.264 High Profile / Level 4.1 transfer syntax (PS3.5 8.2.8), filed in its source's study as a render is.
#pragma once

#include <cstddef>
#include <string>

#include "pacs/secondary_capture.h"

namespace cinevol::pacs {

inline constexpr const char* kMultiFrameTrueColorSopClass = "1.2.840.10008.5.1.4.1.1.7.4";
inline constexpr const char* kMpeg4HighProfileLevel41 = "1.2.840.10008.1.2.4.102";
// Its series number: past the renders (9900), reports (9901) and presentation states (9902).
inline constexpr int kMovieSeriesNumber = 9903;
// The largest stream cinevol stores: about a minute of 1080p at visually lossless quality (5 to 10 Mbit/s).
// It is held in memory while it is read from the encoder's file and wrapped (three copies at most), on a pool of four.
inline constexpr std::size_t kMaxMovieBytes = std::size_t{64} << 20;

struct MovieStream {
  int width = 0;        // even, [16; 1920]
  int height = 0;       // even, [16; 1080]
  int fps = 25;         // [1; 30]: level 4.1
  int frames = 0;       // [1; 36000]
  std::string h264;     // the Annex B byte stream, as H264Writer writes it (VideoContainer::kAnnexB)
  std::string description;  // the series description's tail: "cinevol movie: <description>"
};

// A DICOM Part 10 Multi-frame True Color Secondary Capture: patient and study copied from `study` (as a render's),
// a new series (9903) and instance, Conversion Type WSD, YBR_PARTIAL_420, Cine (frame time 1000/fps ms) and
// Multi-frame modules, lossy compression ISO_14496_10, and the stream in one fragment of encapsulated Pixel Data.
// Throws InputError naming the field for a bad input: sizes and rates beyond level 4.1, a stream that is not an
// Annex B H.264 stream starting with a sequence parameter set, or longer than kMaxMovieBytes.
std::string MakeMovieCapture(const SourceStudy& study, const MovieStream& movie, const std::string& version,
                             SecondaryCaptureUids* uids_out = nullptr);

}  // namespace cinevol::pacs
