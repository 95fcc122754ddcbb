// What a scene's Phantom asks for, its defaults filled and its ranges
// checked: the scene model's side of phantoms (io/phantom.h builds them).
#pragma once

#include <string>

#include "cinevol/v1/scene.pb.h"

namespace cinevol {

struct PhantomSpec {
  v1::Phantom::Kind kind;
  int size;                                 // voxels along each axis
  float spacing, value, background, radius;  // mm, values, values, mm
};

// `spec` with its defaults (scene.proto); throws InputError naming the field
// when it is out of range.
PhantomSpec ResolvePhantom(const v1::Phantom& spec);

// Throws as ResolvePhantom does.
void ValidatePhantom(const v1::Phantom& spec);

// "phantom:head", "phantom:cube" or "phantom:sphere".
std::string PhantomName(const v1::Phantom& spec);

}  // namespace cinevol
