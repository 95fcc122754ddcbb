// Part10Dataset::Read: one linear pass over the bytes, every length checked against what holds it, every count
// against its limit as it is reached.
#include "pacs/part10_reader.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <utility>

#include "core/error.h"

namespace cinevol::pacs {

static_assert(std::endian::native == std::endian::little, "values are read as the host's: little endian");

namespace {

constexpr std::uint32_t kUndefinedLength = 0xFFFFFFFF;
constexpr std::uint32_t kItem = 0xFFFEE000;
constexpr std::uint32_t kItemDelimiter = 0xFFFEE00D;
constexpr std::uint32_t kSequenceDelimiter = 0xFFFEE0DD;
constexpr std::uint32_t kTransferSyntaxUid = 0x00020010;
constexpr std::size_t kPreamble = 128;

constexpr const char* kExplicitLittle = "1.2.840.10008.1.2.1";
constexpr const char* kImplicitLittle = "1.2.840.10008.1.2";
constexpr const char* kDeflatedExplicit = "1.2.840.10008.1.2.1.99";
constexpr const char* kExplicitBig = "1.2.840.10008.1.2.2";

// VRs whose explicit header has two reserved bytes and a 32-bit length (PS3.5 7.1.2).
bool HasLongLength(std::string_view vr) {
  for (const char* v : {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"}) {
    if (vr == v) return true;
  }
  return false;
}

bool IsKnownVr(std::string_view vr) {
  for (const char* v :
       {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT", "OB", "OD", "OF", "OL", "OV",
        "OW", "PN", "SH", "SL", "SQ", "SS", "ST", "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"}) {
    if (vr == v) return true;
  }
  return false;
}

bool IsStringVr(std::string_view vr) {
  for (const char* v :
       {"AE", "AS", "CS", "DA", "DS", "DT", "IS", "LO", "LT", "PN", "SH", "ST", "TM", "UC", "UI", "UR", "UT"}) {
    if (vr == v) return true;
  }
  return false;
}

// The VRs of the tags cinevol's readers read (a measurement report's, a presentation state's), for implicit VR
// files, which do not say: the sequences to walk into, and the values read. Any other tag there is UN.
const char* ImplicitVr(std::uint32_t tag) {
  struct Known {
    std::uint32_t tag;
    const char* vr;
  };
  static constexpr Known kKnown[] = {
      {0x00080005, "CS"}, {0x00080016, "UI"}, {0x00080018, "UI"}, {0x00080060, "CS"}, {0x00080100, "SH"},
      {0x00080102, "SH"}, {0x00080103, "SH"}, {0x00080104, "LO"}, {0x00080105, "CS"}, {0x00080110, "SQ"},
      {0x00080119, "UC"}, {0x00080120, "UR"}, {0x00081032, "SQ"}, {0x00081110, "SQ"}, {0x00081111, "SQ"},
      {0x00081115, "SQ"}, {0x00081140, "SQ"}, {0x0008114A, "SQ"}, {0x00081150, "UI"}, {0x00081155, "UI"},
      {0x00081160, "IS"}, {0x00081199, "SQ"}, {0x00081200, "SQ"}, {0x0020000D, "UI"}, {0x0020000E, "UI"},
      {0x00200052, "UI"}, {0x00281050, "DS"}, {0x00281051, "DS"}, {0x00281101, "US"}, {0x00281102, "US"},
      {0x00281103, "US"}, {0x00281104, "US"}, {0x00281201, "OW"}, {0x00281202, "OW"}, {0x00281203, "OW"},
      {0x00281204, "OW"}, {0x0028140F, "CS"}, {0x00281410, "CS"}, {0x004008EA, "SQ"}, {0x0040A010, "CS"},
      {0x0040A040, "CS"}, {0x0040A043, "SQ"}, {0x0040A050, "CS"}, {0x0040A073, "SQ"}, {0x0040A078, "SQ"},
      {0x0040A07A, "SQ"}, {0x0040A124, "UI"}, {0x0040A160, "UT"}, {0x0040A168, "SQ"}, {0x0040A195, "SQ"},
      {0x0040A300, "SQ"}, {0x0040A301, "SQ"}, {0x0040A30A, "DS"}, {0x0040A360, "SQ"}, {0x0040A370, "SQ"},
      {0x0040A372, "SQ"}, {0x0040A375, "SQ"}, {0x0040A385, "SQ"}, {0x0040A504, "SQ"}, {0x0040A525, "SQ"},
      {0x0040A730, "SQ"}, {0x0040DB00, "CS"}, {0x0062000B, "US"}, {0x00700022, "FL"}, {0x00700023, "CS"}, {0x00700080, "CS"},
      {0x00700081, "LO"}, {0x00701104, "SQ"}, {0x00701201, "SQ"}, {0x00701202, "CS"}, {0x00701204, "CS"}, {0x00701205, "US"},
      {0x00701207, "US"}, {0x00701209, "UI"}, {0x0070120A, "SQ"}, {0x0070120B, "CS"}, {0x0070120C, "US"},
      {0x00701301, "SQ"}, {0x00701302, "CS"}, {0x00701303, "FD"}, {0x00701304, "SQ"}, {0x00701305, "FD"},
      {0x00701306, "FD"}, {0x00701309, "US"}, {0x00701602, "CS"}, {0x00701603, "FD"}, {0x00701604, "FD"},
      {0x00701605, "FD"}, {0x00701606, "FD"}, {0x00701607, "FD"}, {0x00701701, "CS"}, {0x00701702, "FD"}, {0x00701703, "FD"},
      {0x00701704, "FD"}, {0x00701705, "FD"}, {0x00701706, "FD"}, {0x00701801, "SQ"}, {0x00701802, "CS"},
      {0x00701803, "SQ"}, {0x00701804, "US"}, {0x00701A08, "SQ"}, {0x00701A09, "LO"}, {0x30060024, "UI"},
  };
  const auto* end = std::end(kKnown);
  const auto* it =
      std::lower_bound(std::begin(kKnown), end, tag, [](const Known& k, std::uint32_t t) { return k.tag < t; });
  return it != end && it->tag == tag ? it->vr : "UN";
}

std::string_view Trimmed(std::string_view text, bool leading) {
  while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.remove_suffix(1);
  while (leading && !text.empty() && text.front() == ' ') text.remove_prefix(1);
  return text;
}

}  // namespace

std::string TagName(std::uint32_t tag) { return fmt::format("({:04X},{:04X})", tag >> 16, tag & 0xFFFF); }

class Part10Parser {
 public:
  Part10Parser(Part10Dataset& out, const Part10Limits& limits) : out_(out), limits_(limits), bytes_(*out.bytes_) {}

  void Run() {
    if (bytes_.size() < kPreamble + 4 || bytes_.substr(kPreamble, 4) != "DICM") {
      Fail(0, "not a DICOM Part 10 file: no \"DICM\" after the 128-byte preamble");
    }
    std::size_t pos = kPreamble + 4;
    ReadMeta(pos);
    const std::string& syntax = out_.transfer_syntax_;
    if (syntax == kDeflatedExplicit) {
      Fail(pos,
           "transfer syntax 1.2.840.10008.1.2.1.99 (deflated explicit VR little endian), which cinevol does "
           "not read: store it uncompressed");
    }
    if (syntax == kExplicitBig) Fail(pos, "transfer syntax 1.2.840.10008.1.2.2 (explicit VR big endian, retired)");
    if (syntax != kExplicitLittle && syntax != kImplicitLittle) {
      Fail(pos, fmt::format("transfer syntax {}, which cinevol does not read (it reads explicit or implicit "
                            "VR little endian)",
                            syntax.substr(0, 64)));
    }
    out_.root_ = ParseItem(pos, bytes_.size(), false, syntax == kImplicitLittle, 0);
  }

 private:
  [[noreturn]] void Fail(std::size_t at, const std::string& why) const {
    throw InputError(fmt::format("DICOM: {} (at byte {})", why, at));
  }

  void Need(std::size_t pos, std::size_t count, std::size_t limit, const char* what) const {
    if (pos > limit || limit - pos < count) Fail(pos, fmt::format("the file ends inside {}", what));
  }
  std::uint16_t U16(std::size_t pos) const {
    std::uint16_t v;
    std::memcpy(&v, bytes_.data() + pos, 2);
    return v;
  }
  std::uint32_t U32(std::size_t pos) const {
    std::uint32_t v;
    std::memcpy(&v, bytes_.data() + pos, 4);
    return v;
  }
  std::uint32_t TagAt(std::size_t pos) const { return (std::uint32_t(U16(pos)) << 16) | U16(pos + 2); }

  void CountElement(std::size_t pos) {
    if (++elements_ > limits_.max_elements) {
      Fail(pos, fmt::format("more than {} data elements, the most cinevol reads in one object", limits_.max_elements));
    }
  }

  // The header of the element at `pos` (which holds its tag): its VR, value length, and header size.
  struct Header {
    char vr[2];
    std::uint32_t length;
    std::size_t size;
  };
  Header ReadHeader(std::size_t pos, std::size_t limit, bool implicit, std::uint32_t tag) const {
    Need(pos, 8, limit, "an element's header");
    if (implicit) {
      const char* vr = ImplicitVr(tag);
      return {{vr[0], vr[1]}, U32(pos + 4), 8};
    }
    const std::string_view vr = bytes_.substr(pos + 4, 2);
    if (!IsKnownVr(vr)) Fail(pos, fmt::format("element {} has no known VR", TagName(tag)));
    if (!HasLongLength(vr)) return {{vr[0], vr[1]}, U16(pos + 6), 8};
    Need(pos, 12, limit, "an element's header");
    return {{vr[0], vr[1]}, U32(pos + 8), 12};
  }

  // File meta information: explicit VR little endian whatever follows, group 0002 only.
  void ReadMeta(std::size_t& pos) {
    bool seen_syntax = false;
    std::uint32_t last = 0;
    while (pos + 4 <= bytes_.size() && U16(pos) == 0x0002) {
      const std::uint32_t tag = TagAt(pos);
      if (tag <= last && last != 0) Fail(pos, fmt::format("meta element {} out of order", TagName(tag)));
      last = tag;
      CountElement(pos);
      const Header h = ReadHeader(pos, bytes_.size(), false, tag);
      if (h.length == kUndefinedLength || std::string_view(h.vr, 2) == "SQ") {
        Fail(pos, fmt::format("meta element {} is a sequence or of undefined length", TagName(tag)));
      }
      Need(pos + h.size, h.length, bytes_.size(), "the file meta information");
      if (tag == kTransferSyntaxUid) {
        out_.transfer_syntax_ = std::string(Trimmed(bytes_.substr(pos + h.size, h.length), true));
        seen_syntax = true;
      }
      pos += h.size + h.length;
    }
    if (!seen_syntax) Fail(pos, "the file meta information names no transfer syntax (0002,0010)");
  }

  // A data set from `pos`: up to `limit` (a defined length), or to its item
  // delimiter (`undefined`, within `limit`). Its elements are appended to the
  // data set once it is whole, so they lie together.
  Part10Item ParseItem(std::size_t& pos, std::size_t limit, bool undefined, bool implicit, int depth) {
    std::vector<Part10Element> elements;
    std::uint32_t last = 0;
    bool any = false;
    while (undefined || pos < limit) {
      Need(pos, 8, limit, undefined ? "an item of undefined length (no item delimiter)" : "an element");
      const std::uint32_t tag = TagAt(pos);
      if (tag == kItemDelimiter) {
        if (!undefined) Fail(pos, "an item delimiter inside an item of defined length");
        if (U32(pos + 4) != 0) Fail(pos, "an item delimiter with a length");
        pos += 8;
        break;
      }
      if ((tag >> 16) == 0xFFFE) Fail(pos, fmt::format("{} where a data element should be", TagName(tag)));
      if (any && tag <= last) {
        Fail(pos, fmt::format("element {} {} {}", TagName(tag), tag == last ? "twice: after" : "out of order: after",
                              TagName(last)));
      }
      last = tag;
      any = true;
      CountElement(pos);
      const Header h = ReadHeader(pos, limit, implicit, tag);
      Part10Element element;
      element.tag = tag;
      std::memcpy(element.vr, h.vr, 2);
      const std::size_t start = pos;
      pos += h.size;
      const bool sequence = element.Is("SQ") || (element.Is("UN") && h.length == kUndefinedLength);
      if (sequence) {
        // A UN of undefined length is a sequence in implicit VR (PS3.5 6.2.2).
        const bool inner_implicit = implicit || element.Is("UN");
        element.vr[0] = 'S';
        element.vr[1] = 'Q';
        if (depth + 1 > limits_.max_depth) {
          Fail(start, fmt::format("sequences nested more than {} deep", limits_.max_depth));
        }
        if (h.length == kUndefinedLength) {
          std::tie(element.first_item, element.item_count) = ParseSequence(pos, limit, true, inner_implicit, depth + 1);
        } else {
          Need(pos, h.length, limit, fmt::format("sequence {}", TagName(tag)).c_str());
          const std::size_t end = pos + h.length;
          std::tie(element.first_item, element.item_count) = ParseSequence(pos, end, false, inner_implicit, depth + 1);
        }
      } else {
        if (h.length == kUndefinedLength) {
          Fail(start, fmt::format("element {} ({}) of undefined length, which only a sequence may have", TagName(tag),
                                  element.Vr()));
        }
        Need(pos, h.length, limit, fmt::format("the value of {}", TagName(tag)).c_str());
        element.value = bytes_.substr(pos, h.length);
        pos += h.length;
      }
      elements.push_back(element);
    }
    Part10Item item;
    item.first_element = std::uint32_t(out_.elements_.size());
    item.element_count = std::uint32_t(elements.size());
    out_.elements_.insert(out_.elements_.end(), elements.begin(), elements.end());
    return item;
  }

  // A sequence's items from `pos`, up to `limit` or its delimiter; appended once whole, so they lie together.
  std::pair<std::uint32_t, std::uint32_t> ParseSequence(std::size_t& pos, std::size_t limit, bool undefined,
                                                        bool implicit, int depth) {
    std::vector<Part10Item> items;
    while (undefined || pos < limit) {
      Need(pos, 8, limit, undefined ? "a sequence of undefined length (no sequence delimiter)" : "an item");
      const std::uint32_t tag = TagAt(pos);
      const std::uint32_t length = U32(pos + 4);
      if (tag == kSequenceDelimiter) {
        if (!undefined) Fail(pos, "a sequence delimiter inside a sequence of defined length");
        if (length != 0) Fail(pos, "a sequence delimiter with a length");
        pos += 8;
        break;
      }
      if (tag != kItem) Fail(pos, fmt::format("a sequence holds {} where an item should be", TagName(tag)));
      if (++items_ > limits_.max_items) {
        Fail(pos, fmt::format("more than {} sequence items, the most cinevol reads in one object", limits_.max_items));
      }
      pos += 8;
      if (length == kUndefinedLength) {
        items.push_back(ParseItem(pos, limit, true, implicit, depth));
      } else {
        Need(pos, length, limit, "an item");
        items.push_back(ParseItem(pos, pos + length, false, implicit, depth));
      }
    }
    const auto first = std::uint32_t(out_.items_.size());
    out_.items_.insert(out_.items_.end(), items.begin(), items.end());
    return {first, std::uint32_t(items.size())};
  }

  Part10Dataset& out_;
  const Part10Limits& limits_;
  const std::string_view bytes_;
  std::size_t elements_ = 0;
  std::size_t items_ = 0;
};

Part10Dataset Part10Dataset::Read(std::string bytes, const Part10Limits& limits) {
  if (bytes.size() > limits.max_bytes) {
    throw InputError(
        fmt::format("DICOM: the object is {} bytes; cinevol reads at most {}", bytes.size(), limits.max_bytes));
  }
  Part10Dataset dataset;
  dataset.bytes_ = std::make_unique<const std::string>(std::move(bytes));
  Part10Parser(dataset, limits).Run();
  return dataset;
}

const Part10Element* Part10Dataset::Find(const Part10Item& item, std::uint32_t tag) const {
  const auto begin = elements_.begin() + item.first_element;
  const auto end = begin + item.element_count;
  const auto it = std::lower_bound(begin, end, tag, [](const Part10Element& e, std::uint32_t t) { return e.tag < t; });
  return it != end && it->tag == tag ? &*it : nullptr;
}

std::vector<const Part10Item*> Part10Dataset::Items(const Part10Item& item, std::uint32_t tag) const {
  const Part10Element* element = Find(item, tag);
  if (element == nullptr) return {};
  if (!element->Is("SQ")) {
    throw InputError(fmt::format("DICOM: {} has VR {}; a sequence (SQ) was expected", TagName(tag), element->Vr()));
  }
  std::vector<const Part10Item*> items;
  for (std::uint32_t i = 0; i < element->item_count; ++i) items.push_back(&items_[element->first_item + i]);
  return items;
}

std::optional<std::string> Part10Dataset::Text(const Part10Item& item, std::uint32_t tag) const {
  const Part10Element* element = Find(item, tag);
  if (element == nullptr) return std::nullopt;
  if (!IsStringVr(element->Vr())) {
    throw InputError(fmt::format("DICOM: {} has VR {}; a text was expected", TagName(tag), element->Vr()));
  }
  const bool leading = element->Is("CS") || element->Is("DS") || element->Is("IS") || element->Is("UI");
  return std::string(Trimmed(element->value, leading));
}

std::vector<double> Part10Dataset::Floats(const Part10Item& item, std::uint32_t tag, std::size_t max_values) const {
  const Part10Element* element = Find(item, tag);
  if (element == nullptr) return {};
  const bool single = element->Is("FL");
  if (!single && !element->Is("FD")) {
    throw InputError(fmt::format("DICOM: {} has VR {}; FL (32-bit floats) was expected", TagName(tag), element->Vr()));
  }
  const std::size_t size = single ? 4 : 8;
  if (element->value.size() % size != 0) {
    throw InputError(fmt::format("DICOM: {} is {} bytes, not a whole number of {} values", TagName(tag),
                                 element->value.size(), element->Vr()));
  }
  const std::size_t count = element->value.size() / size;
  if (count > max_values) {
    throw InputError(
        fmt::format("DICOM: {} holds {} values; at most {} were expected", TagName(tag), count, max_values));
  }
  std::vector<double> values(count);
  for (std::size_t i = 0; i < count; ++i) {
    if (single) {
      float f;
      std::memcpy(&f, element->value.data() + i * 4, 4);
      values[i] = f;
    } else {
      std::memcpy(&values[i], element->value.data() + i * 8, 8);
    }
  }
  return values;
}

}  // namespace cinevol::pacs
