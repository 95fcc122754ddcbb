// DICOM structured reports written byte by byte (explicit VR little endian), for tests: what no library would write
// (hostile values, wrong VRs, floods) and reports shaped as other software writes them (OHIF's TID 1500).
#pragma once

#include <cstdint>
#include <cstring>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "pacs/measurement_report.h"

namespace cinevol::testing {

inline constexpr const char* kHandmadeFrame = "2.25.3400357.9";

inline std::string Le16(std::uint16_t v) { return {char(v & 0xff), char(v >> 8)}; }
inline std::string Le32(std::uint32_t v) { return Le16(std::uint16_t(v & 0xffff)) + Le16(std::uint16_t(v >> 16)); }
inline std::string TagBytes(std::uint32_t tag) {
  return Le16(std::uint16_t(tag >> 16)) + Le16(std::uint16_t(tag & 0xffff));
}

// One element in explicit VR little endian, its value padded to an even length.
inline std::string Element(std::uint32_t tag, const std::string& vr, std::string value) {
  if (value.size() % 2) value += vr == "UI" ? '\0' : ' ';
  const bool long_length = vr == "OB" || vr == "SQ" || vr == "UN" || vr == "UT" || vr == "UC" || vr == "UR";
  return TagBytes(tag) + vr +
         (long_length ? Le16(0) + Le32(std::uint32_t(value.size())) : Le16(std::uint16_t(value.size()))) + value;
}

inline std::string Floats(const std::vector<float>& values) {
  std::string bytes(values.size() * 4, '\0');
  std::memcpy(bytes.data(), values.data(), bytes.size());
  return bytes;
}

// A sequence and its items, each of undefined length.
inline std::string Sequence(std::uint32_t tag, const std::vector<std::string>& items) {
  std::string bytes = TagBytes(tag) + "SQ" + Le16(0) + Le32(0xffffffff);
  for (const std::string& item : items)
    bytes += TagBytes(0xfffee000) + Le32(0xffffffff) + item + TagBytes(0xfffee00d) + Le32(0);
  return bytes + TagBytes(0xfffee0dd) + Le32(0);
}

// Elements by tag, written in tag order.
using Elements = std::map<std::uint32_t, std::string>;
inline std::string Join(const Elements& elements) {
  std::string bytes;
  for (const auto& [tag, element] : elements) bytes += element;
  return bytes;
}

// A Part 10 file: preamble, "DICM", the meta information (the SOP class and instance where given), `dataset`.
inline std::string Part10(const std::string& dataset, const std::string& syntax = "1.2.840.10008.1.2.1",
                          const std::string& sop_class = {}, const std::string& instance = {}) {
  std::string meta;
  if (!sop_class.empty()) meta += Element(0x00020002, "UI", sop_class) + Element(0x00020003, "UI", instance);
  return std::string(128, '\0') + "DICM" + meta + Element(0x00020010, "UI", syntax) + dataset;
}

struct CodeTriple {
  std::string value, scheme, meaning;
};

inline std::string CodeItem(const CodeTriple& c) {
  return Element(0x00080100, "SH", c.value) + Element(0x00080102, "SH", c.scheme) +
         Element(0x00080104, "LO", c.meaning);
}

inline Elements ContentItem(const std::string& relation, const std::string& type, const CodeTriple& concept_name) {
  return {{0x0040A010, Element(0x0040A010, "CS", relation)},
          {0x0040A040, Element(0x0040A040, "CS", type)},
          {0x0040A043, Sequence(0x0040A043, {CodeItem(concept_name)})}};
}

inline Elements WithChildren(Elements item, const std::vector<Elements>& children) {
  std::vector<std::string> items;
  for (const Elements& child : children) items.push_back(Join(child));
  item[0x0040A730] = Sequence(0x0040A730, items);
  return item;
}

inline Elements Scoord3d(const std::vector<float>& xyz, const std::string& frame = kHandmadeFrame) {
  Elements item{{0x0040A010, Element(0x0040A010, "CS", "INFERRED FROM")},
                {0x0040A040, Element(0x0040A040, "CS", "SCOORD3D")},
                {0x00700022, Element(0x00700022, "FL", Floats(xyz))},
                {0x00700023, Element(0x00700023, "CS", "POLYLINE")},
                {0x30060024, Element(0x30060024, "UI", frame)}};
  return item;
}

inline Elements Num(const CodeTriple& concept_name, const std::string& units, const std::string& value,
                    const Elements& coordinates) {
  Elements num = ContentItem("CONTAINS", "NUM", concept_name);
  num[0x0040A300] = Sequence(
      0x0040A300, {Sequence(0x004008EA, {CodeItem({units, "UCUM", units})}) + Element(0x0040A30A, "DS", value)});
  return WithChildren(num, {coordinates});
}

inline Elements Tracking(const std::string& text) {
  Elements item = ContentItem("HAS OBS CONTEXT", "TEXT", {"112039", "DCM", "Tracking Identifier"});
  item[0x0040A160] = Element(0x0040A160, "UT", text);
  return item;
}

inline Elements FreeTextFinding(const std::string& label) {
  Elements item = ContentItem("CONTAINS", "CODE", {"121071", "DCM", "Finding"});
  item[0x0040A168] = Sequence(0x0040A168, {CodeItem({"CORNERSTONEFREETEXT", "CORNERSTONEJS", label})});
  return item;
}

inline Elements Group(std::vector<Elements> children) {
  return WithChildren(ContentItem("CONTAINS", "CONTAINER", {"125007", "DCM", "Measurement Group"}), children);
}

// What a handmade report says about itself: its UIDs and class, and the evidence it lists.
struct HandmadeReport {
  std::string study_uid = "2.25.3400359";
  std::string series_uid = "2.25.3400359.1";
  std::string instance_uid = "2.25.3400359.1.1";
  std::string sop_class = pacs::kComprehensive3dSrSopClass;
  std::string patient_id = "HANDMADE";
  std::string evidence_series = "2.25.3400359.7";
  std::vector<std::pair<std::string, std::string>> evidence_instances;  // SOP class, instance
};

// A TID 1500 report around `groups`, with `root_extra` elements beside the root's own.
inline std::string Report(const std::vector<Elements>& groups, const Elements& root_extra = {},
                          const HandmadeReport& about = {}) {
  std::vector<std::string> references;
  for (const auto& [sop_class, instance] : about.evidence_instances) {
    references.push_back(Element(0x00081150, "UI", sop_class) + Element(0x00081155, "UI", instance));
  }
  std::string series = references.empty() ? "" : Sequence(0x00081199, references);
  series += Element(0x0020000E, "UI", about.evidence_series);
  Elements root{{0x00080005, Element(0x00080005, "CS", "ISO_IR 192")},
                {0x00080016, Element(0x00080016, "UI", about.sop_class)},
                {0x00080018, Element(0x00080018, "UI", about.instance_uid)},
                {0x00080060, Element(0x00080060, "CS", "SR")},
                {0x00100020, Element(0x00100020, "LO", about.patient_id)},
                {0x0020000D, Element(0x0020000D, "UI", about.study_uid)},
                {0x0020000E, Element(0x0020000E, "UI", about.series_uid)},
                {0x0040A040, Element(0x0040A040, "CS", "CONTAINER")},
                {0x0040A043, Sequence(0x0040A043, {CodeItem({"126000", "DCM", "Imaging Measurement Report"})})},
                {0x0040A375,
                 Sequence(0x0040A375, {Sequence(0x00081115, {series}) + Element(0x0020000D, "UI", about.study_uid)})}};
  const Elements imaging =
      WithChildren(ContentItem("CONTAINS", "CONTAINER", {"126010", "DCM", "Imaging Measurements"}), groups);
  root = WithChildren(root, {ContentItem("CONTAINS", "CONTAINER", {"111028", "DCM", "Image Library"}), imaging});
  for (const auto& [tag, element] : root_extra) root[tag] = element;
  return Part10(Join(root), "1.2.840.10008.1.2.1", about.sop_class, about.instance_uid);
}

// 2D coordinates (column, row pairs) on an image, as OHIF writes a measurement made on a slice.
inline Elements Scoord(const std::vector<float>& xy, const std::string& image_uid,
                       const std::string& sop_class = "1.2.840.10008.5.1.4.1.1.2") {
  Elements image{{0x0040A010, Element(0x0040A010, "CS", "SELECTED FROM")},
                 {0x0040A040, Element(0x0040A040, "CS", "IMAGE")},
                 {0x00081199,
                  Sequence(0x00081199, {Element(0x00081150, "UI", sop_class) + Element(0x00081155, "UI", image_uid)})}};
  Elements item{{0x0040A010, Element(0x0040A010, "CS", "INFERRED FROM")},
                {0x0040A040, Element(0x0040A040, "CS", "SCOORD")},
                {0x00700022, Element(0x00700022, "FL", Floats(xy))},
                {0x00700023, Element(0x00700023, "CS", "POLYLINE")}};
  return WithChildren(item, {image});
}

inline const CodeTriple kLength{"410668003", "SCT", "Length"};
inline const CodeTriple kCobbAngle{"285285000", "SCT", "Cobb angle"};

}  // namespace cinevol::testing
