// Finds a CT's table (the couch the patient lies on) so that it can be hidden
// like a label: thin structures outside the body that run along the scan,
// flat or curved, and the partial-volume rim around them. Computed once per
// volume, on the loader (docs/volumes-and-scenes.md, "Table removal").
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "core/labels.h"
#include "core/volume.h"

namespace cinevol {

// What FindTable decides per voxel, one byte each.
enum TableMaskBits : std::uint8_t {
  kBodyVoxel = 1u << 0,      // the body: everything thick the table is not
  kTableVoxel = 1u << 1,     // the table, above the table threshold
  kTableRimVoxel = 1u << 2,  // its partial-volume rim: touching it, neither table nor body nor its rim
};

struct TableSettings {
  // [1; 20] mm. Structures thinner than twice this are thin: tables, pads,
  // cables are; bodies and limbs are not.
  float opening_mm = 6.0f;
  // [0; 10] mm. Gaps in a body's outline this wide close before its holes
  // fill, where fat is as dark as air (not CT in HU).
  float closing_mm = 4.0f;
  // [0; 1]. A table runs along the scan: its components span at least this
  // fraction of the axial slices (a nose tip or a lead does not).
  float min_axial_span = 0.5f;
  // [0; 1000] ml. A table is large: smaller components (slivers of lung a
  // crop's edge cuts off, speckle) are not one.
  float min_table_ml = 5.0f;
  // [0; 1]. A thin component: at most this fraction of its voxels lies in a
  // region thicker than 2 * opening_mm (a lung cut by a crop's edge is thick).
  float max_thick_fraction = 0.1f;
  // Raised: the search stops within one pass over the volume, throwing Cancelled.
  const std::atomic<bool>* cancel = nullptr;
};

struct TableMask {
  Vec3i dims;
  // TableMaskBits per voxel (x fastest); empty where no table was found or searched.
  std::vector<std::uint8_t> voxels;
  std::uint64_t body_voxels = 0, table_voxels = 0, rim_voxels = 0;
  int table_components = 0;
  // Above body_threshold a voxel may be body; above table_threshold, table.
  float body_threshold = 0, table_threshold = 0;
  int axial_axis = 2;   // the index axis nearest the patient's head-feet axis
  double seconds = 0;   // what the search took
  std::string note;     // what was found, or why nothing, for people
  bool found() const { return table_voxels > 0; }
};

// Searches CT volumes (in HU, scaled, or 8-bit exports the histogram does not
// tell from CT) for a table; MR volumes get an empty mask and a note. Holds
// one byte per voxel while it runs.
TableMask FindTable(const Volume& volume, const TableSettings& settings = {});

// Memory FindTable holds at most for a volume of `voxels` voxels, besides
// the volume: what a load reserves before it searches.
std::uint64_t TableSearchBytes(std::uint64_t voxels);

}  // namespace cinevol
