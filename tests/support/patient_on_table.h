// A synthetic CT in HU for table removal (issue 32): a patient (an elliptic
// trunk with lungs and a spine, an arm beside it) lying on a curved table,
// and a lead that runs a quarter of the scan. Index x is the patient's left,
// y posterior, z superior (LPS), so the table lies at large y.
#pragma once

#include <cmath>

#include "core/vec.h"

namespace cinevol::testing {

struct PatientOnTable {
  Vec3i dims{100, 80, 40};
  float spacing_mm = 2.5f;
  float gap_mm = 12.0f;  // between the back and the table; 0: the back rests on it
  int resting_slices = 0;  // slices from z = 0 where the back rests on the table (gap 0) all the same

  // What is where, in mm in the slice plane.
  static constexpr float kTrunkX = 125, kTrunkY = 90, kTrunkA = 70, kTrunkB = 50;
  static constexpr float kTableRadius = 110, kTableThickness = 4;

  // The trunk lowered onto the table in the resting slices.
  bool InTrunk(float x, float y, int z = -1) const {
    const float lowered = z >= 0 && z < resting_slices ? gap_mm : 0.0f;
    return Sq((x - kTrunkX) / kTrunkA) + Sq((y - kTrunkY - lowered) / kTrunkB) <= 1;
  }
  bool InLung(float x, float y) const {
    return Sq((std::abs(x - kTrunkX) - 30) / 20) + Sq((y - 85) / 25) <= 1;
  }
  bool InSpine(float x, float y) const { return Sq(x - kTrunkX) + Sq(y - 125) <= Sq(10); }
  bool InArm(float x, float y) const { return Sq(x - 30) + Sq(y - 60) <= Sq(18); }
  // An arc of a circle under the back, its lowest point gap_mm below it.
  float TableCentreY() const { return kTrunkY + kTrunkB + gap_mm - kTableRadius; }
  bool InTable(float x, float y) const {
    const float r = std::sqrt(Sq(x - kTrunkX) + Sq(y - TableCentreY()));
    return y > kTrunkY && r >= kTableRadius && r <= kTableRadius + kTableThickness;
  }
  bool InLead(float x, float y, int z) const { return z < dims.z / 4 && Sq(x - 215) + Sq(y - 40) <= Sq(2.0f); }

  float Hu(int xi, int yi, int z) const {
    const float x = (float(xi) + 0.5f) * spacing_mm, y = (float(yi) + 0.5f) * spacing_mm;
    if (InTrunk(x, y, z)) return InSpine(x, y) ? 700.0f : (InLung(x, y) ? -850.0f : 40.0f);
    if (InArm(x, y)) return 40.0f;
    if (InTable(x, y) || InLead(x, y, z)) return 300.0f;
    return -1000.0f;
  }

 private:
  static float Sq(float v) { return v * v; }
};

}  // namespace cinevol::testing
