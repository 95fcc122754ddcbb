// Series a PACS will take, made from the shared data: the shared DICOM folders
// lack Study and Series Instance UIDs (and the CT its SOP UIDs and patient),
// so copies are stamped with deterministic ones by GDCM.
#pragma once

#include <gdcmAttribute.h>
#include <gdcmReader.h>
#include <gdcmWriter.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace cinevol::testing {

struct SeriesStamp {
  std::string study_uid;
  std::string series_uid;  // instance i (from 1) gets SOP Instance UID series_uid + "." + i
  std::string patient_id;
  std::string patient_name;
  std::string pixel_spacing = {};  // Pixel Spacing (0028,0030) written over the source's ("1e-10\\1e-10"); empty: kept
};

struct StampedInstance {
  std::string sop_instance_uid;
  std::string bytes;  // the Part 10 file as written
};

struct StampedSeries {
  SeriesStamp stamp;
  std::vector<StampedInstance> instances;
};

inline std::string ReadWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// The DICOM files of a shared folder, in name order (a README sits beside them).
inline std::vector<std::filesystem::path> DicomFilesIn(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().filename() != "README.txt") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// Sets one text attribute of `data` (a data set or the file meta header).
template <std::uint16_t kGroup, std::uint16_t kElement>
void SetAttribute(gdcm::DataSet& data, const std::string& value) {
  gdcm::Attribute<kGroup, kElement> attribute;
  attribute.SetValue(value);
  data.Replace(attribute.GetAsDataElement());
}

// Writes a stamped copy of `source` to `target`; returns its SOP Instance UID.
inline std::string StampCopy(const std::filesystem::path& source, const std::filesystem::path& target,
                             const SeriesStamp& stamp, const std::string& sop_instance_uid) {
  constexpr const char* kCtImageStorage = "1.2.840.10008.5.1.4.1.1.2";
  gdcm::Reader reader;
  reader.SetFileName(source.c_str());
  if (!reader.Read()) throw std::runtime_error("GDCM cannot read " + source.string());
  gdcm::DataSet& data = reader.GetFile().GetDataSet();
  gdcm::Attribute<0x0008, 0x0016> sop_class;
  sop_class.SetFromDataSet(data);
  std::string sop_class_uid = sop_class.GetValue().Trim();
  if (sop_class_uid.empty()) sop_class_uid = kCtImageStorage;  // the shared CT's is empty
  SetAttribute<0x0008, 0x0016>(data, sop_class_uid);
  SetAttribute<0x0008, 0x0018>(data, sop_instance_uid);
  SetAttribute<0x0020, 0x000d>(data, stamp.study_uid);
  SetAttribute<0x0020, 0x000e>(data, stamp.series_uid);
  SetAttribute<0x0010, 0x0020>(data, stamp.patient_id);
  SetAttribute<0x0010, 0x0010>(data, stamp.patient_name);
  if (!stamp.pixel_spacing.empty()) {  // DS, two values: written as text, padded to an even length
    std::string text = stamp.pixel_spacing + (stamp.pixel_spacing.size() % 2 ? " " : "");
    gdcm::DataElement spacing(gdcm::Tag(0x0028, 0x0030));
    spacing.SetVR(gdcm::VR::DS);
    spacing.SetByteValue(text.data(), std::uint32_t(text.size()));
    data.Replace(spacing);
  }
  // The file meta header names the instance too; a PACS may check they agree.
  gdcm::FileMetaInformation& meta = reader.GetFile().GetHeader();
  SetAttribute<0x0002, 0x0002>(meta, sop_class_uid);
  SetAttribute<0x0002, 0x0003>(meta, sop_instance_uid);
  gdcm::Writer writer;
  writer.SetFile(reader.GetFile());
  writer.SetFileName(target.c_str());
  if (!writer.Write()) throw std::runtime_error("GDCM cannot write " + target.string());
  return sop_instance_uid;
}

// Stamped copies of `sources` under `folder`, read back as bytes.
inline StampedSeries StampSeries(const std::vector<std::filesystem::path>& sources, const SeriesStamp& stamp,
                                 const std::filesystem::path& folder) {
  StampedSeries series{stamp, {}};
  std::filesystem::create_directories(folder);
  for (std::size_t i = 0; i < sources.size(); ++i) {
    const std::filesystem::path target = folder / (std::to_string(i + 1) + ".dcm");
    const std::string uid = StampCopy(sources[i], target, stamp, stamp.series_uid + "." + std::to_string(i + 1));
    series.instances.push_back({uid, ReadWholeFile(target)});
  }
  return series;
}

}  // namespace cinevol::testing
