// DICOM Part 10 bytes from outside read strictly and within bounds, by cinevol's own parser (no library that may
// assert on hostile bytes): the data set as a tree of elements and sequence items, values as views into the bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cinevol::pacs {

// What one read may take. Memory is known before it is taken: at most
// max_elements elements and max_items items, each a few words, besides the bytes.
struct Part10Limits {
  std::size_t max_bytes = std::size_t{32} << 20;    // [132; 1 GiB] - the whole file
  std::size_t max_elements = std::size_t{1} << 18;  // data elements, every level together
  std::size_t max_items = std::size_t{1} << 15;     // sequence items, every sequence together
  int max_depth = 24;                               // [1; 64] - sequences nested in sequences
};

// A data element: its tag, its VR (as the file wrote it; in implicit VR the
// one cinevol knows for the tag, else "UN") and its value as a view into the
// bytes; a sequence's items are Part10Dataset::items_[first_item, +item_count).
struct Part10Element {
  std::uint32_t tag = 0;  // (group << 16) | element
  char vr[2] = {'U', 'N'};
  std::string_view value;
  std::uint32_t first_item = 0;
  std::uint32_t item_count = 0;

  bool Is(std::string_view v) const { return v.size() == 2 && vr[0] == v[0] && vr[1] == v[1]; }
  std::string_view Vr() const { return {vr, 2}; }
};

// One data set (the file's, or a sequence item): Part10Dataset::elements_[first_element, +element_count), in
// ascending tag order.
struct Part10Item {
  std::uint32_t first_element = 0;
  std::uint32_t element_count = 0;
};

// "(0040,A730)": how messages name a tag.
std::string TagName(std::uint32_t tag);

class Part10Dataset {
 public:
  // Reads `bytes`: a 128-byte preamble, "DICM", the file meta information
  // (group 0002, explicit VR little endian), then the data set in explicit or
  // implicit VR little endian (the two transfer syntaxes an SR travels in;
  // deflated and big endian ones are refused by name). Every length is
  // checked against what holds it; items and sequences of undefined length
  // end at their delimiters; tags ascend within each item. Throws InputError
  // saying what is wrong and where ("DICOM: ... at byte N"), and the limit
  // that was passed ("more than 32768 sequence items").
  static Part10Dataset Read(std::string bytes, const Part10Limits& limits = {});

  const Part10Item& root() const { return root_; }
  const std::string& transfer_syntax() const { return transfer_syntax_; }

  // The element `tag` of `item`, or null.
  const Part10Element* Find(const Part10Item& item, std::uint32_t tag) const;
  // The items of sequence `tag` of `item`: empty when absent; InputError when it is there but not a sequence.
  std::vector<const Part10Item*> Items(const Part10Item& item, std::uint32_t tag) const;
  // The value of text element `tag` (any string VR), without its padding
  // (trailing spaces and NULs; leading spaces too for CS, DS, IS, UI);
  // nullopt when absent; InputError when its VR is not a string VR.
  std::optional<std::string> Text(const Part10Item& item, std::uint32_t tag) const;
  // The values of an FL (or FD) element, at most `max_values`; InputError for another VR, a length that is not a
  // whole number of values, or more values than that.
  std::vector<double> Floats(const Part10Item& item, std::uint32_t tag, std::size_t max_values) const;

 private:
  std::unique_ptr<const std::string> bytes_;  // what the views point into: it stays put when the data set moves
  std::vector<Part10Element> elements_;
  std::vector<Part10Item> items_;
  Part10Item root_;
  std::string transfer_syntax_;
  friend class Part10Parser;
};

}  // namespace cinevol::pacs
