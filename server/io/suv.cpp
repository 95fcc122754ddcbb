// SUVbw from a PET's DICOM attributes: QIBA's pseudo-code, every attribute
// checked on the way (they come from a file, through the reader cage).
#include "io/suv.h"

#include <fmt/format.h>

#include <cmath>
#include <vector>

#include "core/log_safe.h"  // ValidUtf8

namespace cinevol {
namespace {

constexpr double kSecondsPerDay = 86400;
// An injection given as a time only, later in the day than the scan: taken as
// the day before where that puts it at most this long before the scan.
constexpr double kMidnightSpanS = 12 * 3600;

// A value from the file as messages quote it: control characters escaped
// (\xNN), bytes that are not UTF-8 too, at most 64 bytes of it.
std::string Quoted(std::string_view value) {
  constexpr std::size_t kMost = 64;
  std::string out;
  for (const char c : value.substr(0, kMost)) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      out += fmt::format("\\x{:02x}", byte);
    } else {
      out += c;
    }
  }
  if (value.size() > kMost) out += fmt::format("...({} bytes)", value.size());
  return fmt::format("'{}'", ValidUtf8(out));
}

std::string_view TrimmedEnd(std::string_view s) {
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.remove_suffix(1);
  return s;
}

// The `n` digits at `s`'s front as a number, consumed; nullopt where fewer.
std::optional<int> Digits(std::string_view& s, std::size_t n) {
  if (s.size() < n) return std::nullopt;
  int v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (s[i] < '0' || s[i] > '9') return std::nullopt;
    v = 10 * v + (s[i] - '0');
  }
  s.remove_prefix(n);
  return v;
}

bool IsLeapYear(int y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

int DaysInMonth(int y, int m) {
  static constexpr int kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && IsLeapYear(y) ? 29 : kDays[m - 1];
}

// Days from 1970-01-01 to the proleptic Gregorian y-m-d (valid), counted
// through 400-year eras that start on 1 March.
std::int64_t DaysFromCivil(int y, int m, int d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const std::int64_t year_of_era = y - era * 400;
  const std::int64_t day_of_year = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const std::int64_t day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
  return era * 146097 + day_of_era - 719468;
}

// "YYYYMMDD" at `s`'s front (dots between the parts allowed where `dots`),
// consumed.
std::optional<std::int64_t> DateAt(std::string_view& s, bool dots) {
  const std::optional<int> y = Digits(s, 4);
  if (dots && s.starts_with('.')) s.remove_prefix(1);
  const std::optional<int> m = Digits(s, 2);
  if (dots && s.starts_with('.')) s.remove_prefix(1);
  const std::optional<int> d = Digits(s, 2);
  if (!y || !m || !d || *m < 1 || *m > 12 || *d < 1 || *d > DaysInMonth(*y, *m)) return std::nullopt;
  return DaysFromCivil(*y, *m, *d);
}

// "HH[MM[SS[.F{1,6}]]]" at `s`'s front (colons between the parts allowed
// where `colons`), consumed; the seconds since midnight.
std::optional<double> TimeAt(std::string_view& s, bool colons) {
  const std::optional<int> h = Digits(s, 2);
  if (!h || *h > 23) return std::nullopt;
  double seconds = 3600.0 * *h;
  const auto part = [&](int most, double unit) -> std::optional<bool> {  // false: none there
    const bool colon = colons && s.starts_with(':');                     // then digits must follow
    if (colon) s.remove_prefix(1);
    if (!colon && (s.empty() || s[0] < '0' || s[0] > '9')) return false;
    const std::optional<int> v = Digits(s, 2);
    if (!v || *v > most) return std::nullopt;
    seconds += unit * *v;
    return true;
  };
  const std::optional<bool> minutes = part(59, 60);
  if (!minutes) return std::nullopt;
  if (!*minutes) return seconds;
  const std::optional<bool> whole_seconds = part(60, 1);  // 60: a leap second
  if (!whole_seconds) return std::nullopt;
  if (!*whole_seconds) return seconds;
  if (!s.starts_with('.')) return seconds;
  s.remove_prefix(1);
  double unit = 0.1;
  std::size_t n = 0;
  for (; n < s.size() && n < 6 && s[n] >= '0' && s[n] <= '9'; ++n, unit /= 10) seconds += unit * (s[n] - '0');
  if (n == 0) return std::nullopt;
  s.remove_prefix(n);
  return seconds;
}

// A DICOM date and time as seconds since 1970-01-01 00:00, and the value as
// the file says it, for messages.
struct Instant {
  double seconds;
  std::string shown;
};

// Corrected Image's values ("ATTN\DECY\...").
bool Holds(std::string_view values, std::string_view value) {
  while (!values.empty()) {
    const std::size_t end = std::min(values.find('\\'), values.size());
    std::string_view item = values.substr(0, end);
    while (item.starts_with(' ')) item.remove_prefix(1);
    if (TrimmedEnd(item) == value) return true;
    values.remove_prefix(std::min(end + 1, values.size()));
  }
  return false;
}

SuvbwFactor Refused(std::string sentence) { return {0, std::move(sentence)}; }

// The scan's start (QIBA): the series date and time, or the earliest
// acquisition's where the series time is later than it; or a refusal.
struct ScanStart {
  std::optional<Instant> at;
  std::string refused;
};

ScanStart ScanStartOf(const reader::PetDose& pet) {
  const std::string_view series_date = TrimmedEnd(pet.series_date()), series_time = TrimmedEnd(pet.series_time());
  const std::string_view acquisition_time = TrimmedEnd(pet.acquisition_time());
  std::string_view acquisition_date = TrimmedEnd(pet.acquisition_date());
  if (acquisition_date.empty()) acquisition_date = series_date;
  std::optional<Instant> series, acquisition;
  if (!series_date.empty() && !series_time.empty()) {
    const std::optional<std::int64_t> day = ParseDicomDate(series_date);
    if (!day) return {std::nullopt, fmt::format("Series Date (0008,0021) {} is no DICOM date", Quoted(series_date))};
    const std::optional<double> time = ParseDicomTime(series_time);
    if (!time) return {std::nullopt, fmt::format("Series Time (0008,0031) {} is no DICOM time", Quoted(series_time))};
    series = Instant{double(*day) * kSecondsPerDay + *time,
                     fmt::format("Series Date and Time {} {}", Quoted(series_date), Quoted(series_time))};
  }
  if (!acquisition_time.empty() && !acquisition_date.empty()) {
    const std::optional<std::int64_t> day = ParseDicomDate(acquisition_date);
    if (!day) {
      return {std::nullopt, fmt::format("Acquisition Date (0008,0022) {} is no DICOM date", Quoted(acquisition_date))};
    }
    const std::optional<double> time = ParseDicomTime(acquisition_time);
    if (!time) {
      return {std::nullopt, fmt::format("Acquisition Time (0008,0032) {} is no DICOM time", Quoted(acquisition_time))};
    }
    acquisition =
        Instant{double(*day) * kSecondsPerDay + *time, fmt::format("the earliest Acquisition Date and Time {} {}",
                                                                   Quoted(acquisition_date), Quoted(acquisition_time))};
  }
  if (series && (!acquisition || series->seconds <= acquisition->seconds)) return {series, ""};
  if (acquisition) return {acquisition, ""};
  return {std::nullopt, fmt::format("Series {} (0008,{}) is missing, and so is Acquisition Time (0008,0032): the "
                                    "scan's start is not known",
                                    series_date.empty() ? "Date" : "Time", series_date.empty() ? "0021" : "0031")};
}

// The injection: its date and time, or its time on the scan's date (the day
// before where the scan started after midnight); or a refusal.
struct Injection {
  std::optional<Instant> at;
  std::string refused;
};

Injection InjectionOf(const reader::PetDose& pet, const Instant& scan) {
  const std::string_view datetime = TrimmedEnd(pet.injection_datetime()), time = TrimmedEnd(pet.injection_time());
  if (!datetime.empty()) {
    const std::optional<double> at = ParseDicomDateTime(datetime);
    if (!at) {
      return {std::nullopt, fmt::format("Radiopharmaceutical Start DateTime (0018,1078) {} is no DICOM date and time",
                                        Quoted(datetime))};
    }
    return {Instant{*at, fmt::format("Radiopharmaceutical Start DateTime (0018,1078) {}", Quoted(datetime))}, ""};
  }
  if (time.empty()) {
    return {std::nullopt,
            "Radiopharmaceutical Start Time (0018,1072) and DateTime (0018,1078) are missing: the injection's time "
            "is not known"};
  }
  const std::optional<double> of_day = ParseDicomTime(time);
  if (!of_day) {
    return {std::nullopt, fmt::format("Radiopharmaceutical Start Time (0018,1072) {} is no DICOM time", Quoted(time))};
  }
  const double scan_day = std::floor(scan.seconds / kSecondsPerDay) * kSecondsPerDay;
  double at = scan_day + *of_day;
  if (at > scan.seconds && at - kSecondsPerDay >= scan.seconds - kMidnightSpanS) at -= kSecondsPerDay;
  return {Instant{at, fmt::format("Radiopharmaceutical Start Time (0018,1072) {}{}", Quoted(time),
                                  at < scan_day ? " (the day before the scan)" : "")},
          ""};
}

}  // namespace

std::optional<std::int64_t> ParseDicomDate(std::string_view da) {
  da = TrimmedEnd(da);
  const std::optional<std::int64_t> day = DateAt(da, true);
  if (!day || !da.empty()) return std::nullopt;
  return day;
}

std::optional<double> ParseDicomTime(std::string_view tm) {
  tm = TrimmedEnd(tm);
  const std::optional<double> seconds = TimeAt(tm, true);
  if (!seconds || !tm.empty()) return std::nullopt;
  return seconds;
}

std::optional<double> ParseDicomDateTime(std::string_view dt) {
  dt = TrimmedEnd(dt);
  const std::optional<std::int64_t> day = DateAt(dt, false);
  if (!day) return std::nullopt;
  const std::optional<double> time = TimeAt(dt, false);
  if (!time) return std::nullopt;
  if (!dt.empty()) {  // an offset from UTC: "+HHMM" or "-HHMM"
    if (dt[0] != '+' && dt[0] != '-') return std::nullopt;
    dt.remove_prefix(1);
    const std::optional<int> hours = Digits(dt, 2), minutes = Digits(dt, 2);
    if (!hours || !minutes || *hours > 14 || *minutes > 59 || !dt.empty()) return std::nullopt;
  }
  return double(*day) * kSecondsPerDay + *time;
}

SuvbwFactor SuvbwFactorOf(const reader::PetDose& pet) {
  const std::string_view units = TrimmedEnd(pet.units());
  if (units.empty()) return Refused("Units (0054,1001) is missing: what the values measure is not known");
  if (units == "GML") return {1, ""};  // SUVbw already (g/ml)
  if (units != "BQML") {
    return Refused(
        fmt::format("Units (0054,1001) is {}: cinevol computes SUVbw from BQML (Bq/ml), or takes GML as "
                    "SUVbw",
                    Quoted(units)));
  }
  const std::string_view corrected = TrimmedEnd(pet.corrected_image());
  for (const auto& [value, what] : {std::pair{"DECY", "decay"}, std::pair{"ATTN", "attenuation"}}) {
    if (corrected.empty() || Holds(corrected, value)) continue;
    return Refused(fmt::format("Corrected Image (0028,0051) is {}, without {}: the images are not {} corrected",
                               Quoted(corrected), value, what));
  }
  const std::string_view decay_correction = TrimmedEnd(pet.decay_correction());
  const bool admin = decay_correction == "ADMIN";
  if (!admin && !decay_correction.empty() && decay_correction != "START") {
    return Refused(fmt::format(
        "Decay Correction (0054,1102) is {}: {}", Quoted(decay_correction),
        decay_correction == "NONE" ? "the images are not decay corrected" : "cinevol reads START or ADMIN"));
  }
  const double weight = pet.patient_weight_kg(), dose = pet.total_dose_bq(), half_life = pet.half_life_s();
  if (!(weight > 0 && weight <= kMaxSuvWeightKg)) {
    return Refused(weight == 0 ? std::string("Patient's Weight (0010,1030) is missing (or no number)")
                               : fmt::format("Patient's Weight (0010,1030) is {:g} kg, outside (0, {:g}] kg", weight,
                                             kMaxSuvWeightKg));
  }
  if (!(dose > 0 && dose <= kMaxSuvDoseBq)) {
    return Refused(dose == 0 ? std::string("Radionuclide Total Dose (0018,1074) is missing (or no number)")
                             : fmt::format("Radionuclide Total Dose (0018,1074) is {:g} Bq, outside (0, {:g}] Bq", dose,
                                           kMaxSuvDoseBq));
  }
  const double weight_g = weight * 1000;
  if (admin) return {weight_g / dose, ""};  // the images are corrected to the injection: the dose as given
  if (!(half_life > 0 && half_life <= kMaxSuvHalfLifeS)) {
    return Refused(half_life == 0 ? std::string("Radionuclide Half Life (0018,1075) is missing (or no number)")
                                  : fmt::format("Radionuclide Half Life (0018,1075) is {:g} s, outside (0, {:g}] s",
                                                half_life, kMaxSuvHalfLifeS));
  }
  const ScanStart scan = ScanStartOf(pet);
  if (!scan.at) return Refused(scan.refused);
  const Injection injection = InjectionOf(pet, *scan.at);
  if (!injection.at) return Refused(injection.refused);
  const double decay_s = scan.at->seconds - injection.at->seconds;
  if (decay_s < 0 || decay_s > kMaxUptakeS) {
    return Refused(fmt::format("the injection, {}, is {:.0f} s {} the scan's start, {}{}", injection.at->shown,
                               std::abs(decay_s), decay_s < 0 ? "after" : "before", scan.at->shown,
                               decay_s < 0 ? "" : fmt::format(": more than {:g} h", kMaxUptakeS / 3600)));
  }
  const double factor = weight_g / (dose * std::exp2(-decay_s / half_life));
  if (!std::isfinite(factor)) {
    return Refused(
        fmt::format("Radionuclide Half Life (0018,1075) is {:g} s: the dose is all decayed in the {:.0f} "
                    "s from the injection to the scan",
                    half_life, decay_s));
  }
  return {factor, ""};
}

}  // namespace cinevol
