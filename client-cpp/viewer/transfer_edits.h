// Edits a transfer function the way the viewer's editor does (move, add and
// delete points, window/level) and evaluates it, without any UI: pure
// functions of the proto, so they are unit-tested on their own.
#pragma once

#include "cinevol/v1/scene.pb.h"

namespace cinevol::viewer {

// Smallest gap kept between neighbouring point values: 1e-4 of the points'
// value range, and never less than a few float ulps of the values themselves.
float MinPointGap(const v1::TransferFunction& tf);

// Moves point `index` to (value, opacity). The value is clamped to lie at
// least MinPointGap() inside its neighbours, so values stay strictly
// increasing; opacity is clamped to [0, 1]. Clears the preset, since the
// points now define the function. False (and tf unchanged) for an index out
// of range or a non-finite value or opacity.
bool MoveTransferPoint(v1::TransferFunction& tf, int index, float value, float opacity);

// Inserts a point at `value` with `opacity` (clamped to [0, 1]). Its diffuse,
// specular, roughness and emission are interpolated linearly from its
// neighbours, or copied from the nearest end point beyond the ends (an empty
// function gets a white diffuse, non-specular point). Clears the preset.
// Returns the new point's index, or -1 (tf unchanged) when a point already has
// that value (within MinPointGap()) or the value is not finite.
int AddTransferPoint(v1::TransferFunction& tf, float value, float opacity);

// Deletes point `index`, keeping at least two points: false (tf unchanged)
// when only two are left or the index is out of range. Clears the preset.
bool DeleteTransferPoint(v1::TransferFunction& tf, int index);

// Window/level as radiologists use it: every value moves by `level_delta`
// (data units) and their spread around the centre of [first, last] is scaled
// by `window_scale` (clamped to [0.05, 20]; > 1 widens the window). Values
// stay strictly increasing. Does nothing to a function without points.
void ApplyWindowLevel(v1::TransferFunction& tf, float level_delta, float window_scale);

// Piecewise-linear evaluation between points; beyond the ends the end point's
// channel holds. An empty function gives opacity 0 and black.
float OpacityAt(const v1::TransferFunction& tf, float value);
v1::Color DiffuseAt(const v1::TransferFunction& tf, float value);

}  // namespace cinevol::viewer
