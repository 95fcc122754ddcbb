// Loading a series from a PACS by what a user knows of it: a study (its
// largest series unless one is named) or a patient (the latest study).
// `cinevol pacs load` and `cinevol view --pacs` both load this way.
#pragma once

#include <functional>
#include <string>

#include "client.h"

namespace cinevol::cli {

struct PacsLoad {
  std::string pacs;        // the PACS by the name the server gives it
  std::string study;       // Study Instance UID, or
  std::string patient_id;  // the patient, whose latest study (by date) is taken
  std::string series;      // Series Instance UID; empty: the study's with the most instances
  std::string orientation;
  bool resample_uneven = false;
  std::string labels_for;  // a volume id: the series is a DICOM SEG, loaded as that volume's labels
};

// Throws InputError unless exactly one of study and patient_id is given, or
// when the patient or study has nothing in the PACS.
v1::VolumeInfo LoadFromPacs(Client& client, const PacsLoad& load,
                            const std::function<void(const v1::LoadSeriesProgress&)>& progress);

}  // namespace cinevol::cli
