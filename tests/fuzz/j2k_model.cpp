// JPEG 2000 codestreams and JP2 files: parsed into marker segments (or
// boxes), mutated field by field, written back.
#include "j2k_model.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <optional>
#include <vector>

namespace cinevol::fuzz {
namespace {

constexpr std::uint16_t kSoc = 0xff4f, kSiz = 0xff51, kCod = 0xff52, kCoc = 0xff53, kQcd = 0xff5c, kQcc = 0xff5d,
                        kRgn = 0xff5e, kPoc = 0xff5f, kTlm = 0xff55, kPlm = 0xff57, kPpm = 0xff60, kCrg = 0xff63,
                        kCom = 0xff64, kSot = 0xff90, kSod = 0xff93, kEoc = 0xffd9;
const char kJp2Signature[] = "\0\0\0\x0cjP  \r\n\x87\n";

std::uint32_t Be(const std::string& s, std::size_t at, int width) {
  std::uint32_t v = 0;
  for (int k = 0; k < width; ++k) v = v << 8 | std::uint8_t(s[at + std::size_t(k)]);
  return v;
}
void PutBe(std::string& s, std::size_t at, int width, std::uint32_t v) {
  for (int k = width - 1; k >= 0; --k, v >>= 8) s[at + std::size_t(k)] = char(v & 0xff);
}
void AppendBe(std::string& s, int width, std::uint32_t v) {
  s.resize(s.size() + std::size_t(width));
  PutBe(s, s.size() - std::size_t(width), width, v);
}

struct Segment {
  std::uint16_t marker = 0;
  std::string body;                            // after the length
  std::optional<std::uint16_t> stated_length;  // a length that lies
};

// SOC, the main header's segments, then everything from the first tile part.
struct Codestream {
  std::vector<Segment> header;
  std::string tiles;
};

std::optional<Codestream> ParseCodestream(const std::string& s) {
  if (s.size() < 2 || Be(s, 0, 2) != kSoc) return std::nullopt;
  Codestream c;
  std::size_t at = 2;
  while (at + 2 <= s.size()) {
    const std::uint16_t marker = std::uint16_t(Be(s, at, 2));
    if (marker == kSot || marker == kEoc || c.header.size() > 256) break;
    if ((marker >> 8) != 0xff || at + 4 > s.size()) return std::nullopt;
    const std::uint32_t length = Be(s, at + 2, 2);
    if (length < 2 || at + 2 + length > s.size()) return std::nullopt;
    c.header.push_back({marker, s.substr(at + 4, length - 2), std::nullopt});
    at += 2 + length;
  }
  c.tiles = s.substr(std::min(at, s.size()));
  return c;
}

std::string WriteCodestream(const Codestream& c) {
  std::string out;
  AppendBe(out, 2, kSoc);
  for (const Segment& seg : c.header) {
    AppendBe(out, 2, seg.marker);
    AppendBe(out, 2, seg.stated_length.value_or(std::uint16_t(std::min<std::size_t>(seg.body.size() + 2, 0xffff))));
    out += seg.body;
  }
  return out + c.tiles;
}

Segment* FindSegment(Codestream& c, std::uint16_t marker) {
  for (Segment& s : c.header) {
    if (s.marker == marker) return &s;
  }
  return nullptr;
}

std::uint32_t Interesting32(Random& random, std::uint32_t current) {
  static const std::uint32_t kValues[] = {0, 1, 2, 3, 4, 7, 8, 15, 16, 17, 255, 256, 65535, 65536, 0x7fffffff,
                                          0xffffffffu};
  switch (random.Below(4)) {
    case 0: return current + 1;
    case 1: return current - 1;
    case 2: return random.OneIn(2) ? current * 2 : current / 2;
    default: return kValues[random.Below(std::size(kValues))];
  }
}

// A field of a segment's body, if the body is long enough for it.
void SetField(Segment& seg, std::size_t at, int width, std::uint32_t value) {
  if (at + std::size_t(width) <= seg.body.size()) PutBe(seg.body, at, width, value);
}
std::uint32_t Field(const Segment& seg, std::size_t at, int width) {
  return at + std::size_t(width) <= seg.body.size() ? Be(seg.body, at, width) : 0;
}

// SIZ: Rsiz(2) Xsiz Ysiz XOsiz YOsiz XTsiz YTsiz XTOsiz YTOsiz (4 each) Csiz(2),
// then Ssiz XRsiz YRsiz (1 each) per component.
void MutateSiz(Segment& siz, Random& random) {
  const std::size_t pick = random.Below(6);
  if (pick <= 1) {
    const std::size_t at = 2 + 4 * random.Below(8);
    SetField(siz, at, 4, Interesting32(random, Field(siz, at, 4)));
  } else if (pick == 2) {
    const std::uint32_t c = random.Pick(std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 16384, 0xffff});
    SetField(siz, 34, 2, c);
    if (random.OneIn(2) && c <= 16) {  // and the component list to match
      siz.body.resize(std::min<std::size_t>(siz.body.size(), 36));
      for (std::uint32_t k = 0; k < c; ++k) siz.body += std::string{char(0x07), 1, 1};
    }
  } else if (pick == 3) {
    const std::size_t comps = siz.body.size() > 36 ? (siz.body.size() - 36) / 3 : 0;
    if (comps) {
      SetField(
          siz, 36 + 3 * random.Below(comps), 1,
          random.Pick(std::vector<std::uint32_t>{0x00, 0x07, 0x0b, 0x0f, 0x8f, 0x87, 0x1f, 0x25, 0x26, 0x7f, 0xff}));
    }
  } else if (pick == 4) {
    const std::size_t comps = siz.body.size() > 36 ? (siz.body.size() - 36) / 3 : 0;
    if (comps)
      SetField(siz, 36 + 3 * random.Below(comps) + 1 + random.Below(2), 1,
               std::uint32_t(random.Pick(std::vector<int>{0, 1, 2, 3, 4, 255})));
  } else {
    SetField(siz, 0, 2, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 0x4000, 0x8000, 0xffff}));
  }
}

// COD: Scod, progression order, layers(2), MCT, decomposition levels,
// code-block width and height, code-block style, transform, precincts.
void MutateCod(Segment& cod, Random& random) {
  switch (random.Below(8)) {
    case 0: SetField(cod, 0, 1, std::uint32_t(random.Below(8))); break;
    case 1: SetField(cod, 1, 1, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 255})); break;
    case 2: SetField(cod, 2, 2, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 65535})); break;
    case 3: SetField(cod, 4, 1, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 255})); break;
    case 4: SetField(cod, 5, 1, random.Pick(std::vector<std::uint32_t>{0, 1, 5, 10, 32, 33, 255})); break;
    case 5: SetField(cod, 6 + random.Below(2), 1, random.Pick(std::vector<std::uint32_t>{0, 2, 4, 8, 9, 255})); break;
    case 6: SetField(cod, 8, 1, random.Pick(std::vector<std::uint32_t>{0, 1, 0x08, 0x20, 0x3f, 0x40, 0xff})); break;
    default: SetField(cod, 9, 1, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 255})); break;
  }
}

// A segment the main header may hold, with a plausible or odd body.
Segment NewSegment(Random& random) {
  Segment s;
  s.marker = random.Pick(std::vector<std::uint16_t>{kCoc, kQcc, kRgn, kPoc, kTlm, kPlm, kPpm, kCrg, kCom, kCod, kQcd,
                                                    kSiz, 0xff30, 0xff70});
  const std::size_t n = random.Below(24);
  for (std::size_t k = 0; k < n; ++k) s.body.push_back(char(random.OneIn(3) ? 0 : random.Next()));
  return s;
}

void MutateTiles(Codestream& c, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  std::string& t = c.tiles;
  // SOT: Isot(2) Psot(4) TPsot(1) TNsot(1) after its marker and length.
  const bool sot = t.size() >= 12 && Be(t, 0, 2) == kSot;
  switch (random.Below(7)) {
    case 0:
      if (sot) PutBe(t, 6, 4, random.OneIn(3) ? std::uint32_t(t.size()) : Interesting32(random, Be(t, 6, 4)));
      break;
    case 1:
      if (sot) PutBe(t, 4, 2, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 0xffff}));
      break;
    case 2:
      if (sot) PutBe(t, 10 + random.Below(2), 1, random.Pick(std::vector<std::uint32_t>{0, 1, 2, 255}));
      break;
    case 3: t.resize(random.Below(t.size() + 1)); break;  // truncated
    case 4:                                                 // no end of codestream, or two
      if (t.size() >= 2 && Be(t, t.size() - 2, 2) == kEoc) {
        t.resize(t.size() - 2);
      } else {
        AppendBe(t, 2, kEoc);
      }
      break;
    case 5:
      if (sot && t.size() * 2 < max_size) t += t;  // the tile part again
      break;
    default: {  // the coded data, after SOD
      const std::size_t sod = t.find("\xff\x93");
      const std::size_t from = sod == std::string::npos ? 0 : sod + 2;
      if (from >= t.size()) break;
      t = t.substr(0, from) + MutateString(t.substr(from), mutate, std::min(max_size, t.size() - from + 64));
      break;
    }
  }
}

void MutateCodestream(Codestream& c, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  switch (random.Below(10)) {
    case 0:
    case 1:
      if (Segment* siz = FindSegment(c, kSiz)) MutateSiz(*siz, random);
      break;
    case 2:
    case 3:
      if (Segment* cod = FindSegment(c, kCod)) MutateCod(*cod, random);
      break;
    case 4:
      if (Segment* qcd = FindSegment(c, kQcd)) {
        if (random.OneIn(2)) {
          SetField(*qcd, 0, 1, random.Pick(std::vector<std::uint32_t>{0x00, 0x01, 0x02, 0x20, 0x22, 0x40, 0x42, 0xff}));
        } else {
          qcd->body.resize(random.Below(qcd->body.size() * 2 + 2), char(0x48));
        }
      }
      break;
    case 5: {  // segments removed, repeated, reordered or added
      std::vector<Segment>& h = c.header;
      const std::size_t n = h.size();
      const std::size_t op = random.Below(4);
      if (op == 0 && n) h.erase(h.begin() + std::ptrdiff_t(random.Below(n)));
      if (op == 1 && n) h.insert(h.begin() + std::ptrdiff_t(random.Below(n + 1)), h[random.Below(n)]);
      if (op == 2 && n > 1) std::swap(h[random.Below(n)], h[random.Below(n)]);
      if (op == 3) h.insert(h.begin() + std::ptrdiff_t(random.Below(n + 1)), NewSegment(random));
      break;
    }
    case 6:
      if (!c.header.empty()) {
        Segment& s = c.header[random.Below(c.header.size())];
        s.stated_length = std::uint16_t(random.Pick(std::vector<std::uint32_t>{
            0, 1, 2, 3, std::uint32_t(s.body.size() + 3), std::uint32_t(s.body.size() + 1), 0xffff}));
      }
      break;
    default: MutateTiles(c, random, mutate, max_size); break;
  }
}

// ---- JP2

bool IsJp2(const std::string& s) { return s.size() >= 12 && std::memcmp(s.data(), kJp2Signature, 12) == 0; }

// The jp2c box's content: where it starts and ends (the file's end when the box says 0).
bool FindCodestreamBox(const std::string& s, std::size_t& begin, std::size_t& end) {
  std::size_t at = 0;
  for (int boxes = 0; at + 8 <= s.size() && boxes < 64; ++boxes) {
    std::uint64_t length = Be(s, at, 4);
    std::size_t header = 8;
    if (length == 1) {
      if (at + 16 > s.size()) return false;
      length = std::uint64_t(Be(s, at + 8, 4)) << 32 | Be(s, at + 12, 4);
      header = 16;
    } else if (length == 0) {
      length = s.size() - at;
    }
    if (length < header || length > s.size() - at) return false;
    if (s.compare(at + 4, 4, "jp2c") == 0) {
      begin = at + header;
      end = at + std::size_t(length);
      return true;
    }
    at += std::size_t(length);
  }
  return false;
}

std::string Box(const char* type, const std::string& content) {
  std::string out;
  AppendBe(out, 4, std::uint32_t(content.size() + 8));
  out.append(type, 4);
  return out + content;
}

// A JP2 file around `codestream`, its header boxes from the codestream's SIZ.
std::string WrapJp2(const std::string& codestream, Random& random) {
  std::uint32_t width = 1, height = 1, components = 1, depth = 7;
  if (std::optional<Codestream> c = ParseCodestream(codestream)) {
    if (Segment* siz = FindSegment(*c, kSiz)) {
      width = Field(*siz, 2, 4);
      height = Field(*siz, 6, 4);
      components = Field(*siz, 34, 2);
      depth = Field(*siz, 36, 1);
    }
  }
  std::string ihdr;
  AppendBe(ihdr, 4, height);
  AppendBe(ihdr, 4, width);
  AppendBe(ihdr, 2, components);
  ihdr += std::string{char(depth), 7, 0, 0};  // BPC, C (wavelet), UnkC, IPR
  std::string colr{1, 0, 0};                  // enumerated colour space
  AppendBe(colr, 4, random.Pick(std::vector<std::uint32_t>{17, 16, 18, 0, 12, 20, 24}));  // grey, sRGB, sYCC, ...
  std::string ftyp = "jp2 ";
  AppendBe(ftyp, 4, 0);
  ftyp += "jp2 ";
  return std::string(kJp2Signature, 12) + Box("ftyp", ftyp) + Box("jp2h", Box("ihdr", ihdr) + Box("colr", colr)) +
         Box("jp2c", codestream);
}

// A field of a JP2 header box, found by its type.
void MutateJp2Header(std::string& s, Random& random) {
  const bool ihdr = random.OneIn(2);
  const std::size_t box = s.find(ihdr ? "ihdr" : "colr");
  if (box == std::string::npos) return;
  const std::size_t at = box + 4;
  if (ihdr) {  // HEIGHT(4) WIDTH(4) NC(2) BPC(1) C(1) UnkC(1) IPR(1)
    const std::size_t field = random.Below(6);
    static const std::size_t kOffset[] = {0, 4, 8, 10, 11, 12};
    static const int kWidth[] = {4, 4, 2, 1, 1, 1};
    if (at + kOffset[field] + std::size_t(kWidth[field]) <= s.size()) {
      PutBe(s, at + kOffset[field], kWidth[field], Interesting32(random, Be(s, at + kOffset[field], kWidth[field])));
    }
  } else if (at + 7 <= s.size()) {  // METH(1) PREC(1) APPROX(1) EnumCS(4)
    if (random.OneIn(3)) {
      s[at] = char(random.Pick(std::vector<int>{0, 1, 2, 3, 255}));
    } else {
      PutBe(s, at + 3, 4, random.Pick(std::vector<std::uint32_t>{0, 1, 12, 16, 17, 18, 20, 21, 22, 24, 0xffffffffu}));
    }
  }
}

}  // namespace

bool LooksLikeJ2k(const std::string& payload) {
  return IsJp2(payload) || (payload.size() >= 2 && Be(payload, 0, 2) == kSoc);
}

void MutateJ2k(std::string& payload, Random& random, const ByteMutator& mutate, std::size_t max_size) {
  if (IsJp2(payload)) {
    std::size_t begin = 0, end = 0;
    if (!FindCodestreamBox(payload, begin, end) || random.OneIn(4)) {
      if (random.OneIn(4) && FindCodestreamBox(payload, begin, end)) {
        payload = payload.substr(begin, end - begin);  // the bare codestream
      } else {
        MutateJp2Header(payload, random);
      }
      return;
    }
    std::string codestream = payload.substr(begin, end - begin);
    MutateJ2k(codestream, random, mutate, max_size);
    // The box keeps its old length one time in four: a box that lies.
    std::string out = payload.substr(0, begin) + codestream + payload.substr(end);
    if (!random.OneIn(4) && begin >= 8) PutBe(out, begin - 8, 4, std::uint32_t(codestream.size() + 8));
    payload = std::move(out);
    return;
  }
  std::optional<Codestream> c = ParseCodestream(payload);
  if (!c) {
    payload = MutateString(payload, mutate, max_size);
    return;
  }
  if (random.OneIn(16)) {
    payload = WrapJp2(payload, random);
    return;
  }
  MutateCodestream(*c, random, mutate, max_size);
  payload = WriteCodestream(*c);
  if (payload.size() > max_size) payload.resize(max_size);
}

std::string SyntheticJ2k(Random& random, std::uint32_t width, std::uint32_t height, int components, int bits,
                         bool is_signed) {
  Codestream c;
  Segment siz{kSiz, {}, std::nullopt};
  AppendBe(siz.body, 2, 0);
  for (std::uint32_t v : {width, height, 0u, 0u, width, height, 0u, 0u}) AppendBe(siz.body, 4, v);
  AppendBe(siz.body, 2, std::uint32_t(components));
  for (int k = 0; k < components; ++k) {
    siz.body += std::string{char((bits - 1) | (is_signed ? 0x80 : 0)), 1, 1};
  }
  int levels = 0;
  while (levels < 5 && (std::min(width, height) >> (levels + 1)) > 0) ++levels;
  Segment cod{kCod, {}, std::nullopt};
  cod.body = std::string{0, 0, 0, 1, char(components >= 3 ? 1 : 0), char(levels), 4, 4, 0, 1};
  Segment qcd{kQcd, {}, std::nullopt};
  qcd.body.push_back(0x40);  // no quantization, two guard bits
  for (int band = 0; band < 1 + 3 * levels; ++band) qcd.body.push_back(char((bits + 2) << 3));
  c.header = {siz, cod, qcd};
  std::string data;
  for (std::size_t n = 16 + random.Below(240); n > 0; --n) {
    const char b = char(random.Next());
    data.push_back(b == char(0xff) ? char(0x7f) : b);  // no markers inside
  }
  std::string& t = c.tiles;
  AppendBe(t, 2, kSot);
  AppendBe(t, 2, 10);
  AppendBe(t, 2, 0);                                  // Isot
  AppendBe(t, 4, std::uint32_t(12 + 2 + data.size()));  // Psot: SOT, SOD and the data
  t += std::string{0, 1};                             // TPsot, TNsot
  AppendBe(t, 2, kSod);
  t += data;
  AppendBe(t, 2, kEoc);
  return WriteCodestream(c);
}

}  // namespace cinevol::fuzz
