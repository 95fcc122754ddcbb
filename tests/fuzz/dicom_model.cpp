// DicomFile: parsing, writing and mutating DICOM files as trees of elements.
#include "dicom_model.h"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "j2k_model.h"

namespace cinevol::fuzz {
namespace {

constexpr int kMaxDepth = 12;
constexpr std::size_t kMaxElements = 50000;
constexpr std::size_t kMaxInflated = std::size_t{16} << 20;

const char* const kVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO", "LT",
                            "OB", "OD", "OF", "OL", "OV", "OW", "PN", "SH", "SL", "SQ", "SS", "ST",
                            "SV", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT", "UV"};
const char* const kLongVrs[] = {"OB", "OD", "OF", "OL", "OV", "OW", "SQ", "SV", "UC", "UN", "UR", "UT", "UV"};

bool IsKnownVr(const char* v) {
  return std::any_of(std::begin(kVrs), std::end(kVrs), [&](const char* k) { return std::memcmp(k, v, 2) == 0; });
}
bool IsLongVr(const std::string& vr) {
  return vr.size() == 2 &&
         std::any_of(std::begin(kLongVrs), std::end(kLongVrs), [&](const char* k) { return vr == k; });
}

// The size of the binary numbers a VR holds (what big endian swaps); 0 for text and bytes.
int SwapUnit(const std::string& vr) {
  if (vr == "US" || vr == "SS" || vr == "OW" || vr == "AT") return 2;
  if (vr == "UL" || vr == "SL" || vr == "FL" || vr == "OF" || vr == "OL") return 4;
  if (vr == "FD" || vr == "OD" || vr == "SV" || vr == "UV" || vr == "OV") return 8;
  return 0;
}

std::string Swapped(std::string value, const std::string& vr) {
  const int unit = SwapUnit(vr);
  if (unit == 0) return value;
  for (std::size_t i = 0; i + unit <= value.size(); i += unit)
    std::reverse(value.begin() + i, value.begin() + i + unit);
  return value;
}

// What an implicit VR data set would call the elements cinevol's readers and
// GDCM look at; UN for the rest.
struct DictionaryEntry {
  std::uint16_t group, element;
  const char* vr;
};
constexpr DictionaryEntry kDictionary[] = {
    {0x0002, 0x0000, "UL"}, {0x0002, 0x0001, "OB"}, {0x0002, 0x0002, "UI"}, {0x0002, 0x0003, "UI"},
    {0x0002, 0x0010, "UI"}, {0x0002, 0x0012, "UI"}, {0x0002, 0x0013, "SH"}, {0x0008, 0x0008, "CS"},
    {0x0008, 0x0016, "UI"}, {0x0008, 0x0018, "UI"}, {0x0008, 0x0060, "CS"}, {0x0008, 0x0070, "LO"},
    {0x0008, 0x103e, "LO"}, {0x0008, 0x1115, "SQ"}, {0x0008, 0x1140, "SQ"}, {0x0010, 0x0010, "PN"},
    {0x0018, 0x0050, "DS"}, {0x0018, 0x0088, "DS"}, {0x0018, 0x1164, "DS"}, {0x0020, 0x000d, "UI"},
    {0x0020, 0x000e, "UI"}, {0x0020, 0x0013, "IS"}, {0x0020, 0x0032, "DS"}, {0x0020, 0x0037, "DS"},
    {0x0020, 0x0052, "UI"}, {0x0020, 0x1041, "DS"}, {0x0020, 0x9113, "SQ"}, {0x0020, 0x9116, "SQ"},
    {0x0028, 0x0002, "US"}, {0x0028, 0x0004, "CS"}, {0x0028, 0x0006, "US"}, {0x0028, 0x0008, "IS"},
    {0x0028, 0x0009, "AT"}, {0x0028, 0x0010, "US"}, {0x0028, 0x0011, "US"}, {0x0028, 0x0030, "DS"},
    {0x0028, 0x0034, "IS"}, {0x0028, 0x0100, "US"}, {0x0028, 0x0101, "US"}, {0x0028, 0x0102, "US"},
    {0x0028, 0x0103, "US"}, {0x0028, 0x0106, "US"}, {0x0028, 0x0107, "US"}, {0x0028, 0x0120, "US"},
    {0x0028, 0x1050, "DS"}, {0x0028, 0x1051, "DS"}, {0x0028, 0x1052, "DS"}, {0x0028, 0x1053, "DS"},
    {0x0028, 0x1054, "LO"}, {0x0028, 0x1101, "US"}, {0x0028, 0x1102, "US"}, {0x0028, 0x1103, "US"},
    {0x0028, 0x1201, "OW"}, {0x0028, 0x1202, "OW"}, {0x0028, 0x1203, "OW"}, {0x0028, 0x2110, "CS"},
    {0x0028, 0x3000, "SQ"}, {0x0028, 0x3002, "US"}, {0x0028, 0x3004, "LO"}, {0x0028, 0x3006, "US"},
    {0x0028, 0x3010, "SQ"}, {0x0028, 0x9110, "SQ"}, {0x0028, 0x9145, "SQ"}, {0x0088, 0x0200, "SQ"},
    {0x5200, 0x9229, "SQ"}, {0x5200, 0x9230, "SQ"}, {0x7fe0, 0x0008, "OF"}, {0x7fe0, 0x0009, "OD"},
    {0x7fe0, 0x0010, "OW"},
};

std::string ImplicitVr(std::uint16_t group, std::uint16_t element) {
  for (const DictionaryEntry& d : kDictionary) {
    if (d.group == group && d.element == element) return d.vr;
  }
  if (element == 0x0000) return "UL";  // group lengths
  return "UN";
}

bool IsPixelData(std::uint16_t group, std::uint16_t element) { return group == 0x7fe0 && element == 0x0010; }

// ---- parsing

class Parser {
 public:
  explicit Parser(const std::string& bytes) : b_(bytes) {}

  std::uint16_t U16(std::size_t at, bool be) const {
    const auto* p = reinterpret_cast<const std::uint8_t*>(b_.data()) + at;
    return be ? std::uint16_t(p[0] << 8 | p[1]) : std::uint16_t(p[1] << 8 | p[0]);
  }
  std::uint32_t U32(std::size_t at, bool be) const {
    return be ? std::uint32_t(U16(at, true)) << 16 | U16(at + 2, true)
              : std::uint32_t(U16(at + 2, false)) << 16 | U16(at, false);
  }

  // Elements from `at` until `end` or an (FFFE,xxxx) tag; false (with `at`
  // at the element that failed) when one does not parse.
  bool Elements(std::size_t& at, std::size_t end, bool explicit_vr, bool be, int depth, std::vector<Element>& out) {
    while (at < end) {
      if (at + 8 <= end && U16(at, be) == 0xfffe) return true;
      Element e;
      std::size_t next = at;
      if (!One(next, end, explicit_vr, be, depth, e)) return false;
      out.push_back(std::move(e));
      at = next;
    }
    return true;
  }

  // One element that is not an item or delimiter.
  bool Single(std::size_t& at, std::size_t end, bool explicit_vr, bool be, Element& e) {
    if (at + 8 > end || U16(at, be) == 0xfffe) return false;
    return One(at, end, explicit_vr, be, 0, e);
  }

 private:
  bool One(std::size_t& at, std::size_t end, bool explicit_vr, bool be, int depth, Element& e) {
    if (depth > kMaxDepth || ++count_ > kMaxElements || at + 8 > end) return false;
    e.group = U16(at, be);
    e.element = U16(at + 2, be);
    std::uint32_t length;
    std::size_t header;
    if (explicit_vr) {
      if (!IsKnownVr(b_.data() + at + 4)) return false;
      e.vr.assign(b_.data() + at + 4, 2);
      if (IsLongVr(e.vr)) {
        if (at + 12 > end) return false;
        length = U32(at + 8, be);
        header = 12;
      } else {
        length = U16(at + 6, be);
        header = 8;
      }
    } else {
      e.vr = ImplicitVr(e.group, e.element);
      length = U32(at + 4, be);
      header = 8;
    }
    std::size_t p = at + header;
    if (length == 0xffffffffu) {
      const bool fragments = IsPixelData(e.group, e.element) || (explicit_vr && (e.vr == "OB" || e.vr == "OW"));
      if (fragments) {
        e.kind = Element::Kind::kFragments;
        if (!Fragments(p, end, be, e.fragments)) return false;
      } else {
        e.kind = Element::Kind::kSequence;
        e.undefined_length = true;
        const bool inner_explicit = explicit_vr && e.vr != "UN";
        if (!Items(p, end, inner_explicit, inner_explicit && be, depth + 1, true, e.items)) return false;
      }
      at = p;
      return true;
    }
    if (length > end - p) return false;
    if (e.vr == "SQ") {
      std::size_t q = p;
      std::vector<Item> items;
      if (Items(q, p + length, explicit_vr, be, depth + 1, false, items) && q == p + length) {
        e.kind = Element::Kind::kSequence;
        e.items = std::move(items);
        at = p + length;
        return true;
      }
    }
    e.value = b_.substr(p, length);
    if (be) e.value = Swapped(std::move(e.value), e.vr);
    at = p + length;
    return true;
  }

  // Items of a sequence up to its end (`delimited`: up to and past the
  // sequence delimiter).
  bool Items(std::size_t& at, std::size_t end, bool explicit_vr, bool be, int depth, bool delimited,
             std::vector<Item>& out) {
    while (at + 8 <= end) {
      if (U16(at, be) != 0xfffe || ++count_ > kMaxElements) return false;
      const std::uint16_t element = U16(at + 2, be);
      const std::uint32_t length = U32(at + 4, be);
      if (element == 0xe0dd && delimited) {
        at += 8;
        return true;
      }
      if (element != 0xe000) return false;
      at += 8;
      Item item;
      if (length == 0xffffffffu) {
        item.undefined_length = true;
        if (!Elements(at, end, explicit_vr, be, depth, item.elements)) return false;
        if (at + 8 > end || U16(at, be) != 0xfffe || U16(at + 2, be) != 0xe00d) return false;
        at += 8;
      } else {
        if (length > end - at) return false;
        const std::size_t item_end = at + length;
        if (!Elements(at, item_end, explicit_vr, be, depth, item.elements) || at != item_end) return false;
      }
      out.push_back(std::move(item));
    }
    return !delimited && at == end;
  }

  bool Fragments(std::size_t& at, std::size_t end, bool be, std::vector<std::string>& out) {
    while (at + 8 <= end) {
      if (U16(at, be) != 0xfffe || ++count_ > kMaxElements) return false;
      const std::uint16_t element = U16(at + 2, be);
      const std::uint32_t length = U32(at + 4, be);
      at += 8;
      if (element == 0xe0dd) return true;
      if (element != 0xe000 || length > end - at) return false;
      out.push_back(b_.substr(at, length));
      at += length;
    }
    return false;
  }

  const std::string& b_;
  std::size_t count_ = 0;
};

std::optional<std::string> Inflate(const std::string& in) {
  z_stream z{};
  if (inflateInit2(&z, -15) != Z_OK) return std::nullopt;
  std::string out;
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = uInt(in.size());
  int rc = Z_OK;
  char buffer[16384];
  while (rc == Z_OK && out.size() < kMaxInflated) {
    z.next_out = reinterpret_cast<Bytef*>(buffer);
    z.avail_out = sizeof buffer;
    rc = inflate(&z, Z_NO_FLUSH);
    out.append(buffer, sizeof buffer - z.avail_out);
    if (rc == Z_BUF_ERROR && z.avail_in == 0) break;
  }
  inflateEnd(&z);
  if (rc != Z_STREAM_END) return std::nullopt;
  return out;
}

std::string Deflate(const std::string& in) {
  z_stream z{};
  deflateInit2(&z, 6, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY);
  std::string out(deflateBound(&z, uLong(in.size())) + 16, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = uInt(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = uInt(out.size());
  deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

// ---- writing

class Writer {
 public:
  static void U16(std::string& out, std::uint32_t v, bool be) {
    const char b[2] = {char(v & 0xff), char((v >> 8) & 0xff)};
    if (be) {
      out.push_back(b[1]);
      out.push_back(b[0]);
    } else {
      out.append(b, 2);
    }
  }
  static void U32(std::string& out, std::uint32_t v, bool be) {
    if (be) {
      U16(out, v >> 16, true);
      U16(out, v & 0xffff, true);
    } else {
      U16(out, v & 0xffff, false);
      U16(out, v >> 16, false);
    }
  }
  static void Tag(std::string& out, std::uint16_t group, std::uint16_t element, bool be) {
    U16(out, group, be);
    U16(out, element, be);
  }

  static void Elements(std::string& out, const std::vector<Element>& elements, bool explicit_vr, bool be) {
    for (const Element& e : elements) One(out, e, explicit_vr, be);
  }

  static void One(std::string& out, const Element& e, bool explicit_vr, bool be) {
    std::string body;
    std::uint32_t length = 0;
    switch (e.kind) {
      case Element::Kind::kValue:
        body = be ? Swapped(e.value, e.vr) : e.value;
        length = e.undefined_length ? 0xffffffffu : std::uint32_t(body.size());
        break;
      case Element::Kind::kSequence: {
        const bool inner_explicit = explicit_vr && !(e.undefined_length && e.vr == "UN");
        const bool inner_be = inner_explicit && be;
        for (const Item& item : e.items) {
          std::string inner;
          Elements(inner, item.elements, inner_explicit, inner_be);
          Tag(body, 0xfffe, 0xe000, inner_be);
          U32(body, item.undefined_length ? 0xffffffffu : item.stated_length.value_or(std::uint32_t(inner.size())),
              inner_be);
          body += inner;
          if (item.undefined_length) {
            Tag(body, 0xfffe, 0xe00d, inner_be);
            U32(body, 0, inner_be);
          }
        }
        if (e.undefined_length) {
          Tag(body, 0xfffe, 0xe0dd, inner_be);
          U32(body, 0, inner_be);
        }
        length = e.undefined_length ? 0xffffffffu : std::uint32_t(body.size());
        break;
      }
      case Element::Kind::kFragments:
        for (const std::string& f : e.fragments) {
          Tag(body, 0xfffe, 0xe000, be);
          U32(body, std::uint32_t(f.size()), be);
          body += f;
        }
        Tag(body, 0xfffe, 0xe0dd, be);
        U32(body, 0, be);
        length = 0xffffffffu;
        break;
    }
    if (e.stated_length) length = *e.stated_length;
    Tag(out, e.group, e.element, be);
    if (explicit_vr) {
      out.append(e.vr.size() == 2 ? e.vr : std::string("UN"));
      if (IsLongVr(e.vr)) {
        U16(out, 0, be);
        U32(out, length, be);
      } else {
        U16(out, length == 0xffffffffu ? 0xffff : length & 0xffff, be);
      }
    } else {
      U32(out, length, be);
    }
    out += body;
  }
};

// ---- values

std::string US(std::initializer_list<unsigned> values) {
  std::string out;
  for (unsigned v : values) Writer::U16(out, v, false);
  return out;
}
std::string UL(std::uint32_t v) {
  std::string out;
  Writer::U32(out, v, false);
  return out;
}
// Text padded to an even length with a space (UIDs with NUL).
std::string Text(std::string s, char pad = ' ') {
  if (s.size() % 2) s.push_back(pad);
  return s;
}
std::string Uid(const std::string& s) { return Text(s, '\0'); }

unsigned UsValue(const Element* e, unsigned fallback) {
  if (!e || e->kind != Element::Kind::kValue || e->value.size() < 2) return fallback;
  return unsigned(std::uint8_t(e->value[0])) | unsigned(std::uint8_t(e->value[1])) << 8;
}
long IntValue(const Element* e, long fallback) {
  if (!e || e->kind != Element::Kind::kValue) return fallback;
  const std::string t = Trimmed(e->value);
  char* end = nullptr;
  const long v = std::strtol(t.c_str(), &end, 10);
  return end && end != t.c_str() ? v : fallback;
}
std::vector<double> Numbers(const Element* e) {
  std::vector<double> out;
  if (!e || e->kind != Element::Kind::kValue) return out;
  const std::string t = Trimmed(e->value);
  for (std::size_t at = 0; at <= t.size();) {
    const std::size_t end = std::min(t.find('\\', at), t.size());
    const std::string item = t.substr(at, end - at);
    char* stop = nullptr;
    const double v = std::strtod(item.c_str(), &stop);
    if (item.empty() || stop == item.c_str()) return {};
    out.push_back(v);
    at = end + 1;
  }
  return out;
}

const std::vector<std::string> kTransferSyntaxes = {
    "1.2.840.10008.1.2",       "1.2.840.10008.1.2.1",     "1.2.840.10008.1.2.2",     "1.2.840.10008.1.2.1.99",
    "1.2.840.10008.1.2.4.50",  "1.2.840.10008.1.2.4.51",  "1.2.840.10008.1.2.4.57",  "1.2.840.10008.1.2.4.70",
    "1.2.840.10008.1.2.4.80",  "1.2.840.10008.1.2.4.81",  "1.2.840.10008.1.2.4.90",  "1.2.840.10008.1.2.4.91",
    "1.2.840.10008.1.2.4.92",  "1.2.840.10008.1.2.4.93",  "1.2.840.10008.1.2.4.201", "1.2.840.10008.1.2.4.203",
    "1.2.840.10008.1.2.5",     "1.2.840.10008.1.2.4.100", "1.2.840.10008.1.2.4.94",  "1.2.840.10008.1.2.1.98",
    "1.2.840.113619.5.2",      "1.3.46.670589.33.1.4.1",  "",                        "1.2.840.10008.1.2.4",
    "1.2.840.10008.1.2.4.90.1"};
const std::vector<std::string> kJ2kSyntaxes = {"1.2.840.10008.1.2.4.90", "1.2.840.10008.1.2.4.91",
                                               "1.2.840.10008.1.2.4.92", "1.2.840.10008.1.2.4.93"};
const std::vector<std::string> kNativeSyntaxes = {"1.2.840.10008.1.2", "1.2.840.10008.1.2.1", "1.2.840.10008.1.2.2",
                                                  "1.2.840.10008.1.2.1.99"};

const std::vector<std::string> kPhotometric = {
    "MONOCHROME1", "MONOCHROME2",  "RGB",    "YBR_FULL", "YBR_FULL_422", "YBR_PARTIAL_422", "YBR_PARTIAL_420",
    "YBR_RCT",     "YBR_ICT",      "ARGB",   "CMYK",     "HSV",          "PALETTE COLOR",   "",
    "MONOCHROME",  "RGB\\RGB",     "YBR_",   "PALETTE",  "monochrome2",  std::string(64, 'M')};

// The values that make the image pixel module (and the elements around it)
// interesting: each with its VR and the values to try.
struct Interesting {
  std::uint16_t group, element;
  const char* vr;
  std::vector<std::string> values;
};

std::vector<std::string> UsChoices(std::initializer_list<unsigned> values) {
  std::vector<std::string> out;
  for (unsigned v : values) out.push_back(US({v}));
  return out;
}
std::vector<std::string> TextChoices(std::initializer_list<const char*> values, char pad = ' ') {
  std::vector<std::string> out;
  for (const char* v : values) out.push_back(Text(v, pad));
  return out;
}
std::vector<std::string> Padded(const std::vector<std::string>& values, char pad = ' ') {
  std::vector<std::string> out;
  for (const std::string& v : values) out.push_back(Text(v, pad));
  return out;
}

const std::vector<Interesting>& Table() {
  static const std::vector<Interesting> table = {
      {0x0028, 0x0002, "US", UsChoices({0, 1, 2, 3, 4, 5, 0xffff})},
      {0x0028, 0x0004, "CS", Padded(kPhotometric)},
      {0x0028, 0x0006, "US", UsChoices({0, 1, 2, 0xffff})},
      {0x0028, 0x0008, "IS", TextChoices({"0", "1", "2", "3", "4", "-1", "65536", "2147483648", "", "1.5", "x"})},
      {0x0028, 0x0009, "AT", {US({0x0018, 0x1063}), US({0x0054, 0x0080}), US({0x7fe0, 0x0010}), ""}},
      {0x0028, 0x0010, "US", UsChoices({0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 255, 256, 4096, 32768, 65535})},
      {0x0028, 0x0011, "US", UsChoices({0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 255, 256, 4096, 32768, 65535})},
      {0x0028, 0x0030, "DS",
       TextChoices({"0.5\\0.5", "1\\1", "0\\0", "-1\\1", "nan\\1", "inf\\inf", "1e38\\1e-38", "1", "", "1\\1\\1"})},
      {0x0028, 0x0034, "IS", TextChoices({"1\\1", "0\\0", "1", "-1\\2"})},
      {0x0028, 0x0100, "US", UsChoices({0, 1, 7, 8, 12, 16, 24, 32, 48, 64, 128, 0xffff})},
      {0x0028, 0x0101, "US", UsChoices({0, 1, 7, 8, 11, 12, 15, 16, 17, 24, 32, 64, 0xffff})},
      {0x0028, 0x0102, "US", UsChoices({0, 7, 11, 15, 16, 23, 31, 63, 0xffff})},
      {0x0028, 0x0103, "US", UsChoices({0, 1, 2, 0xffff})},
      {0x0028, 0x0106, "US", UsChoices({0, 0x7fff, 0x8000, 0xffff})},
      {0x0028, 0x0107, "US", UsChoices({0, 0x7fff, 0x8000, 0xffff})},
      {0x0028, 0x0120, "US", UsChoices({0, 0x8000, 0xffff})},
      {0x0028, 0x1050, "DS", TextChoices({"40", "0", "-1e308", "nan", "40\\400"})},
      {0x0028, 0x1051, "DS", TextChoices({"400", "0", "-1", "1e308", "inf"})},
      {0x0028, 0x1052, "DS", TextChoices({"0", "-1024", "1e308", "-1e308", "nan", "inf", "", "1\\2", "1e39"})},
      {0x0028, 0x1053, "DS", TextChoices({"1", "0", "-1", "1e-300", "1e300", "nan", "inf", "", "0.5", "1e-39"})},
      {0x0028, 0x1054, "LO", TextChoices({"HU", "US", "OD", ""})},
      {0x0028,
       0x1101,
       "US",
       {US({256, 0, 8}), US({0, 0, 16}), US({65535, 0, 16}), US({4096, 0, 16}), US({1, 0, 8}), US({256, 65535, 8}),
        US({256, 0, 0}), US({256, 0, 32}), US({256}), ""}},
      {0x0028, 0x1102, "US", {US({256, 0, 8}), US({0, 0, 16}), US({4096, 0, 16}), US({2, 0, 16}), US({256, 0, 1})}},
      {0x0028, 0x1103, "US", {US({256, 0, 8}), US({0, 0, 16}), US({65535, 32768, 16}), US({256, 0, 12})}},
      {0x0028, 0x1201, "OW", {"", std::string(2, '\x7f'), std::string(512, '\x40'), std::string(8192, '\x10')}},
      {0x0028, 0x1202, "OW", {"", std::string(512, '\x20'), std::string(513, '\x20')}},
      {0x0028, 0x1203, "OW", {"", std::string(512, '\x30'), std::string(131072, '\x30')}},
      {0x0028, 0x1221, "OW", {US({0, 2, 0, 255}), US({1, 3, 0}), US({2, 1, 0, 0}), ""}},
      {0x0028, 0x2110, "CS", TextChoices({"00", "01", ""})},
      {0x0002, 0x0010, "UI", Padded(kTransferSyntaxes, '\0')},
      {0x0002, 0x0002, "UI",
       TextChoices({"1.2.840.10008.5.1.4.1.1.2", "1.2.840.10008.5.1.4.1.1.4", "1.2.840.10008.5.1.4.1.1.2.1",
                    "1.2.840.10008.5.1.4.1.1.7", "1.2.840.10008.5.1.4.1.1.481.2", "1.2.840.10008.1.3.10",
                    "1.2.840.10008.5.1.4.1.1.66.4", ""},
                   '\0')},
      {0x0008, 0x0016, "UI",
       TextChoices({"1.2.840.10008.5.1.4.1.1.2", "1.2.840.10008.5.1.4.1.1.4.1", "1.2.840.10008.5.1.4.1.1.3.1",
                    "1.2.840.10008.5.1.4.1.1.7.2", "1.2.840.10008.1.3.10", "1.2.840.10008.5.1.4.1.1.104.1", ""},
                   '\0')},
      {0x0008, 0x0060, "CS", TextChoices({"CT", "MR", "US", "RTDOSE", "SEG", "OT", "PT", ""})},
      {0x0008, 0x0008, "CS", TextChoices({"ORIGINAL\\PRIMARY\\AXIAL", "DERIVED\\SECONDARY\\LOCALIZER", ""})},
      {0x0018, 0x0050, "DS", TextChoices({"1", "0", "-1", "nan", "1e30", "", "0.0001"})},
      {0x0018, 0x0088, "DS", TextChoices({"1", "0", "-2", "nan"})},
      {0x0018, 0x1164, "DS", TextChoices({"0.5\\0.5", "0\\0", "1e30\\1"})},
      {0x0020, 0x000e, "UI", TextChoices({"1.2.826.0.1.3680043.2.1125.1.1", "1.2.3", "", "1"}, '\0')},
      {0x0020, 0x0013, "IS", TextChoices({"1", "0", "-1", "99999999999", ""})},
      {0x0020, 0x0032, "DS",
       TextChoices({"0\\0\\0", "-1\\-1\\10", "nan\\0\\0", "1e308\\0\\0", "0\\0", "", "1e-300\\0\\1e300"})},
      {0x0020, 0x0037, "DS",
       TextChoices({"1\\0\\0\\0\\1\\0", "0\\1\\0\\0\\0\\-1", "1\\0\\0\\1\\0\\0", "0\\0\\0\\0\\0\\0",
                    "nan\\0\\0\\0\\1\\0", "1\\0\\0\\0\\1", "0.7071\\0.7071\\0\\-0.7071\\0.7071\\0",
                    "1e300\\0\\0\\0\\1e300\\0"})},
      {0x7fe0, 0x0008, "OF", {std::string(64, '\x3f'), ""}},
  };
  return table;
}

bool IsPixelModuleTag(std::uint16_t group, std::uint16_t element) {
  return (group == 0x0028 && (element <= 0x0120 || (element >= 0x1101 && element <= 0x1223))) ||
         IsPixelData(group, element);
}

// ---- the tree's lists and elements, for mutations

struct Lists {
  std::vector<std::vector<Element>*> lists;  // every element list: the data set's and every item's
  std::vector<Item*> items;
};

void CollectLists(std::vector<Element>& list, Lists& out, int depth = 0) {
  out.lists.push_back(&list);
  if (depth > kMaxDepth) return;
  for (Element& e : list) {
    for (Item& item : e.items) {
      out.items.push_back(&item);
      CollectLists(item.elements, out, depth + 1);
    }
  }
}

// A random element of the tree (data set and nested items), or null.
Element* AnyElement(DicomFile& file, Random& random, bool include_meta = false) {
  Lists l;
  CollectLists(file.data_set, l);
  if (include_meta && random.OneIn(8)) l.lists.push_back(&file.meta);
  std::vector<std::pair<std::vector<Element>*, std::size_t>> all;
  for (auto* list : l.lists) {
    for (std::size_t i = 0; i < list->size(); ++i) all.emplace_back(list, i);
  }
  if (all.empty()) return nullptr;
  const auto& [list, i] = all[random.Below(all.size())];
  return &(*list)[i];
}

std::vector<Element>& AnyList(DicomFile& file, Random& random) {
  Lists l;
  CollectLists(file.data_set, l);
  return random.OneIn(3) ? file.data_set : *l.lists[random.Below(l.lists.size())];
}

Element& SetIn(std::vector<Element>& list, std::uint16_t group, std::uint16_t element, const std::string& vr,
               const std::string& value) {
  const std::uint32_t tag = std::uint32_t(group) << 16 | element;
  auto it = std::find_if(list.begin(), list.end(), [&](const Element& e) { return e.tag() == tag; });
  if (it == list.end()) {
    it = std::find_if(list.begin(), list.end(), [&](const Element& e) { return e.tag() > tag; });
    Element e;
    e.group = group;
    e.element = element;
    it = list.insert(it, std::move(e));
  }
  it->vr = vr;
  it->kind = Element::Kind::kValue;
  it->value = value;
  it->items.clear();
  it->fragments.clear();
  it->undefined_length = false;
  it->stated_length.reset();
  return *it;
}

void SortList(std::vector<Element>& list) {
  std::stable_sort(list.begin(), list.end(), [](const Element& a, const Element& b) { return a.tag() < b.tag(); });
}

// The pixel data's size the pixel module announces (bits packed), capped.
std::size_t ExpectedPixelBytes(const DicomFile& file) {
  const std::uint64_t rows = UsValue(file.Find(0x0028, 0x0010), 0);
  const std::uint64_t columns = UsValue(file.Find(0x0028, 0x0011), 0);
  const std::uint64_t samples = std::min(UsValue(file.Find(0x0028, 0x0002), 1), 4u);
  const std::uint64_t bits = std::min(UsValue(file.Find(0x0028, 0x0100), 16), 64u);
  const long frames = std::clamp(IntValue(file.Find(0x0028, 0x0008), 1), 1L, 4096L);
  const std::uint64_t bytes = (rows * columns * samples * std::uint64_t(frames) * bits + 7) / 8;
  return std::size_t(std::min<std::uint64_t>(bytes, std::uint64_t{1} << 30));
}

std::string Filled(std::size_t bytes, const std::string& pattern, Random& random) {
  std::string out(bytes, '\0');
  if (!pattern.empty() && !random.OneIn(4)) {
    for (std::size_t i = 0; i < bytes; ++i) out[i] = pattern[i % pattern.size()];
  } else {
    const int style = int(random.Below(3));
    for (std::size_t i = 0; i < bytes; ++i) {
      out[i] = style == 0 ? char(i * 7) : style == 1 ? char(random.Next()) : char(i & 1 ? 0x80 : 0x00);
    }
  }
  return out;
}

// Native pixel data of the size the pixel module announces (within `budget`).
void FitNativePixels(DicomFile& file, Random& random, std::size_t budget) {
  const std::size_t want = std::min(ExpectedPixelBytes(file), budget);
  const Element* old = file.Find(0x7fe0, 0x0010);
  const std::string pattern = old && old->kind == Element::Kind::kValue ? old->value.substr(0, 4096) : "";
  const std::string vr = old ? old->vr : (UsValue(file.Find(0x0028, 0x0100), 16) > 8 ? "OW" : "OB");
  SetIn(file.data_set, 0x7fe0, 0x0010, vr, Filled(want + (want & 1), pattern, random));
}

std::size_t Budget(const DicomFile& file, std::size_t max_size) {
  const Element* pixels = file.Find(0x7fe0, 0x0010);
  std::size_t pixel_bytes = 0;
  if (pixels) {
    pixel_bytes = pixels->value.size();
    for (const std::string& f : pixels->fragments) pixel_bytes += f.size() + 8;
  }
  const std::size_t written = WriteDicom(file).size();
  const std::size_t rest = written > pixel_bytes ? written - pixel_bytes : 0;
  return max_size > rest + 64 ? max_size - rest - 64 : 0;
}

// ---- the mutations

void MutateInteresting(DicomFile& file, Random& random, std::size_t max_size) {
  const Interesting& entry = random.Pick(Table());
  std::string value = random.Pick(entry.values);
  std::string vr = random.OneIn(10) ? kVrs[random.Below(std::size(kVrs))] : entry.vr;
  if (entry.group == 0x0002) {
    file.Set(entry.group, entry.element, vr, value);  // routed to the meta group
    return;
  }
  std::vector<Element>& list = random.OneIn(6) ? AnyList(file, random) : file.data_set;
  SetIn(list, entry.group, entry.element, vr, value);
  const bool shapes_pixels = entry.group == 0x0028 &&
                             (entry.element == 0x0002 || entry.element == 0x0008 || entry.element == 0x0010 ||
                              entry.element == 0x0011 || entry.element == 0x0100);
  const Element* pixels = file.Find(0x7fe0, 0x0010);
  if (shapes_pixels && &list == &file.data_set && pixels && pixels->kind == Element::Kind::kValue && random.OneIn(2)) {
    FitNativePixels(file, random, Budget(file, max_size));
  }
}

// A colour model that holds together (or nearly): Photometric
// Interpretation, Samples per Pixel, Planar Configuration, palettes.
void MutateColourModel(DicomFile& file, Random& random, std::size_t max_size) {
  struct Model {
    const char* photometric;
    unsigned samples;
  };
  static const Model kModels[] = {{"MONOCHROME1", 1}, {"MONOCHROME2", 1}, {"PALETTE COLOR", 1}, {"RGB", 3},
                                  {"YBR_FULL", 3},    {"YBR_FULL_422", 3}, {"YBR_RCT", 3},     {"YBR_ICT", 3},
                                  {"YBR_PARTIAL_420", 3}, {"ARGB", 4},   {"CMYK", 4},          {"HSV", 3}};
  const Model& m = kModels[random.Below(std::size(kModels))];
  SetIn(file.data_set, 0x0028, 0x0004, "CS", Text(m.photometric));
  SetIn(file.data_set, 0x0028, 0x0002, "US", US({random.OneIn(8) ? unsigned(random.Below(6)) : m.samples}));
  if (m.samples > 1 || random.OneIn(4)) SetIn(file.data_set, 0x0028, 0x0006, "US", US({unsigned(random.Below(2))}));
  if (std::string(m.photometric) == "PALETTE COLOR") {
    const unsigned bits = random.OneIn(2) ? 8 : 16;
    const unsigned entries = random.Pick(std::vector<unsigned>{256, 4096, 0, 2, 65535});
    const std::size_t data_bytes = std::min<std::size_t>(std::size_t(entries == 0 ? 65536 : entries) * 2, 1 << 17);
    for (unsigned c = 0; c < 3; ++c) {
      SetIn(file.data_set, 0x0028, std::uint16_t(0x1101 + c), "US", US({entries, 0, bits}));
      if (!random.OneIn(8)) {
        SetIn(file.data_set, 0x0028, std::uint16_t(0x1201 + c), "OW",
              Filled(random.OneIn(6) ? data_bytes / 2 : data_bytes, "", random));
      }
    }
  }
  const Element* pixels = file.Find(0x7fe0, 0x0010);
  if ((!pixels || pixels->kind == Element::Kind::kValue) && !random.OneIn(3)) {
    FitNativePixels(file, random, Budget(file, max_size));
  }
}

// The pixel data's first frame as a J2K codestream, from the pixel module.
std::string J2kFor(const DicomFile& file, Random& random) {
  const std::uint32_t rows = std::clamp(UsValue(file.Find(0x0028, 0x0010), 4), 1u, 512u);
  const std::uint32_t columns = std::clamp(UsValue(file.Find(0x0028, 0x0011), 4), 1u, 512u);
  const int samples = int(std::clamp(UsValue(file.Find(0x0028, 0x0002), 1), 1u, 4u));
  const int bits = int(std::clamp(UsValue(file.Find(0x0028, 0x0101), 16), 1u, 38u));
  const bool is_signed = UsValue(file.Find(0x0028, 0x0103), 0) == 1;
  return SyntheticJ2k(random, columns, rows, samples, bits, is_signed);
}

void ToFragments(Element& pixels, std::string payload) {
  pixels.kind = Element::Kind::kFragments;
  pixels.vr = "OB";
  pixels.fragments = {"", std::move(payload)};
  pixels.value.clear();
  pixels.undefined_length = false;
  pixels.stated_length.reset();
}

void ToNative(Element& pixels) {
  std::string joined;
  for (std::size_t i = 1; i < pixels.fragments.size(); ++i) joined += pixels.fragments[i];
  if (joined.size() & 1) joined.push_back('\0');
  pixels.kind = Element::Kind::kValue;
  pixels.vr = "OW";
  pixels.value = std::move(joined);
  pixels.fragments.clear();
  pixels.stated_length.reset();
}

void MutateTransferSyntax(DicomFile& file, Random& random, std::size_t max_size) {
  const std::string ts = random.OneIn(3) ? random.Pick(kJ2kSyntaxes) : random.Pick(kTransferSyntaxes);
  if (!file.preamble && file.meta.empty()) file.preamble = true;
  file.Set(0x0002, 0x0010, "UI", Uid(ts));
  if (!random.OneIn(3)) file.encoding = EncodingOf(ts);
  Element* pixels = file.Find(0x7fe0, 0x0010);
  if (!pixels || random.OneIn(3)) return;
  const bool native = std::find(kNativeSyntaxes.begin(), kNativeSyntaxes.end(), ts) != kNativeSyntaxes.end();
  const bool j2k = std::find(kJ2kSyntaxes.begin(), kJ2kSyntaxes.end(), ts) != kJ2kSyntaxes.end();
  if (native && pixels->kind == Element::Kind::kFragments) {
    ToNative(*pixels);
  } else if (!native && pixels->kind == Element::Kind::kValue) {
    std::string payload = j2k ? J2kFor(file, random) : pixels->value.substr(0, max_size / 2);
    ToFragments(*file.Find(0x7fe0, 0x0010), std::move(payload));
  }
}

std::vector<std::uint32_t> InterestingLengths(std::uint32_t real) {
  return {0, 1, 2, real - 1, real + 1, real + 2, real * 2, real / 2, 0xffff, 0x10000, 0x7fffffff, 0xfffffffe,
          0xfffffff0, real + 8};
}

void MutatePixelData(DicomFile& file, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  Element* pixels = file.Find(0x7fe0, 0x0010);
  if (!pixels) {
    FitNativePixels(file, random, Budget(file, max_size));
    return;
  }
  const std::size_t budget = Budget(file, max_size);
  if (pixels->kind == Element::Kind::kValue) {
    switch (random.Below(7)) {
      case 0: FitNativePixels(file, random, budget); break;
      case 1: pixels->value.resize(random.Below(pixels->value.size() + 1)); break;
      case 2: pixels->value += pixels->value.substr(0, std::min(pixels->value.size(), budget / 2)); break;
      case 3: pixels->value = MutateString(pixels->value, mutate, std::min(budget, pixels->value.size() + 64)); break;
      case 4: ToFragments(*pixels, random.OneIn(2) ? J2kFor(file, random) : pixels->value.substr(0, budget)); break;
      case 5: pixels->vr = random.Pick(std::vector<std::string>{"OB", "OW", "UN", "OF", "OD", "SQ", "US"}); break;
      default: pixels->undefined_length = !pixels->undefined_length; break;
    }
    return;
  }
  std::vector<std::string>& f = pixels->fragments;
  if (f.empty()) f.push_back("");
  const std::size_t i = f.size() > 1 ? 1 + random.Below(f.size() - 1) : 0;
  const std::size_t room = std::min<std::size_t>(budget, f[i].size() + 4096);
  switch (random.Below(12)) {
    case 0:
    case 1:
    case 2:
    case 3:
      if (LooksLikeJ2k(f[i])) {
        MutateJ2k(f[i], random, mutate, room);
      } else {
        f[i] = MutateString(f[i], mutate, room);
      }
      break;
    case 4: {  // split one fragment in two
      const std::size_t at = random.Below(f[i].size() + 1);
      const std::string tail = f[i].substr(at);
      f[i].resize(at);
      f.insert(f.begin() + std::ptrdiff_t(i) + 1, tail);
      break;
    }
    case 5: {  // all fragments after the offset table as one
      std::string joined;
      for (std::size_t k = 1; k < f.size(); ++k) joined += f[k];
      f.resize(1);
      f.push_back(std::move(joined));
      break;
    }
    case 6:
      f.insert(f.begin() + std::ptrdiff_t(random.Below(f.size() + 1)), random.OneIn(2) ? std::string() : f[i]);
      break;
    case 7:
      if (f.size() > 1) f.erase(f.begin() + std::ptrdiff_t(i));
      break;
    case 8: {  // a basic offset table that lies, or none
      std::string table;
      const std::size_t n = random.Below(5);
      for (std::size_t k = 0; k < n; ++k) {
        Writer::U32(table, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 0x7fffffff, 0xffffffff,
                                                                  std::uint32_t(f[i].size() + 8)}),
                    false);
      }
      f[0] = table;
      break;
    }
    case 9: f[i] = J2kFor(file, random); break;
    case 10: ToNative(*pixels); break;
    default: pixels->stated_length = random.Pick(InterestingLengths(0)); break;
  }
}

void MutateTag(DicomFile& file, Random& random) {
  Element* e = AnyElement(file, random, true);
  if (!e) return;
  switch (random.Below(5)) {
    case 0: e->element = std::uint16_t(e->element + (random.OneIn(2) ? 1 : -1)); break;
    case 1: {
      const Interesting& entry = random.Pick(Table());
      e->group = entry.group;
      e->element = entry.element;
      break;
    }
    case 2:
      e->group = random.Pick(std::vector<std::uint16_t>{0x0000, 0x0002, 0x0008, 0x0009, 0x0028, 0x0029, 0x7fe0,
                                                        0xfffe, 0xffff, 0x0001, 0x6000});
      break;
    case 3: e->element = random.Pick(std::vector<std::uint16_t>{0x0000, 0x0010, 0xe000, 0xe00d, 0xe0dd, 0xffff}); break;
    default:
      e->group = std::uint16_t(random.Next());
      e->element = std::uint16_t(random.Next());
      break;
  }
  if (random.OneIn(2)) SortList(file.data_set);
}

void MutateVr(DicomFile& file, Random& random) {
  Element* e = AnyElement(file, random, true);
  if (!e) return;
  if (random.OneIn(5)) {
    e->vr = std::string{char(random.Next()), char(random.Next())};
  } else {
    e->vr = kVrs[random.Below(std::size(kVrs))];
  }
}

void MutateLength(DicomFile& file, Random& random) {
  Lists l;
  CollectLists(file.data_set, l);
  if (!l.items.empty() && random.OneIn(4)) {
    Item& item = *l.items[random.Below(l.items.size())];
    if (random.OneIn(2)) {
      item.undefined_length = !item.undefined_length;
    } else {
      item.stated_length = random.Pick(InterestingLengths(0));
    }
    return;
  }
  if (random.OneIn(10)) {
    file.meta_group_length = random.Pick(InterestingLengths(0));
    return;
  }
  Element* e = AnyElement(file, random, true);
  if (!e) return;
  switch (random.Below(4)) {
    case 0: e->undefined_length = !e->undefined_length; break;
    case 1: e->stated_length.reset(); break;
    default: {
      e->stated_length = random.Pick(InterestingLengths(std::uint32_t(e->value.size())));
      break;
    }
  }
}

Element Sequence(std::uint16_t group, std::uint16_t element, std::vector<Item> items, bool undefined) {
  Element s;
  s.group = group;
  s.element = element;
  s.vr = "SQ";
  s.kind = Element::Kind::kSequence;
  s.items = std::move(items);
  s.undefined_length = undefined;
  return s;
}

void MutateStructure(DicomFile& file, Random& random) {
  std::vector<Element>& list = AnyList(file, random);
  const std::size_t n = list.size();
  switch (random.Below(10)) {
    case 0:
      if (n) list.erase(list.begin() + std::ptrdiff_t(random.Below(n)));
      break;
    case 1:
      if (n) {
        const std::size_t i = random.Below(n);
        list.insert(list.begin() + std::ptrdiff_t(i), list[i]);
      }
      break;
    case 2:
      if (n > 1) std::swap(list[random.Below(n)], list[random.Below(n)]);
      break;
    case 3:
      if (n) {  // an element moved into an item of a new sequence
        const std::size_t i = random.Below(n);
        Item item;
        item.elements.push_back(list[i]);
        item.undefined_length = random.OneIn(2);
        list[i] = Sequence(random.OneIn(2) ? 0x0009 : list[i].group, random.OneIn(2) ? 0x1010 : list[i].element,
                           {std::move(item)}, random.OneIn(2));
      }
      break;
    case 4: {  // an icon: the pixel module and pixel data again, nested
      Item icon;
      for (const Element& e : file.data_set) {
        if (IsPixelModuleTag(e.group, e.element)) icon.elements.push_back(e);
      }
      icon.undefined_length = random.OneIn(2);
      Element seq = Sequence(0x0088, 0x0200, {std::move(icon)}, random.OneIn(2));
      SetIn(file.data_set, 0x0088, 0x0200, "SQ", "");
      *file.Find(0x0088, 0x0200) = std::move(seq);
      break;
    }
    case 5: {  // functional groups (enhanced images): pixel measures and plane orientation per frame
      Item measures, orientation, group;
      SetIn(measures.elements, 0x0018, 0x0050, "DS", Text("1"));
      SetIn(measures.elements, 0x0028, 0x0030, "DS", Text(random.OneIn(2) ? "0.5\\0.5" : "0\\0"));
      SetIn(orientation.elements, 0x0020, 0x0037, "DS", Text("1\\0\\0\\0\\1\\0"));
      group.elements.push_back(Sequence(0x0020, 0x9116, {orientation}, random.OneIn(2)));
      group.elements.push_back(Sequence(0x0028, 0x9110, {measures}, random.OneIn(2)));
      SetIn(file.data_set, 0x5200, 0x9229, "SQ", "");
      *file.Find(0x5200, 0x9229) = Sequence(0x5200, 0x9229, {group}, random.OneIn(2));
      if (random.OneIn(2)) {
        std::vector<Item> frames(std::size_t(1 + random.Below(4)));
        for (std::size_t k = 0; k < frames.size(); ++k) {
          Item position;
          SetIn(position.elements, 0x0020, 0x0032, "DS", Text("0\\0\\" + std::to_string(k)));
          frames[k].elements.push_back(Sequence(0x0020, 0x9113, {position}, false));
        }
        SetIn(file.data_set, 0x5200, 0x9230, "SQ", "");
        *file.Find(0x5200, 0x9230) = Sequence(0x5200, 0x9230, frames, random.OneIn(2));
      }
      break;
    }
    case 6: {  // a modality LUT sequence
      Item lut;
      SetIn(lut.elements, 0x0028, 0x3002, "US", random.Pick(std::vector<std::string>{US({256, 0, 16}), US({0, 0, 8}),
                                                                                       US({4096, 65535, 16})}));
      SetIn(lut.elements, 0x0028, 0x3004, "LO", Text("HU"));
      SetIn(lut.elements, 0x0028, 0x3006, random.OneIn(2) ? "US" : "OW", Filled(random.OneIn(2) ? 512 : 3, "", random));
      SetIn(file.data_set, 0x0028, 0x3000, "SQ", "");
      *file.Find(0x0028, 0x3000) = Sequence(0x0028, 0x3000, {lut}, random.OneIn(2));
      break;
    }
    case 7: {  // nesting: a sequence whose item holds a sequence ...
      Element inner = Sequence(0x0009, 0x1011, {Item{}}, true);
      for (std::size_t depth = random.Below(20); depth > 0; --depth) {
        Item item;
        item.elements.push_back(std::move(inner));
        item.undefined_length = random.OneIn(2);
        inner = Sequence(0x0009, 0x1011, {std::move(item)}, random.OneIn(2));
      }
      list.insert(list.begin() + std::ptrdiff_t(random.Below(n + 1)), std::move(inner));
      break;
    }
    case 8:
      if (n) {  // an element copied into another list
        const Element copy = list[random.Below(n)];
        std::vector<Element>& other = AnyList(file, random);
        other.insert(other.begin() + std::ptrdiff_t(random.Below(other.size() + 1)), copy);
      }
      break;
    default:
      SortList(list);
      break;
  }
}

void MutateValueBytes(DicomFile& file, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  Element* e = AnyElement(file, random, true);
  if (!e || e->kind != Element::Kind::kValue) return;
  e->value = MutateString(e->value, mutate, std::min<std::size_t>(max_size / 2, e->value.size() * 2 + 16));
}

void MutateEncoding(DicomFile& file, Random& random) {
  switch (random.Below(3)) {
    case 0: file.encoding.explicit_vr = !file.encoding.explicit_vr; break;
    case 1: file.encoding.big_endian = !file.encoding.big_endian; break;
    default: file.encoding.deflated = !file.encoding.deflated; break;
  }
}

void MutateMeta(DicomFile& file, Random& random) {
  switch (random.Below(6)) {
    case 0: file.preamble = !file.preamble; break;
    case 1: file.meta.clear(); break;
    case 2:
      if (!file.meta.empty()) file.meta.erase(file.meta.begin() + std::ptrdiff_t(random.Below(file.meta.size())));
      break;
    case 3: file.meta_group_length = std::uint32_t(random.Below(2) ? random.Next() : random.Below(256)); break;
    case 4:
      file.preamble_bytes[random.Below(file.preamble_bytes.size())] = char(random.Next());
      break;
    default:  // the meta group's own elements, as GDCM writes them
      file.Set(0x0002, 0x0001, "OB", std::string("\0\1", 2));
      file.Set(0x0002, 0x0003, "UI", Uid("1.2.826.0.1.3680043.2.1125.1.3"));
      file.Set(0x0002, 0x0012, "UI", Uid("1.2.826.0.1.3680043.2.1125"));
      file.meta_group_length.reset();
      break;
  }
}

void MutateSlices(DicomFile& file, Random& random) {
  file.preamble = true;
  file.preamble_bytes[0] = char(random.Below(3));
  if (random.OneIn(2)) {  // and the gap between them
    SetIn(file.data_set, 0x0018, 0x0050, "DS", Text(random.Pick(std::vector<std::string>{"1", "2.5", "0.1", "0"})));
  }
}

}  // namespace

// ---- DicomFile

Element* DicomFile::Find(std::uint16_t group, std::uint16_t element) {
  const std::uint32_t tag = std::uint32_t(group) << 16 | element;
  std::vector<Element>& list = group == 0x0002 ? meta : data_set;
  for (Element& e : list) {
    if (e.tag() == tag) return &e;
  }
  return nullptr;
}

const Element* DicomFile::Find(std::uint16_t group, std::uint16_t element) const {
  return const_cast<DicomFile*>(this)->Find(group, element);
}

Element& DicomFile::Set(std::uint16_t group, std::uint16_t element, const std::string& vr, const std::string& value) {
  return SetIn(group == 0x0002 ? meta : data_set, group, element, vr, value);
}

std::string Trimmed(const std::string& value) {
  std::string s = value;
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  std::size_t start = 0;
  while (start < s.size() && s[start] == ' ') ++start;
  return s.substr(start);
}

Encoding EncodingOf(const std::string& uid) {
  Encoding e;
  if (uid == "1.2.840.10008.1.2" || uid == "1.2.840.113619.5.2") e.explicit_vr = false;
  if (uid == "1.2.840.10008.1.2.2" || uid == "1.2.840.113619.5.2") e.big_endian = true;
  if (uid == "1.2.840.10008.1.2.1.99") e.deflated = true;
  return e;
}

std::string TransferSyntax(const DicomFile& file) {
  const Element* ts = file.Find(0x0002, 0x0010);
  return ts && ts->kind == Element::Kind::kValue ? Trimmed(ts->value) : "";
}

std::optional<DicomFile> ParseDicom(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  DicomFile file;
  Parser p(bytes);
  std::size_t at = 0;
  if (size >= 132 && std::memcmp(data + 128, "DICM", 4) == 0) {
    file.preamble_bytes = bytes.substr(0, 128);
    at = 132;
  } else {
    file.preamble = false;
  }
  while (at + 8 <= size && p.U16(at, false) == 0x0002) {  // the meta group ends where group 0002 does
    Element e;
    std::size_t next = at;
    if (!p.Single(next, size, true, false, e)) break;
    file.meta.push_back(std::move(e));
    at = next;
  }
  if (!file.preamble && file.meta.empty() && size < 8) return std::nullopt;
  if (const Element* length = file.Find(0x0002, 0x0000)) {
    std::uint32_t actual = 0;
    for (const Element& e : file.meta) {
      if (e.element == 0x0000) continue;
      std::string written;
      Writer::One(written, e, true, false);
      actual += std::uint32_t(written.size());
    }
    if (length->value.size() == 4) {
      const auto* v = reinterpret_cast<const std::uint8_t*>(length->value.data());
      const std::uint32_t stated = std::uint32_t(v[0]) | std::uint32_t(v[1]) << 8 | std::uint32_t(v[2]) << 16 |
                                   std::uint32_t(v[3]) << 24;
      if (stated != actual) file.meta_group_length = stated;
    }
  }

  std::string rest = bytes.substr(at);
  Encoding declared = EncodingOf(TransferSyntax(file));
  if (file.meta.empty()) declared.explicit_vr = rest.size() >= 6 && IsKnownVr(rest.data() + 4);
  if (declared.deflated) {
    if (std::optional<std::string> inflated = Inflate(rest)) {
      rest = std::move(*inflated);
    } else {
      declared.deflated = false;
    }
  }
  // The declared encoding first; another when it parses further (a mutated
  // file may say one and be another).
  Encoding candidates[] = {declared, {true, false, declared.deflated}, {false, false, declared.deflated},
                           {true, true, declared.deflated}};
  std::size_t best_at = 0;
  bool first = true;
  for (const Encoding& c : candidates) {
    Parser q(rest);
    std::vector<Element> elements;
    std::size_t pos = 0;
    q.Elements(pos, rest.size(), c.explicit_vr, c.big_endian, 0, elements);
    if (first || pos > best_at) {
      best_at = pos;
      file.encoding = c;
      file.data_set = std::move(elements);
    }
    first = false;
    if (best_at == rest.size()) break;
  }
  file.trailing = rest.substr(best_at);
  if (file.data_set.empty() && file.meta.empty()) return std::nullopt;
  return file;
}

std::string WriteDicom(const DicomFile& file) {
  std::string out;
  if (file.preamble) {
    std::string preamble = file.preamble_bytes;
    preamble.resize(128, '\0');
    out += preamble;
    out += "DICM";
  }
  std::string meta_rest;
  for (const Element& e : file.meta) {
    if (e.element != 0x0000) Writer::One(meta_rest, e, true, false);
  }
  for (const Element& e : file.meta) {
    if (e.element == 0x0000 && e.kind == Element::Kind::kValue && e.value.size() == 4) {
      Element length = e;
      length.value = UL(file.meta_group_length.value_or(std::uint32_t(meta_rest.size())));
      Writer::One(out, length, true, false);
    } else if (e.element == 0x0000) {
      Writer::One(out, e, true, false);
    }
  }
  out += meta_rest;
  std::string data;
  Writer::Elements(data, file.data_set, file.encoding.explicit_vr, file.encoding.big_endian);
  data += file.trailing;
  out += file.encoding.deflated ? Deflate(data) : data;
  return out;
}

int SliceCount(const DicomFile& file) {
  return file.preamble && !file.preamble_bytes.empty() ? 1 + std::uint8_t(file.preamble_bytes[0]) % 3 : 1;
}

std::vector<std::string> Slices(const DicomFile& file, int count) {
  std::vector<std::string> out;
  const std::vector<double> position = Numbers(file.Find(0x0020, 0x0032));
  std::vector<double> orientation = Numbers(file.Find(0x0020, 0x0037));
  double normal[3] = {0, 0, 1};
  if (orientation.size() == 6) {
    const double* r = orientation.data();
    const double* c = orientation.data() + 3;
    normal[0] = r[1] * c[2] - r[2] * c[1];
    normal[1] = r[2] * c[0] - r[0] * c[2];
    normal[2] = r[0] * c[1] - r[1] * c[0];
  }
  const std::vector<double> thickness = Numbers(file.Find(0x0018, 0x0050));
  const double gap = thickness.size() == 1 && std::isfinite(thickness[0]) && thickness[0] > 0 ? thickness[0] : 1.0;
  for (int i = 0; i < count; ++i) {
    DicomFile slice = file;
    if (i > 0 && position.size() == 3) {
      char text[128];
      std::snprintf(text, sizeof text, "%.9g\\%.9g\\%.9g", position[0] + i * gap * normal[0],
                    position[1] + i * gap * normal[1], position[2] + i * gap * normal[2]);
      Element* e = slice.Find(0x0020, 0x0032);
      e->value = Text(text);
      e->stated_length.reset();
    }
    out.push_back(WriteDicom(slice));
  }
  return out;
}

void Mutate(DicomFile& file, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  const std::size_t rounds = 1 + random.Below(3);
  for (std::size_t r = 0; r < rounds; ++r) {
    const std::size_t pick = random.Below(100);
    if (pick < 26) {
      MutateInteresting(file, random, max_size);
    } else if (pick < 34) {
      MutateColourModel(file, random, max_size);
    } else if (pick < 42) {
      MutateTransferSyntax(file, random, max_size);
    } else if (pick < 58) {
      MutatePixelData(file, random, mutate, max_size);
    } else if (pick < 63) {
      MutateTag(file, random);
    } else if (pick < 68) {
      MutateVr(file, random);
    } else if (pick < 75) {
      MutateLength(file, random);
    } else if (pick < 84) {
      MutateStructure(file, random);
    } else if (pick < 91) {
      MutateValueBytes(file, random, mutate, max_size);
    } else if (pick < 94) {
      MutateEncoding(file, random);
    } else if (pick < 97) {
      MutateMeta(file, random);
    } else {
      MutateSlices(file, random);
    }
  }
}

void CrossOver(DicomFile& into, const DicomFile& from, Random& random) {
  switch (random.Below(4)) {
    case 0:    // the pixel module and pixel data
    case 1: {  // ... with the transfer syntax and encoding
      into.data_set.erase(std::remove_if(into.data_set.begin(), into.data_set.end(),
                                         [](const Element& e) { return IsPixelModuleTag(e.group, e.element); }),
                          into.data_set.end());
      for (const Element& e : from.data_set) {
        if (IsPixelModuleTag(e.group, e.element)) into.data_set.push_back(e);
      }
      SortList(into.data_set);
      if (random.OneIn(2)) {
        if (const Element* ts = from.Find(0x0002, 0x0010)) into.Set(0x0002, 0x0010, ts->vr, ts->value);
        into.encoding = from.encoding;
      }
      break;
    }
    case 2: {  // the other's pixel data only (a J2K payload under these headers)
      const Element* pixels = from.Find(0x7fe0, 0x0010);
      if (!pixels) break;
      SetIn(into.data_set, 0x7fe0, 0x0010, "OB", "");
      *into.Find(0x7fe0, 0x0010) = *pixels;
      if (const Element* ts = from.Find(0x0002, 0x0010); ts && random.OneIn(2)) {
        into.Set(0x0002, 0x0010, ts->vr, ts->value);
        into.encoding = from.encoding;
      }
      break;
    }
    default: {  // some of its elements, anywhere
      DicomFile source = from;
      for (std::size_t k = 1 + random.Below(4); k > 0; --k) {
        const Element* e = AnyElement(source, random);
        if (!e) break;
        const Element copy = *e;
        std::vector<Element>& list = AnyList(into, random);
        list.insert(list.begin() + std::ptrdiff_t(random.Below(list.size() + 1)), copy);
      }
      break;
    }
  }
}

std::string MutateString(const std::string& bytes, const ByteMutator& mutate, std::size_t max_size) {
  if (max_size == 0) return "";
  std::string s = bytes.substr(0, max_size);
  if (s.empty()) s.push_back('\0');  // a mutator wants a byte to start from
  const std::size_t size = s.size();
  s.resize(max_size);
  const std::size_t n = mutate(reinterpret_cast<std::uint8_t*>(s.data()), size, max_size);
  s.resize(std::min(n, s.size()));
  return s;
}

std::string MutateDicomBytes(const std::uint8_t* data, std::size_t size, std::size_t max_size, Random& random,
                             const ByteMutator& mutate) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  if (!random.OneIn(10)) {
    if (std::optional<DicomFile> file = ParseDicom(data, size)) {
      for (int attempt = 0; attempt < 3; ++attempt) {
        DicomFile copy = *file;
        Mutate(copy, random, mutate, max_size);
        std::string out = WriteDicom(copy);
        if (out.size() <= max_size && out != bytes) return out;
      }
    }
  }
  return MutateString(bytes, mutate, max_size);
}

std::string CrossOverDicomBytes(const std::uint8_t* a, std::size_t a_size, const std::uint8_t* b, std::size_t b_size,
                                std::size_t max_size, Random& random) {
  std::optional<DicomFile> first = ParseDicom(a, a_size);
  std::optional<DicomFile> second = ParseDicom(b, b_size);
  if (first && second) {
    CrossOver(*first, *second, random);
    std::string out = WriteDicom(*first);
    if (out.size() <= max_size) return out;
  }
  const std::size_t head = random.Below(a_size + 1), tail = random.Below(b_size + 1);
  std::string out(reinterpret_cast<const char*>(a), head);
  out.append(reinterpret_cast<const char*>(b) + tail, b_size - tail);
  out.resize(std::min(out.size(), max_size));
  return out;
}

std::size_t MutateDicomInPlace(std::uint8_t* data, std::size_t size, std::size_t max_size, unsigned int seed,
                               const ByteMutator& mutate) {
  Random random(seed);
  const std::string out = MutateDicomBytes(data, size, max_size, random, mutate);
  std::copy(out.begin(), out.end(), data);
  return out.size();
}

std::size_t CrossOverDicomInto(const std::uint8_t* a, std::size_t a_size, const std::uint8_t* b, std::size_t b_size,
                               std::uint8_t* out, std::size_t max_size, unsigned int seed) {
  Random random(seed);
  const std::string bytes = CrossOverDicomBytes(a, a_size, b, b_size, max_size, random);
  std::copy(bytes.begin(), bytes.end(), out);
  return bytes.size();
}

ByteMutator PlainByteMutator(Random& random) {
  return [&random](std::uint8_t* data, std::size_t size, std::size_t max_size) -> std::size_t {
    static const std::uint32_t kInteresting[] = {0, 1, 2, 0x7f, 0x80, 0xff, 0x100, 0x7fff, 0x8000, 0xffff,
                                                 0x10000, 0x7fffffff, 0x80000000u, 0xfffffffeu, 0xffffffffu};
    std::size_t n = std::min(size, max_size);
    const std::size_t rounds = 1 + random.Below(4);
    for (std::size_t r = 0; r < rounds; ++r) {
      switch (n == 0 ? 5 : random.Below(7)) {
        case 0: data[random.Below(n)] ^= std::uint8_t(1u << random.Below(8)); break;
        case 1: data[random.Below(n)] = std::uint8_t(random.Next()); break;
        case 2: {
          const std::uint32_t v = kInteresting[random.Below(std::size(kInteresting))];
          const std::size_t width = random.Pick(std::vector<std::size_t>{1, 2, 4});
          if (n < width) break;
          const std::size_t at = random.Below(n - width + 1);
          const bool be = random.OneIn(2);
          for (std::size_t k = 0; k < width; ++k) {
            data[at + k] = std::uint8_t(v >> (8 * (be ? width - 1 - k : k)));
          }
          break;
        }
        case 3: {  // erase a run
          const std::size_t at = random.Below(n);
          const std::size_t len = std::min(n - at, 1 + random.Below(std::min<std::size_t>(n, 64)));
          std::memmove(data + at, data + at + len, n - at - len);
          n -= len;
          break;
        }
        case 4: {  // copy a run over another place
          const std::size_t from = random.Below(n), to = random.Below(n);
          const std::size_t len = std::min({n - from, n - to, 1 + random.Below(64)});
          std::memmove(data + to, data + from, len);
          break;
        }
        case 5: {  // insert random bytes or a repeated byte
          if (n >= max_size) break;
          const std::size_t at = random.Below(n + 1);
          const std::size_t len = std::min(max_size - n, 1 + random.Below(32));
          std::memmove(data + at + len, data + at, n - at);
          const bool repeat = random.OneIn(2);
          const std::uint8_t b = std::uint8_t(random.Next());
          for (std::size_t k = 0; k < len; ++k) data[at + k] = repeat ? b : std::uint8_t(random.Next());
          n += len;
          break;
        }
        default: {  // add or subtract a little
          const std::size_t at = random.Below(n);
          data[at] = std::uint8_t(data[at] + int(random.Below(33)) - 16);
          break;
        }
      }
    }
    return n;
  };
}

}  // namespace cinevol::fuzz
