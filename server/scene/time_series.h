// A time series' clock (Scene.time): which phase a session shows while it
// plays, from where it started and how long ago, at a rate or in the series'
// own time, looping.
#pragma once

#include <string>
#include <vector>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

// While playing at no rate and with no times from the series: phases a second.
inline constexpr float kDefaultPhasesPerSecond = 10;
inline constexpr float kMaxPhasesPerSecond = 120;

// The phase shown `elapsed_s` seconds after playing began at phase `from`
// (of `phases`, each at `seconds` from the first where the series says:
// empty otherwise). Not playing: time.phase. Playing at
// time.phases_per_second, or at 0 in real time: each phase for its span, the
// last for the mean span, then the first again.
int PhaseAt(const v1::Time& time, int from, double elapsed_s, const std::vector<double>& seconds, int phases);

// Throws InputError (prefixed by `field`) unless `time` fits a series of
// `phases` phases: a phase that exists, a rate in [0, kMaxPhasesPerSecond],
// playing only a series of more than one phase.
void CheckTime(const v1::Time& time, int phases, const std::string& field);

}  // namespace cinevol
