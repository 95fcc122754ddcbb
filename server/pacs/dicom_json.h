// The DICOM JSON model (PS3.18 F.2) that QIDO-RS and STOW-RS answer in, read
// defensively: an attribute that is missing, of the wrong JSON type or absurd
// reads as absent, never as a crash. Parsed by JsonDocument, whose bounds no
// answer gets past (json_document.h).
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "pacs/json_document.h"

namespace cinevol::pacs {

// The longest text kept from one attribute's value, in bytes (a PN or LO holds
// 64 characters per value); longer values are cut here, between characters.
constexpr std::size_t kMaxDicomText = 256;

// `text` as valid UTF-8 of at most `max_bytes`: each malformed sequence
// becomes U+FFFD, and a cut never splits a character.
std::string CleanText(std::string_view text, std::size_t max_bytes = kMaxDicomText);

// One data set (one JSON object, tags as keys).
class DicomJsonDataset {
 public:
  explicit DicomJsonDataset(JsonDocument::Ref object) : object_(object) {}

  // The first value of `tag` as text (a string, or a number written out); empty when absent or not text.
  std::string Text(std::uint32_t tag) const;
  // Every value of `tag` that is text, at most `max_values`.
  std::vector<std::string> Texts(std::uint32_t tag, std::size_t max_values) const;
  // The first value of a PN attribute: its Alphabetic group (or the value itself where a PACS sends a string).
  std::string PersonName(std::uint32_t tag) const;
  // The first value of `tag` as a whole number in [0; 2^31), from a JSON number or a numeric string.
  std::optional<std::int64_t> Count(std::uint32_t tag) const;
  // The first `max_values` values of a numeric attribute (DS, FD, FL, IS: JSON
  // numbers or numeric strings); a value that is not a finite number ends
  // the list there.
  std::vector<double> Numbers(std::uint32_t tag, std::size_t max_values) const;
  // The items of a sequence (SQ) attribute, at most `max_items`.
  std::vector<DicomJsonDataset> Items(std::uint32_t tag, std::size_t max_items) const;

 private:
  // The "Value" array of `tag`'s items; empty when absent.
  std::vector<JsonDocument::Ref> Values(std::uint32_t tag) const;
  JsonDocument::Ref object_;
};

// A DICOM JSON answer: an array of data sets (QIDO-RS) or one data set
// (STOW-RS answers), parsed into `storage`. Throws JsonError (an
// std::invalid_argument) when `json` is not JSON of that shape within the
// limits; Cancelled once `cancel` is raised. Objects inside that are not data
// sets are skipped.
std::vector<DicomJsonDataset> ParseDicomJson(std::string_view json, JsonDocument& storage,
                                             const std::atomic<bool>* cancel = nullptr);

// True for a DICOM UID: 1 to 64 characters of digits and dots, no empty
// component. (Leading zeros, which PS3.5 forbids, are let through: some
// devices write them, and they cannot change a URL's meaning.)
bool IsValidUid(std::string_view uid);

}  // namespace cinevol::pacs
