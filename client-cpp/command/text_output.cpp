// Tables, fields and sparklines for people; proto3 JSON for scripts.
#include "text_output.h"

#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <fmt/format.h>

namespace cinevol::cli {
namespace {

// What an unset string field reads as.
std::string OrDash(const std::string& text) { return text.empty() ? "-" : Printable(text); }

}  // namespace

std::string Printable(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    const bool c1 = c == 0xc2 && i + 1 < text.size() && static_cast<unsigned char>(text[i + 1]) < 0xa0;  // U+0080..9F
    if (c < 0x20 || c == 0x7f || c1) {
      for (std::size_t k = 0; k < (c1 ? 2u : 1u); ++k) {
        out += fmt::format("\\x{:02x}", static_cast<unsigned char>(text[i + k]));
      }
      i += c1 ? 2 : 1;
    } else {
      out += char(c);
      ++i;
    }
  }
  return out;
}

void PrintTable(const std::vector<TextRow>& rows) {
  std::vector<TextRow> shown = rows;  // cells come from servers and PACS: no control character reaches the terminal
  std::vector<std::size_t> widths;
  for (TextRow& row : shown) {
    widths.resize(std::max(widths.size(), row.size()));
    for (std::size_t c = 0; c < row.size(); ++c) {
      row[c] = Printable(row[c]);
      widths[c] = std::max(widths[c], row[c].size());
    }
  }
  for (const TextRow& row : shown) {
    std::string line;
    for (std::size_t c = 0; c < row.size(); ++c) {
      line += c + 1 < row.size() ? fmt::format("{:<{}}  ", row[c], widths[c]) : row[c];
    }
    std::puts(line.c_str());
  }
}

void PrintJson(const google::protobuf::Message& message) {
  google::protobuf::util::JsonPrintOptions options;
  options.always_print_primitive_fields = true;  // a script can rely on every field being there
  std::string json;
  google::protobuf::util::MessageToJsonString(message, &json, options);
  std::puts(json.c_str());
}

std::string Bytes(std::uint64_t bytes) {
  static const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double value = double(bytes);
  int unit = 0;
  while (value >= 1024 && unit < 4) value /= 1024, ++unit;
  return unit == 0 ? fmt::format("{} B", bytes) : fmt::format("{:.1f} {}", value, kUnits[unit]);
}

std::string Triple(double x, double y, double z, const std::string& unit) {
  return fmt::format("{:g}x{:g}x{:g}{}", x, y, z, unit.empty() ? "" : " " + unit);
}

std::string ValueRange(const v1::VolumeInfo& v) {
  return fmt::format("{:g} .. {:g}{}", v.min_value(), v.max_value(),
                     v.value_unit().empty() ? "" : " " + v.value_unit());
}

std::string KindName(v1::VolumeKind kind) {
  return kind == v1::VOLUME_KIND_UNSPECIFIED ? "-" : v1::VolumeKind_Name(kind);
}

std::string Sparkline(const v1::ValueHistogram& histogram, int columns) {
  static const char* kBlocks[] = {" ", "▁", "▂", "▃", "▄", "▅", "▆", "▇", "█"};
  const int bins = histogram.counts_size();
  if (bins == 0) return "";
  columns = std::min(columns, bins);
  std::vector<double> sums(columns, 0.0);
  for (int b = 0; b < bins; ++b) sums[std::size_t(b) * columns / bins] += double(histogram.counts(b));
  const double top = std::log1p(*std::max_element(sums.begin(), sums.end()));
  std::string line;
  for (double sum : sums) {
    // Any voxel at all shows as at least the lowest block.
    const int level = sum > 0 ? std::clamp(int(std::ceil(8 * std::log1p(sum) / top)), 1, 8) : 0;
    line += kBlocks[level];
  }
  return line;
}

void PrintVolumeTable(const std::vector<v1::VolumeInfo>& volumes) {
  std::vector<TextRow> rows{{"ID", "KIND", "DEFAULT PRESET", "DIMS", "SPACING", "VALUES", "MEMORY", "SESSIONS"}};
  for (const v1::VolumeInfo& v : volumes) {
    rows.push_back({v.id(), KindName(v.kind()), OrDash(v.default_preset()),
                    Triple(v.dims().x(), v.dims().y(), v.dims().z()),
                    Triple(v.spacing_mm().x(), v.spacing_mm().y(), v.spacing_mm().z(), "mm"), ValueRange(v),
                    Bytes(v.memory_bytes()), std::to_string(v.sessions())});
  }
  PrintTable(rows);
}

void PrintVolume(const v1::VolumeInfo& v) {
  const auto& d = v.dims();
  const auto& s = v.spacing_mm();
  const std::string reason = v.kind_reason().empty() ? "" : " (" + v.kind_reason() + ")";
  fmt::print("id:              {}\n", v.id());
  fmt::print("source:          {}\n", OrDash(v.source()));
  fmt::print("modality:        {}\n", OrDash(v.modality()));
  fmt::print("value unit:      {}\n", OrDash(v.value_unit()));
  fmt::print("kind:            {}{}\n", KindName(v.kind()), reason);
  fmt::print("default preset:  {}\n", OrDash(v.default_preset()));
  fmt::print("dimensions:      {} voxels\n", Triple(d.x(), d.y(), d.z()));
  fmt::print("spacing:         {}\n", Triple(s.x(), s.y(), s.z(), "mm"));
  fmt::print("extent:          {}\n", Triple(d.x() * s.x(), d.y() * s.y(), d.z() * s.z(), "mm"));
  const auto& o = v.origin_mm();
  fmt::print("origin:          {:g}, {:g}, {:g} mm (LPS, voxel 0's centre: where clipping coordinates lie)\n", o.x(),
             o.y(), o.z());
  fmt::print("value range:     {}\n", ValueRange(v));
  fmt::print("memory:          {}\n", Bytes(v.memory_bytes()));
  fmt::print("sessions:        {}\n", v.sessions());
  for (const std::string& note : v.notes()) fmt::print("note:            {}\n", note);
  if (v.has_table()) {
    fmt::print("table:           {}{}\n", v.table().voxels() > 0 ? "removable (labels.removeTable); " : "",
               OrDash(v.table().note()));
  }
  if (v.has_labels()) PrintLabels(v.labels());
  const v1::ValueHistogram& h = v.histogram();
  if (h.counts_size() == 0) {
    fmt::print("histogram:       -\n");
    return;
  }
  const std::string line = Sparkline(h);
  const int columns = std::min(64, h.counts_size());
  const std::string low = fmt::format("{:g}", h.min_value());
  fmt::print("histogram:       {} bins, log scale\n", h.counts_size());
  fmt::print("                 |{}|\n", line);
  fmt::print("                 {}{:>{}}\n", low, fmt::format("{:g}", h.max_value()),
             std::max<int>(1, columns + 2 - int(low.size())));
}

void PrintLabels(const v1::LabelSet& labels) {
  fmt::print("labels:          {} values from {}\n", labels.names_size(), labels.source());
  if (!labels.note().empty()) fmt::print("                 {}\n", labels.note());
  // A DICOM SEG's recommended colours, as sRGB hex.
  const bool colours =
      std::any_of(labels.names().begin(), labels.names().end(), [](const v1::LabelName& n) { return n.has_color(); });
  std::vector<TextRow> rows{{"  VALUE", "NAME", "VOXELS"}};
  if (colours) rows[0].push_back("COLOUR");
  const auto hex = [](float c) { return int(std::lround(std::clamp(c, 0.0f, 1.0f) * 255)); };
  for (const v1::LabelName& n : labels.names()) {
    rows.push_back({"  " + std::to_string(n.value()), OrDash(n.name()), std::to_string(n.voxels())});
    if (colours) {
      rows.back().push_back(
          n.has_color() ? fmt::format("#{:02x}{:02x}{:02x}", hex(n.color().r()), hex(n.color().g()), hex(n.color().b()))
                        : "-");
    }
  }
  PrintTable(rows);
}

}  // namespace cinevol::cli
