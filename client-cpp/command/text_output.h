// What `cinevol volumes` and `cinevol status` print: readable tables and
// fields for people, and proto3 JSON (one object) for scripts.
#pragma once

#include <google/protobuf/message.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "cinevol/v1/service.pb.h"

namespace cinevol::cli {

using TextRow = std::vector<std::string>;

// `text` for a terminal: control characters (C0, DEL, C1: ESC, CR, CSI...)
// written as \xNN, so a name from a PACS cannot move the cursor or rewrite
// what was printed.
std::string Printable(std::string_view text);

// Rows in columns padded to their widest cell; the first row is the header.
void PrintTable(const std::vector<TextRow>& rows);

// `message` as proto3 JSON on one line, default values included.
void PrintJson(const google::protobuf::Message& message);

// A size: "812 B", "5.3 MiB", "1.2 GiB" (binary steps).
std::string Bytes(std::uint64_t bytes);

// "16x16x16", "0.5x0.5x1 mm".
std::string Triple(double x, double y, double z, const std::string& unit = "");

// The voxel value range: "-1024 .. 3071 HU".
std::string ValueRange(const v1::VolumeInfo& volume);

// "CT_HU", ...; "-" when the server did not say.
std::string KindName(v1::VolumeKind kind);

// The histogram as one line of `columns` block characters (log scale, so a
// sparse bone peak still shows beside the air); "" when it is empty.
std::string Sparkline(const v1::ValueHistogram& histogram, int columns = 64);

// id, kind, default preset, dims, spacing, value range, memory, sessions.
void PrintVolumeTable(const std::vector<v1::VolumeInfo>& volumes);

// Every field of `volume`, one per line, the histogram drawn.
void PrintVolume(const v1::VolumeInfo& volume);

// A segmentation: where it came from, how it was fitted, and each label's
// value, name and voxels.
void PrintLabels(const v1::LabelSet& labels);

}  // namespace cinevol::cli
