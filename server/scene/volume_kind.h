// What a volume's values are (CT in HU, CT not in HU, MR, other data),
// judged from its metadata where it says and from its histogram otherwise.
// The kind picks the default preset.
#pragma once

#include <string>

#include "cinevol/v1/service.pb.h"
#include "core/volume.h"

namespace cinevol {

struct VolumeKindJudgement {
  v1::VolumeKind kind = v1::OTHER;
  std::string reason;  // what the judgement rests on, for people
};

VolumeKindJudgement JudgeVolumeKind(const Volume& volume);

}  // namespace cinevol
