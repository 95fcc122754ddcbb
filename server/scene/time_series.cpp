// PhaseAt and CheckTime: see time_series.h.
#include "scene/time_series.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace cinevol {

int PhaseAt(const v1::Time& time, int from, double elapsed_s, const std::vector<double>& seconds, int phases) {
  if (phases < 2) return 0;
  from = std::clamp(from, 0, phases - 1);
  if (!time.playing()) return std::clamp(int(time.phase()), 0, phases - 1);
  elapsed_s = std::max(0.0, elapsed_s);
  const bool real_time = time.phases_per_second() == 0 && int(seconds.size()) == phases && seconds.back() > 0;
  if (!real_time) {
    const double rate = time.phases_per_second() > 0 ? time.phases_per_second() : kDefaultPhasesPerSecond;
    return int((from + static_cast<long long>(std::floor(elapsed_s * rate))) % phases);
  }
  const double period = seconds.back() * phases / (phases - 1);  // the last phase lasts the mean span
  const double at = std::fmod(seconds[std::size_t(from)] + elapsed_s, period);
  const auto after = std::upper_bound(seconds.begin(), seconds.end(), at);
  return std::max(0, int(after - seconds.begin()) - 1);
}

void CheckTime(const v1::Time& time, int phases, const std::string& field) {
  if (time.phase() >= std::uint32_t(std::max(phases, 1))) {
    throw InputError(fmt::format("{}.phase: {} is past the volume's last phase ({} of {})", field, time.phase(),
                                 std::max(phases, 1) - 1, std::max(phases, 1)));
  }
  if (!(time.phases_per_second() >= 0 && time.phases_per_second() <= kMaxPhasesPerSecond)) {
    throw InputError(fmt::format("{}.phases_per_second: {} is outside [0, {:g}] (0: the series' own times)", field,
                                 time.phases_per_second(), kMaxPhasesPerSecond));
  }
  if (time.playing() && phases < 2) {
    throw InputError(fmt::format("{}.playing: the volume is not a time series (one phase)", field));
  }
}

}  // namespace cinevol
