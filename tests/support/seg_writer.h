// DICOM SEGs for the tests, written with DCMTK's dcmseg (the reader under
// test reads with dcmdata alone): a label map on any grid of planes becomes a
// binary or fractional SEG of one frame per plane and segment present in it.
// Hostile variants are made from a valid one with dcmdata (EditSeg).
#pragma once

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmfg/fgfracon.h>
#include <dcmtk/dcmfg/fgpixmsr.h>
#include <dcmtk/dcmfg/fgplanor.h>
#include <dcmtk/dcmfg/fgplanpo.h>
#include <dcmtk/dcmiod/cielabutil.h>
#include <dcmtk/dcmseg/segdoc.h>
#include <dcmtk/dcmseg/segment.h>
#include <fmt/format.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/volume.h"

namespace cinevol::testing {

using Vec3d = std::array<double, 3>;

// Where a SEG's pixel (column c, row r) of plane k lies: origin + c
// column_spacing along_row + r row_spacing down_column + k plane_step.
struct SegGrid {
  int columns = 0, rows = 0, planes = 0;
  Vec3d origin{}, along_row{}, down_column{}, plane_step{};
  double column_spacing = 1, row_spacing = 1;
  std::function<int(int c, int r, int k)> label;  // 0: none
};

struct SegOptions {
  bool fractional = false;
  int segments = 0;                  // numbered 1..segments, frames only where present
  std::map<int, std::string> names;  // Segment Labels; "segment N" where absent
  std::string frame_of_reference_uid = "2.25.3420000";
  std::string study_uid = "2.25.3420001", series_uid = "2.25.3420001.1", sop_instance_uid = "2.25.3420001.1.1";
  std::string patient_id = "CINEVOL-SEG", patient_name = "Cinevol^Seg";
};

// The recommended display colour the test writes for segment `s` (sRGB in [0, 1]).
inline Vec3d SegColor(int s) {
  return {double((s * 37 + 40) % 256) / 255, double((s * 91 + 20) % 256) / 255, double((s * 151 + 90) % 256) / 255};
}

// A DS value of at most 16 characters.
inline std::string Ds(double v) {
  if (std::abs(v) < 1e-9) v = 0;
  for (int digits = 10; digits > 3; --digits) {
    const std::string s = fmt::format("{:.{}g}", v, digits);
    if (s.size() <= 16) return s;
  }
  return fmt::format("{:.3g}", v);
}

inline void Check(const OFCondition& c, const std::string& what) {
  if (c.bad()) throw std::runtime_error("writing the test's SEG: " + what + ": " + c.text());
}

// Loads a SEG (or any DICOM file) with dcmdata, lets `edit` change its data
// set, and writes it to `to`: hostile variants of a valid SEG.
inline void EditSeg(const std::filesystem::path& from, const std::filesystem::path& to,
                    const std::function<void(DcmDataset&)>& edit, E_TransferSyntax syntax = EXS_LittleEndianExplicit) {
  DcmFileFormat file;
  Check(file.loadFile(from.c_str()), "load");
  Check(file.loadAllDataIntoMemory(), "load");  // `to` may be `from`
  edit(*file.getDataset());
  Check(file.saveFile(to.c_str(), syntax), "save");
}

// A fractional SEG of 0 and 255 made binary, its frames packed as PS3.5 8.1.1
// says: one bit a pixel, the first in the lowest bit, frames back to back.
inline void PackBinary(DcmDataset& data) {
  const Uint8* bytes = nullptr;
  unsigned long count = 0;
  Check(data.findAndGetUint8Array(DCM_PixelData, bytes, &count), "pixel data");
  std::vector<Uint8> packed((count + 7) / 8 + ((count + 7) / 8) % 2, 0);
  for (unsigned long i = 0; i < count; ++i) {
    if (bytes[i] != 0) packed[i >> 3] = Uint8(packed[i >> 3] | (1u << (i & 7)));
  }
  Check(data.putAndInsertUint8Array(DCM_PixelData, packed.data(), packed.size()), "pixel data");
  Check(data.putAndInsertUint16(DCM_BitsAllocated, 1), "bits");
  Check(data.putAndInsertUint16(DCM_BitsStored, 1), "bits");
  Check(data.putAndInsertUint16(DCM_HighBit, 0), "bits");
  Check(data.putAndInsertString(DCM_SegmentationType, "BINARY"), "type");
  delete data.remove(DCM_SegmentationFractionalType);
  delete data.remove(DCM_MaximumFractionalValue);
}

// Fractional frames hold 128 of 255 where the segment is (at the threshold's
// upper side) and 127 elsewhere (just below it). Binary frames of a pixel
// count that is no multiple of 8 are written fractional and packed by
// PackBinary: DCMTK 3.6.7's dcmseg packs them wrongly (DCMTK issue #1132,
// fixed in December 2024); others are DCMTK's own.
inline void WriteSeg(const std::filesystem::path& file, const SegGrid& grid, const SegOptions& options) {
  IODGeneralEquipmentModule::EquipmentInfo equipment("cinevol tests", "seg_writer.h", "1", "1");
  ContentIdentificationMacro content("1", "SEGMENTATION", "a test's segmentation", "Cinevol^Tests");
  DcmSegmentation* raw = nullptr;
  const bool repack = !options.fractional && (std::size_t(grid.rows) * std::size_t(grid.columns)) % 8 != 0;
  if (options.fractional || repack) {
    Check(DcmSegmentation::createFractionalSegmentation(raw, Uint16(grid.rows), Uint16(grid.columns),
                                                        DcmSegTypes::SFT_PROBABILITY, 255, equipment, content),
          "create");
  } else {
    Check(DcmSegmentation::createBinarySegmentation(raw, Uint16(grid.rows), Uint16(grid.columns), equipment, content),
          "create");
  }
  std::unique_ptr<DcmSegmentation> seg(raw);
  Check(seg->getPatient().setPatientName(options.patient_name.c_str()), "patient");
  Check(seg->getPatient().setPatientID(options.patient_id.c_str()), "patient");
  Check(seg->getStudy().setStudyInstanceUID(options.study_uid.c_str()), "study");
  Check(seg->getSeries().setSeriesInstanceUID(options.series_uid.c_str()), "series");
  Check(seg->getSeries().setSeriesNumber("9901"), "series");
  Check(seg->getSOPCommon().setSOPInstanceUID(options.sop_instance_uid.c_str()), "instance");
  Check(seg->getFrameOfReference().setFrameOfReferenceUID(options.frame_of_reference_uid.c_str()),
        "frame of reference");

  for (int s = 1; s <= options.segments; ++s) {
    DcmSegment* segment = nullptr;
    const auto name = options.names.find(s);
    const std::string label = name != options.names.end() ? name->second.substr(0, 64) : fmt::format("segment {}", s);
    Check(
        DcmSegment::create(segment, label.c_str(), CodeSequenceMacro("85756007", "SCT", "Tissue"),
                           CodeSequenceMacro("85756007", "SCT", "Tissue"), DcmSegTypes::SAT_AUTOMATIC, "cinevol tests"),
        "segment");
    const Vec3d rgb = SegColor(s);
    double lab[3];
    IODCIELabUtil::rgb2DicomLab(lab[0], lab[1], lab[2], rgb[0], rgb[1], rgb[2]);
    Check(segment->setRecommendedDisplayCIELabValue(Uint16(std::lround(lab[0])), Uint16(std::lround(lab[1])),
                                                    Uint16(std::lround(lab[2]))),
          "colour");
    Uint16 number = 0;
    Check(seg->addSegment(segment, number), "add segment");
    if (number != s) throw std::runtime_error("segments numbered out of order");
  }

  FGPixelMeasures measures;
  const double step = std::sqrt(grid.plane_step[0] * grid.plane_step[0] + grid.plane_step[1] * grid.plane_step[1] +
                                grid.plane_step[2] * grid.plane_step[2]);
  Check(measures.setPixelSpacing((Ds(grid.row_spacing) + "\\" + Ds(grid.column_spacing)).c_str()), "spacing");
  Check(measures.setSliceThickness(Ds(step).c_str()), "thickness");
  Check(measures.setSpacingBetweenSlices(Ds(step).c_str()), "spacing between slices");
  Check(seg->addForAllFrames(measures), "measures");
  std::unique_ptr<FGPlaneOrientationPatient> orientation(FGPlaneOrientationPatient::createMinimal(
      Ds(grid.along_row[0]).c_str(), Ds(grid.along_row[1]).c_str(), Ds(grid.along_row[2]).c_str(),
      Ds(grid.down_column[0]).c_str(), Ds(grid.down_column[1]).c_str(), Ds(grid.down_column[2]).c_str()));
  Check(seg->addForAllFrames(*orientation), "orientation");

  const std::size_t pixels = std::size_t(grid.rows) * std::size_t(grid.columns);
  std::vector<Uint8> frame(pixels);
  std::vector<int> plane_labels(pixels);
  for (int k = 0; k < grid.planes; ++k) {
    std::vector<bool> present(std::size_t(options.segments) + 1, false);
    for (int r = 0; r < grid.rows; ++r) {
      for (int c = 0; c < grid.columns; ++c) {
        const int label = grid.label(c, r, k);
        plane_labels[std::size_t(r) * grid.columns + c] = label;
        if (label > 0 && label <= options.segments) present[std::size_t(label)] = true;
      }
    }
    Vec3d position;
    for (int a = 0; a < 3; ++a) position[a] = grid.origin[a] + k * grid.plane_step[a];
    for (int s = 1; s <= options.segments; ++s) {
      if (!present[std::size_t(s)]) continue;
      for (std::size_t p = 0; p < pixels; ++p) {
        const bool in = plane_labels[p] == s;
        frame[p] = repack ? (in ? 255 : 0) : options.fractional ? (in ? 128 : 127) : (in ? 1 : 0);
      }
      std::unique_ptr<FGPlanePosPatient> place(
          FGPlanePosPatient::createMinimal(Ds(position[0]).c_str(), Ds(position[1]).c_str(), Ds(position[2]).c_str()));
      FGFrameContent content_fg;
      Check(content_fg.setDimensionIndexValues(Uint32(s), 0), "dimension index");
      Check(content_fg.setDimensionIndexValues(Uint32(k + 1), 1), "dimension index");
      OFVector<FGBase*> groups;
      groups.push_back(place.get());
      groups.push_back(&content_fg);
      Check(seg->addFrame(frame.data(), Uint16(s), groups), "frame");
    }
  }
  const std::string dimensions = options.series_uid + ".9";
  Check(seg->getDimensions().addDimensionIndex(DCM_ReferencedSegmentNumber, dimensions.c_str(),
                                               DCM_SegmentIdentificationSequence, "ReferencedSegmentNumber"),
        "dimension");
  Check(seg->getDimensions().addDimensionIndex(DCM_ImagePositionPatient, dimensions.c_str(), DCM_PlanePositionSequence,
                                               "ImagePositionPatient"),
        "dimension");
  seg->setCheckFGOnWrite(OFFalse);  // no Derivation Image: the tests' label maps come from NIfTI files
  Check(seg->saveFile(file.c_str(), EXS_LittleEndianExplicit), "save");
  if (repack) EditSeg(file, file, PackBinary);
}

// The SEG grid of `image`'s own axial planes (index z), its label map `labels` (x fastest).
inline SegGrid AxialGrid(const Volume& image, const std::vector<std::uint16_t>& labels) {
  SegGrid g;
  const Vec3i n = image.dims();
  const Vec3f s = image.spacing_mm();
  const auto& d = image.metadata().direction;
  g.columns = n.x;
  g.rows = n.y;
  g.planes = n.z;
  g.origin = image.metadata().origin_mm;
  for (int r = 0; r < 3; ++r) {
    g.along_row[r] = d[3 * r + 0];
    g.down_column[r] = d[3 * r + 1];
    g.plane_step[r] = d[3 * r + 2] * s.z;
  }
  g.column_spacing = s.x;
  g.row_spacing = s.y;
  g.label = [&labels, n](int c, int r, int k) { return int(labels[(std::size_t(k) * n.y + r) * n.x + c]); };
  return g;
}

}  // namespace cinevol::testing
