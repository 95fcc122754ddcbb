// A PET's values in SUVbw (body-weight standardised uptake value) from its
// DICOM attributes, as QIBA's vendor-neutral pseudo-code computes it: the
// factor that turns the stored activity concentration (Bq/ml) into SUVbw, or
// a sentence saying why there is none. The attributes come from the reader
// cage's child (reader.proto's PetDose) and are checked here, in the parent.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "cinevol/reader/reader.pb.h"

namespace cinevol {

// What a factor needs to be believed: a patient's weight in (0, 500] kg, a
// dose in (0, 1e11] Bq (100 GBq; a PET dose is some 100 MBq), a half life in
// (0, 1e7] s (about 116 days), an injection at most 24 h before the scan.
inline constexpr double kMaxSuvWeightKg = 500;
inline constexpr double kMaxSuvDoseBq = 1e11;
inline constexpr double kMaxSuvHalfLifeS = 1e7;
inline constexpr double kMaxUptakeS = 24 * 3600;

struct SuvbwFactor {
  // SUVbw per stored unit: value x factor = SUVbw; 0 where refused.
  double factor = 0;
  // Why there is no factor: one sentence naming the attribute and its value;
  // empty where there is one.
  std::string refused;
};

// SUVbw = activity concentration [Bq/ml] x weight [g] / dose [Bq], the dose
// decayed from the injection to the scan's start: the Series Date and Time,
// or the series' earliest Acquisition Date and Time where the series time is
// later (a series made after the scan; QIBA's rule for such vendors). Units
// GML are SUVbw already (factor 1); Decay Correction ADMIN (images corrected
// to the injection) takes the dose undecayed; START or none given decays it.
// Refused: other Units, images not decay or not attenuation corrected (DECY
// or ATTN missing from Corrected Image where it is given, Decay Correction
// NONE), a weight, dose or half life missing or outside the bounds above,
// a date or time that is no DICOM DA, TM or DT, an injection after the scan or
// more than kMaxUptakeS before it. An injection given as a time only is on the
// scan's date, or on the day before where that puts it less than 12 h before
// a scan that started after midnight.
SuvbwFactor SuvbwFactorOf(const reader::PetDose& pet);

// DICOM's date and time values (PS3.5 6.2), trailing spaces allowed:
// DA "YYYYMMDD" (or the old "YYYY.MM.DD") as days since 1970-01-01;
std::optional<std::int64_t> ParseDicomDate(std::string_view da);
// TM "HH[MM[SS[.F{1,6}]]]" (or the old "HH:MM:SS.F") as seconds since midnight;
std::optional<double> ParseDicomTime(std::string_view tm);
// DT "YYYYMMDDHH[MM[SS[.F{1,6}]]]" with an optional "&ZZXX" offset from UTC
// (checked, then ignored: the clock the DT was written on, as the series
// times are), as seconds since 1970-01-01 00:00. A DT without an hour is no
// time of day and not read. nullopt wherever a value is not one of these.
std::optional<double> ParseDicomDateTime(std::string_view dt);

}  // namespace cinevol
