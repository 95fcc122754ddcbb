// JPEG 2000 payloads of DICOM pixel data, mutated at the marker level: the
// main header's segments (SIZ: image and tile sizes, components, bit depths,
// subsampling; COD: progression, layers, colour transform, decomposition
// levels, code blocks; QCD), their lengths, the tile parts (SOT lengths and
// indices, the coded data), and a JP2 wrapper (its image header and colour
// boxes). Part of fuzz_dicom's mutator (dicom_model.h).
#pragma once

#include <cstddef>
#include <string>

#include "dicom_model.h"

namespace cinevol::fuzz {

// Whether `payload` starts like a J2K codestream or a JP2 file.
bool LooksLikeJ2k(const std::string& payload);

// Mutates a codestream or JP2 file at the marker or box level; falls back
// to byte mutations of its coded data when it does not parse.
void MutateJ2k(std::string& payload, Random& random, const ByteMutator& mutate, std::size_t max_size);

// A codestream of `width` x `height` x `components` at `bits` (signed when
// asked) whose main header is sound and whose coded data is made up: it
// parses, and decoding exercises the tile decoder on noise.
std::string SyntheticJ2k(Random& random, std::uint32_t width, std::uint32_t height, int components, int bits,
                         bool is_signed);

}  // namespace cinevol::fuzz
