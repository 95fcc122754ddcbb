// A second volume fused with the session's (Scene.fusion; docs/time-and-fusion.md):
// how the viewer starts one (--fuse) and how its Second volume panel and
// scripts make it glow in 3D. The same defaults as the page's
// (web/src/fusion_panel.ts, glowOf and fusedStart), so that both clients
// show a fused study alike.
#pragma once

#include <string>

#include "cinevol/v1/service.pb.h"

namespace cinevol::viewer {

// --fuse ID [--align-by-patient]: the second volume a new session starts with.
struct FuseStart {
  std::string volume_id;  // empty: none
  bool align_by_patient = false;
};

// How the second volume glows in 3D: transparent below a threshold, emitting
// warm light above it. In SUVbw where the volume has it (2.5 and up: the usual
// threshold of FDG uptake), else over the top 70% of its range.
v1::TransferFunction GlowOf(const v1::VolumeInfo& fused);

// The fusion a session starts with: `fused` glowing, overlaid in HOT at 0.5,
// in SUVbw where it has it.
v1::Fusion FusedStart(const v1::VolumeInfo& fused, bool align_by_patient);

// Whether the second volume shows in 3D (its transfer function has points).
bool Glows(const v1::Fusion& fusion);
// Makes it glow (GlowOf `fused`) or shows it in slices only (no points).
void SetGlow(v1::Fusion& fusion, bool glow, const v1::VolumeInfo& fused);

}  // namespace cinevol::viewer
