// PET values in SUVbw (io/suv.h): QIBA's formula against hand-computed
// factors, its vendor rule for the scan's start, the refusals with their
// sentences, DICOM DA/TM/DT parsing; and a PET series written from the shared
// MR's slices, loaded through the reader cage, with its factor or refusal.
#include "io/suv.h"

#include <fmt/format.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
using testing::SharedData;
namespace fs = std::filesystem;

// An FDG scan an hour after the injection: 70 kg, 370 MBq of F-18 at 08:30,
// the series at 09:30, corrected for attenuation and decay to the series'
// start.
reader::PetDose Fdg() {
  reader::PetDose pet;
  pet.set_units("BQML");
  pet.set_decay_correction("START");
  pet.set_corrected_image("ATTN\\DECY");
  pet.set_patient_weight_kg(70);
  pet.set_total_dose_bq(370e6);
  pet.set_half_life_s(6586.2);
  pet.set_injection_time("083000");
  pet.set_series_date("20240305");
  pet.set_series_time("093000");
  pet.set_acquisition_date("20240305");
  pet.set_acquisition_time("093000");
  return pet;
}

// 70000 g / (370e6 Bq x 2^(-3600 s / 6586.2 s)), worked out by hand: the dose
// decays to 0.68457 of itself in the hour.
constexpr double kFdgFactor = 2.7633668e-4;

std::string RefusalOf(const reader::PetDose& pet) {
  const SuvbwFactor suv = SuvbwFactorOf(pet);
  EXPECT_EQ(suv.factor, 0) << "refused factors are 0";
  return suv.refused;
}

TEST(Suv, AnHourAfterTheInjectionTheDoseHasDecayedByQibasFormula) {
  const SuvbwFactor suv = SuvbwFactorOf(Fdg());
  EXPECT_EQ(suv.refused, "");
  EXPECT_NEAR(suv.factor, kFdgFactor, 1e-10);
  EXPECT_NEAR(suv.factor, 70000 / (370e6 * std::exp2(-3600 / 6586.2)), 1e-15);
}

TEST(Suv, DecayCorrectionAdminTakesTheDoseAsGiven) {
  reader::PetDose pet = Fdg();
  pet.set_decay_correction("ADMIN");
  pet.clear_half_life_s();  // not needed without decay
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, 70000 / 370e6, 1e-15);
}

TEST(Suv, NoDecayCorrectionGivenMeansStart) {
  reader::PetDose pet = Fdg();
  pet.clear_decay_correction();
  pet.clear_corrected_image();
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, kFdgFactor, 1e-10);
}

TEST(Suv, UnitsGmlAreSuvbwAlready) {
  reader::PetDose pet;
  pet.set_units("GML");
  const SuvbwFactor suv = SuvbwFactorOf(pet);
  EXPECT_EQ(suv.factor, 1);
  EXPECT_EQ(suv.refused, "");
}

// QIBA's vendor rule: a series time after the earliest acquisition is when
// the series was made, not the scan; the earliest acquisition is the start.
TEST(Suv, ASeriesTimeAfterTheAcquisitionTakesTheEarliestAcquisition) {
  reader::PetDose pet = Fdg();
  pet.set_series_time("113000");
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, kFdgFactor, 1e-10);
  pet = Fdg();
  pet.set_acquisition_time("093500");  // later than the series: the series' time holds
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, kFdgFactor, 1e-10);
  pet.clear_series_time();  // none: the acquisition's, 65 min
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, 70000 / (370e6 * std::exp2(-3900 / 6586.2)), 1e-15);
}

TEST(Suv, TheInjectionsDateTimeComesBeforeItsTime) {
  reader::PetDose pet = Fdg();
  pet.set_injection_time("120000");
  pet.set_injection_datetime("20240305083000.000000+0100");
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, kFdgFactor, 1e-10);
  pet.set_injection_datetime("20240304233000");  // the evening before: 10 h
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, 70000 / (370e6 * std::exp2(-36000 / 6586.2)), 1e-15);
}

TEST(Suv, AnInjectionBeforeMidnightIsOnTheDayBeforeAScanAfterIt) {
  reader::PetDose pet = Fdg();
  pet.set_injection_time("233000");
  pet.set_series_date("20240306");
  pet.set_series_time("003000");
  pet.clear_acquisition_time();
  EXPECT_NEAR(SuvbwFactorOf(pet).factor, kFdgFactor, 1e-10);
}

TEST(Suv, UnitsCorrectionsAndDecayCorrectionOtherThanQuantitativeAreRefused) {
  reader::PetDose pet = Fdg();
  pet.set_units("CNTS");
  EXPECT_EQ(RefusalOf(pet),
            "Units (0054,1001) is 'CNTS': cinevol computes SUVbw from BQML (Bq/ml), or takes GML as SUVbw");
  pet.clear_units();
  EXPECT_EQ(RefusalOf(pet), "Units (0054,1001) is missing: what the values measure is not known");
  pet = Fdg();
  pet.set_corrected_image("ATTN\\SCAT");
  EXPECT_EQ(RefusalOf(pet),
            "Corrected Image (0028,0051) is 'ATTN\\SCAT', without DECY: the images are not decay corrected");
  pet.set_corrected_image("DECY");
  EXPECT_EQ(RefusalOf(pet),
            "Corrected Image (0028,0051) is 'DECY', without ATTN: the images are not attenuation corrected");
  pet = Fdg();
  pet.set_decay_correction("NONE");
  EXPECT_EQ(RefusalOf(pet), "Decay Correction (0054,1102) is 'NONE': the images are not decay corrected");
  pet.set_decay_correction("LATER");
  EXPECT_EQ(RefusalOf(pet), "Decay Correction (0054,1102) is 'LATER': cinevol reads START or ADMIN");
}

TEST(Suv, MissingOrAbsurdWeightDoseAndHalfLifeAreRefused) {
  reader::PetDose pet = Fdg();
  pet.clear_patient_weight_kg();
  EXPECT_EQ(RefusalOf(pet), "Patient's Weight (0010,1030) is missing (or no number)");
  pet.set_patient_weight_kg(700);
  EXPECT_EQ(RefusalOf(pet), "Patient's Weight (0010,1030) is 700 kg, outside (0, 500] kg");
  pet.set_patient_weight_kg(-3);
  EXPECT_EQ(RefusalOf(pet), "Patient's Weight (0010,1030) is -3 kg, outside (0, 500] kg");
  pet.set_patient_weight_kg(std::nan(""));
  EXPECT_EQ(RefusalOf(pet).rfind("Patient's Weight (0010,1030) is nan kg", 0), 0u);
  pet = Fdg();
  pet.clear_total_dose_bq();
  EXPECT_EQ(RefusalOf(pet), "Radionuclide Total Dose (0018,1074) is missing (or no number)");
  pet.set_total_dose_bq(3.7e11);
  EXPECT_EQ(RefusalOf(pet), "Radionuclide Total Dose (0018,1074) is 3.7e+11 Bq, outside (0, 1e+11] Bq");
  pet = Fdg();
  pet.clear_half_life_s();
  EXPECT_EQ(RefusalOf(pet), "Radionuclide Half Life (0018,1075) is missing (or no number)");
  pet.set_half_life_s(-6586.2);
  EXPECT_EQ(RefusalOf(pet), "Radionuclide Half Life (0018,1075) is -6586.2 s, outside (0, 1e+07] s");
  pet.set_half_life_s(1e-3);  // in range, yet all of the dose is gone within the hour
  EXPECT_EQ(RefusalOf(pet),
            "Radionuclide Half Life (0018,1075) is 0.001 s: the dose is all decayed in the 3600 s from the injection "
            "to the scan");
}

TEST(Suv, TimesThatAreNoDicomTimesAreRefused) {
  reader::PetDose pet = Fdg();
  pet.set_series_time("9:30");
  EXPECT_EQ(RefusalOf(pet), "Series Time (0008,0031) '9:30' is no DICOM time");
  pet = Fdg();
  pet.set_series_date("2024-03-05");
  EXPECT_EQ(RefusalOf(pet), "Series Date (0008,0021) '2024-03-05' is no DICOM date");
  pet = Fdg();
  pet.set_acquisition_time("0961");
  EXPECT_EQ(RefusalOf(pet), "Acquisition Time (0008,0032) '0961' is no DICOM time");
  pet = Fdg();
  pet.set_injection_time("8h30\n");
  EXPECT_EQ(RefusalOf(pet), "Radiopharmaceutical Start Time (0018,1072) '8h30\\x0a' is no DICOM time");
  pet.set_injection_datetime("20240305");  // a date, no time of day
  EXPECT_EQ(RefusalOf(pet), "Radiopharmaceutical Start DateTime (0018,1078) '20240305' is no DICOM date and time");
  pet = Fdg();
  pet.clear_injection_time();
  EXPECT_EQ(RefusalOf(pet),
            "Radiopharmaceutical Start Time (0018,1072) and DateTime (0018,1078) are missing: the injection's time is "
            "not known");
  pet = Fdg();
  pet.clear_series_time();
  pet.clear_acquisition_time();
  EXPECT_EQ(
      RefusalOf(pet),
      "Series Time (0008,0031) is missing, and so is Acquisition Time (0008,0032): the scan's start is not known");
}

TEST(Suv, AnInjectionAfterTheScanOrADayBeforeItIsRefused) {
  reader::PetDose pet = Fdg();
  pet.set_injection_time("100000");  // 30 min after the scan, not 23.5 h before
  EXPECT_EQ(RefusalOf(pet),
            "the injection, Radiopharmaceutical Start Time (0018,1072) '100000', is 1800 s after the scan's start, "
            "Series Date and Time '20240305' '093000'");
  pet.set_injection_datetime("20240304083000");
  EXPECT_EQ(RefusalOf(pet),
            "the injection, Radiopharmaceutical Start DateTime (0018,1078) '20240304083000', is 90000 s before the "
            "scan's start, Series Date and Time '20240305' '093000': more than 24 h");
}

TEST(Suv, DicomTimesParseWithFractionsAndTheirLaterPartsLeftOut) {
  EXPECT_EQ(ParseDicomTime("093000").value_or(-1), 34200);
  EXPECT_EQ(ParseDicomTime("0930").value_or(-1), 34200);
  EXPECT_EQ(ParseDicomTime("09").value_or(-1), 32400);
  EXPECT_DOUBLE_EQ(ParseDicomTime("093000.5").value_or(-1), 34200.5);
  EXPECT_DOUBLE_EQ(ParseDicomTime("093000.123456 ").value_or(-1), 34200.123456);
  EXPECT_DOUBLE_EQ(ParseDicomTime("09:30:00.25").value_or(-1), 34200.25);  // the old ACR-NEMA form
  EXPECT_EQ(ParseDicomTime("235960").value_or(-1), 86400);                 // a leap second
  for (const char* bad : {"", "9", "093", "2400", "0960", "093061", "093000.", "093000.1234567", "0930.5", "09:", "ab",
                          "093000 x", "-93000"}) {
    EXPECT_FALSE(ParseDicomTime(bad).has_value()) << "'" << bad << "'";
  }
}

TEST(Suv, DicomDatesAndDateTimesParseToTheirDays) {
  EXPECT_EQ(ParseDicomDate("19700101").value_or(-1), 0);
  EXPECT_EQ(ParseDicomDate("20000301").value_or(-1), 11017);
  EXPECT_EQ(ParseDicomDate("20240305").value_or(-1), 19787);
  EXPECT_EQ(ParseDicomDate("2024.03.05").value_or(-1), 19787);
  EXPECT_EQ(ParseDicomDate("20240229").value_or(-1), 19787 - 5);
  for (const char* bad : {"", "2023022", "20230229", "20241301", "20240100", "2024-03-05", "202403051"}) {
    EXPECT_FALSE(ParseDicomDate(bad).has_value()) << "'" << bad << "'";
  }
  EXPECT_DOUBLE_EQ(ParseDicomDateTime("20240305093000").value_or(-1), 19787 * 86400.0 + 34200);
  EXPECT_DOUBLE_EQ(ParseDicomDateTime("202403050930").value_or(-1), 19787 * 86400.0 + 34200);
  EXPECT_DOUBLE_EQ(ParseDicomDateTime("2024030509").value_or(-1), 19787 * 86400.0 + 32400);
  EXPECT_DOUBLE_EQ(ParseDicomDateTime("20240305093000.5-0500").value_or(-1), 19787 * 86400.0 + 34200.5);
  for (const char* bad :
       {"20240305", "2024", "20240305093000+2500", "20240305093000+01", "20240305 093000", "20240305093000.5Z"}) {
    EXPECT_FALSE(ParseDicomDateTime(bad).has_value()) << "'" << bad << "'";
  }
}

// ------------------------------------------------- a PET series through the cage

fs::path MrFolder() { return SharedData() / "mr-chest-dicom-seg3d"; }

// Sets a string-valued element (padded to an even length, as DICOM asks).
void SetText(gdcm::DataSet& ds, gdcm::Tag tag, gdcm::VR vr, std::string value) {
  if (value.size() % 2) value += vr == gdcm::VR::UI ? '\0' : ' ';
  gdcm::DataElement e(tag);
  e.SetVR(vr);
  e.SetByteValue(value.data(), std::uint32_t(value.size()));
  ds.Replace(e);
}

// The MR's slices rewritten into `dir` as a PET of the FDG scan above: Units
// BQML, ATTN\DECY, 70 kg (unless `weight` is false), the Radiopharmaceutical
// Information Sequence's dose, half life and 08:30 injection, a series time
// of 11:30 (made after the scan) and acquisitions from 09:30, the earliest
// in the 6th file by name.
void WritePet(const fs::path& dir, bool weight) {
  int n = 0;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(MrFolder())) {
    if (e.path().extension() == ".dcm") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& file : files) {
    gdcm::Reader reader;
    reader.SetFileName(file.c_str());
    ASSERT_TRUE(reader.Read()) << file;
    gdcm::DataSet& ds = reader.GetFile().GetDataSet();
    SetText(ds, gdcm::Tag(0x0008, 0x0060), gdcm::VR::CS, "PT");
    SetText(ds, gdcm::Tag(0x0054, 0x1001), gdcm::VR::CS, "BQML");
    SetText(ds, gdcm::Tag(0x0028, 0x0051), gdcm::VR::CS, "ATTN\\DECY");
    if (weight) {
      SetText(ds, gdcm::Tag(0x0010, 0x1030), gdcm::VR::DS, "70");
    } else {
      ds.Remove(gdcm::Tag(0x0010, 0x1030));
    }
    SetText(ds, gdcm::Tag(0x0008, 0x0021), gdcm::VR::DA, "20240305");
    SetText(ds, gdcm::Tag(0x0008, 0x0031), gdcm::VR::TM, "113000");
    SetText(ds, gdcm::Tag(0x0008, 0x0022), gdcm::VR::DA, "20240305");
    const int after = n == 5 ? 0 : 10 + n;  // seconds after 09:30:00
    SetText(ds, gdcm::Tag(0x0008, 0x0032), gdcm::VR::TM, fmt::format("0930{:02d}.000", after));
    gdcm::Item item;
    item.SetVLToUndefined();
    gdcm::DataSet& nested = item.GetNestedDataSet();
    SetText(nested, gdcm::Tag(0x0018, 0x1072), gdcm::VR::TM, "083000.00");
    SetText(nested, gdcm::Tag(0x0018, 0x1074), gdcm::VR::DS, "370000000");
    SetText(nested, gdcm::Tag(0x0018, 0x1075), gdcm::VR::DS, "6586.2");
    gdcm::SmartPointer<gdcm::SequenceOfItems> sequence = new gdcm::SequenceOfItems;
    sequence->SetLengthToUndefined();
    sequence->AddItem(item);
    gdcm::DataElement radiopharmaceutical(gdcm::Tag(0x0054, 0x0016));
    radiopharmaceutical.SetVR(gdcm::VR::SQ);
    radiopharmaceutical.SetValue(*sequence);
    radiopharmaceutical.SetVLToUndefined();
    ds.Replace(radiopharmaceutical);
    gdcm::Writer writer;
    writer.SetFile(reader.GetFile());
    const fs::path out = dir / file.filename();
    writer.SetFileName(out.c_str());
    ASSERT_TRUE(writer.Write()) << out;
    ++n;
  }
}

VolumeSeries LoadFolder(const fs::path& folder) {
  v1::VolumeSource source;
  source.set_dicom_folder(folder.string());
  return LoadVolumeSeries(source);
}

// Read in the cage's child, computed in the parent: every phase's metadata.
TEST(SuvDicom, APetSeriesLoadsWithItsFactorFromTheEarliestAcquisition) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WritePet(dir.path(), true);
  const VolumeSeries series = LoadFolder(dir.path());
  ASSERT_EQ(series.phases.size(), 1u);
  const VolumeMetadata& m = series.phases.front().metadata();
  EXPECT_EQ(m.modality, "PT");
  EXPECT_EQ(m.suv_refused, "");
  EXPECT_NEAR(m.suv_factor, kFdgFactor, 1e-10);
}

TEST(SuvDicom, APetWithoutAWeightLoadsRefusedWithItsReason) {
  CINEVOL_REQUIRE_SHARED_DATA();
  ScratchDir dir;
  WritePet(dir.path(), false);
  const VolumeSeries series = LoadFolder(dir.path());
  const Volume& v = series.phases.front();
  EXPECT_EQ(v.dims().z, 20);
  EXPECT_EQ(v.metadata().suv_factor, 0);
  EXPECT_EQ(v.metadata().suv_refused, "Patient's Weight (0010,1030) is missing (or no number)");
}

TEST(SuvDicom, AnMrHasNoFactorAndNoRefusal) {
  CINEVOL_REQUIRE_SHARED_DATA();
  const VolumeMetadata& m = LoadFolder(MrFolder()).phases.front().metadata();
  EXPECT_EQ(m.suv_factor, 0);
  EXPECT_EQ(m.suv_refused, "");
}

}  // namespace
}  // namespace cinevol
