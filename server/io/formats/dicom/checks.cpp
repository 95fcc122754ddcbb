// The walk over a DICOM file's elements that GDCM's parser does not survive.
#include "io/formats/dicom/checks.h"

#include <gdcmDicts.h>
#include <gdcmGlobal.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "io/file_checks.h"

namespace fs = std::filesystem;

namespace cinevol::formats::dicom {
namespace {

// GDCM trusts a DICOM file's structure: it asserts (aborting the process;
// Debian keeps its asserts) on a file meta element whose VR it does not know,
// and allocates whatever length an element declares (4 GiB in a 1 KiB file).
// So a file's elements are walked here first, headers only, nested sequences
// included: every VR known, every defined length inside the file. A file
// that fails is not handed to GDCM (it counts as not DICOM).
class DicomWalk {
 public:
  explicit DicomWalk(std::FILE* f, std::int64_t size) : f_(f), size_(size) {}

  bool File() {
    std::uint8_t magic[4];
    std::int64_t at = 0;
    if (size_ >= 132 && Read(128, magic, 4) && std::memcmp(magic, "DICM", 4) == 0) {
      at = 132;
      // The file meta group: explicit VR little endian, group 0002.
      std::uint8_t h[4];
      while (at + 8 <= size_ && Read(at, h, 2) && U16(h) == 0x0002) {
        if (!Element(at, size_, true, 0, true)) return false;
      }
      // GDCM asserts reading a meta group that the file ends in (found by
      // fuzz_volume); a file without a data set holds no image anyway.
      if (at == size_) return false;
      // A data set in big-endian or deflated encoding is not walked here (the
      // walk reads little-endian bytes as they stand): GDCM reads it in the
      // cage, where its failure is the load's alone.
      if (transfer_syntax_ == "1.2.840.10008.1.2.2" || transfer_syntax_ == "1.2.840.10008.1.2.1.99") return true;
    }
    if (at == size_) return true;
    // The data set: explicit VR when the bytes after the first tag read as a
    // VR (GDCM guesses the same way when the meta group is absent or wrong).
    std::uint8_t h[6];
    const bool explicit_vr = at + 6 <= size_ && Read(at, h, 6) && IsVr(h + 4);
    while (at < size_) {
      if (!Element(at, size_, explicit_vr, 0, false)) return false;
    }
    return PixelModuleIsSound();
  }

 private:
  static unsigned U16(const std::uint8_t* b) { return unsigned(b[0]) | unsigned(b[1]) << 8; }
  static std::uint32_t U32(const std::uint8_t* b) { return std::uint32_t(U16(b)) | std::uint32_t(U16(b + 2)) << 16; }
  static bool IsVr(const std::uint8_t* v) {
    static const char* const kVrs[] = {"AE", "AS", "AT", "CS", "DA", "DS", "DT", "FD", "FL", "IS", "LO",
                                       "LT", "OB", "OD", "OF", "OL", "OW", "PN", "SH", "SL", "SQ", "SS",
                                       "ST", "TM", "UC", "UI", "UL", "UN", "UR", "US", "UT"};
    return std::any_of(std::begin(kVrs), std::end(kVrs), [&](const char* k) { return std::memcmp(k, v, 2) == 0; });
  }
  static bool IsLongVr(const std::uint8_t* v) {
    static const char* const kLong[] = {"OB", "OD", "OF", "OL", "OW", "SQ", "UC", "UN", "UR", "UT"};
    return std::any_of(std::begin(kLong), std::end(kLong), [&](const char* k) { return std::memcmp(k, v, 2) == 0; });
  }
  bool Read(std::int64_t at, std::uint8_t* out, std::size_t n) {
    return at >= 0 && at + std::int64_t(n) <= size_ && std::fseek(f_, long(at), SEEK_SET) == 0 &&
           std::fread(out, 1, n, f_) == n;
  }

  // One element at `at` (advanced past it) that must end by `end`.
  bool Element(std::int64_t& at, std::int64_t end, bool explicit_vr, int depth, bool meta) {
    if (depth > 16 || ++elements_ > 200000) return false;
    std::uint8_t h[12];
    if (at + 8 > end || !Read(at, h, 8)) return false;
    const unsigned group = U16(h), element = U16(h + 2);
    std::uint32_t length;
    bool sequence = false;
    if (group == 0xfffe) {  // item or delimiter: tag and a 4-byte length, never a VR
      length = U32(h + 4);
      at += 8;
      if (element == 0xe00d || element == 0xe0dd) return length == 0;
      if (element != 0xe000) return false;
      if (length == 0xffffffffu) return Items(at, end, explicit_vr, depth + 1, 0xe00d);
      if (length > std::uint64_t(end - at)) return false;
      const std::int64_t item_end = at + length;
      while (at < item_end) {
        if (!Element(at, item_end, explicit_vr, depth + 1, false)) return false;
      }
      return true;
    }
    if (meta && group != 0x0002) return false;
    if (explicit_vr) {
      if (!IsVr(h + 4)) return false;
      sequence = std::memcmp(h + 4, "SQ", 2) == 0;
      if (IsLongVr(h + 4)) {
        if (at + 12 > end || !Read(at + 8, h + 8, 4)) return false;
        length = U32(h + 8);
        at += 12;
      } else {
        length = U16(h + 6);
        at += 8;
      }
    } else {
      length = U32(h + 4);
      at += 8;
      sequence = group % 2 == 0 && DictionaryVr(group, element) == gdcm::VR::SQ;  // as GDCM reads it
    }
    // GDCM asserts on a sequence or an undefined length in the file meta
    // group (found by fuzz_volume); the standard allows neither there.
    if (meta && (sequence || length == 0xffffffffu)) return false;
    const bool pixel_data = group == 0x7fe0 && element == 0x0010;
    const bool un = explicit_vr && std::memcmp(h + 4, "UN", 2) == 0;
    // GDCM asserts on Pixel Data of another VR, and on an explicit VR that
    // its dictionary does not allow for a public element (Rows as OW).
    if (explicit_vr && pixel_data && std::memcmp(h + 4, "OB", 2) != 0 && std::memcmp(h + 4, "OW", 2) != 0 && !un) {
      return false;
    }
    if (explicit_vr && !meta && !un && !VrFitsDictionary(group, element, h + 4)) return false;
    if (length == 0xffffffffu) {
      // Undefined lengths: encapsulated Pixel Data (fragments, each an item
      // of plain bytes), or a sequence; GDCM asserts on any other, and on
      // nested UN sequences it repairs otherwise than this walk reads them.
      if (pixel_data) return Fragments(at, end, depth == 0);
      if (explicit_vr && !sequence && !(un && depth == 0)) return false;
      return Items(at, end, explicit_vr && !un, depth + 1, 0xe0dd);  // implicit VR inside an undefined-length UN
    }
    if (length > std::uint64_t(end - at)) return false;
    if (depth > 0 && length % 2 != 0) return false;  // the standard's even lengths; GDCM asserts in items
    if (sequence) {
      // A sequence of defined length is walked like one of undefined length:
      // GDCM asserts on an odd length inside it when it parses its items (an
      // enhanced multi-frame file's functional groups, found by fuzz_dicom's seed).
      const std::int64_t sequence_end = at + length;
      while (at < sequence_end) {
        if (!Element(at, sequence_end, explicit_vr, depth + 1, false)) return false;
      }
      return true;
    }
    if (depth == 0) Remember(group, element, at, length, pixel_data);
    if (meta && element == 0x0010 && length <= 64) {  // (0002,0010) Transfer Syntax UID
      transfer_syntax_.assign(length, '\0');
      if (!Read(at, reinterpret_cast<std::uint8_t*>(transfer_syntax_.data()), length)) return false;
      while (!transfer_syntax_.empty() && (transfer_syntax_.back() == '\0' || transfer_syntax_.back() == ' ')) {
        transfer_syntax_.pop_back();
      }
    }
    // GDCM asserts that Samples per Pixel is 1, 3 or 4 (an abort, found by
    // fuzz_volume), in any image, icons included.
    if (group == 0x0028 && element == 0x0002 && !meta) {
      std::uint8_t v[2];
      if (length < 2 || !Read(at, v, 2) || (U16(v) != 1 && U16(v) != 3 && U16(v) != 4)) return false;
    }
    at += length;
    return true;
  }

  // Items of plain bytes up to the sequence delimiter, which is consumed: the
  // basic offset table, then at least one fragment (GDCM asserts on none).
  // The top-level image's first fragment is remembered, for its codec's check.
  bool Fragments(std::int64_t& at, std::int64_t end, bool top_level) {
    for (int items = 0; at + 8 <= end; ++items) {
      std::uint8_t h[8];
      if (!Read(at, h, 8) || U16(h) != 0xfffe || ++elements_ > 200000) return false;
      at += 8;
      if (U16(h + 2) == 0xe0dd) return items >= 2;
      const std::uint32_t length = U32(h + 4);
      if (U16(h + 2) != 0xe000 || length > std::uint64_t(end - at)) return false;
      if (top_level && items == 1) {
        pixels_.first_fragment = at;
        pixels_.fragment_length = length;
      }
      at += length;
    }
    return false;
  }

  // A public element's VR in GDCM's dictionary (INVALID where it has none).
  static gdcm::VR DictionaryVr(unsigned group, unsigned element) {
    return gdcm::Global::GetInstance()
        .GetDicts()
        .GetPublicDict()
        .GetDictEntry(gdcm::Tag(std::uint16_t(group), std::uint16_t(element)))
        .GetVR();
  }

  // What GDCM's typed reads take from the dictionary: a public element's
  // explicit VR must be one it accepts for the tag.
  static bool VrFitsDictionary(unsigned group, unsigned element, const std::uint8_t* vr) {
    if (group % 2 != 0) return true;  // private: no dictionary entry
    const gdcm::VR expected = DictionaryVr(group, element);
    if (expected == gdcm::VR::INVALID) return true;  // not in the dictionary
    const char name[3] = {char(vr[0]), char(vr[1]), 0};
    return expected.Compatible(gdcm::VR(gdcm::VR::GetVRType(name)));
  }

  // The top-level image's pixel module, as the walk passes it.
  struct PixelModule {
    int rows = -1, columns = -1, samples = -1, bits_allocated = -1, bits_stored = -1;
    bool pixel_data = false;
    std::int64_t first_fragment = -1;  // encapsulated: the first fragment after the offset table
    std::uint32_t fragment_length = 0;
  };

  void Remember(unsigned group, unsigned element, std::int64_t at, std::uint32_t length, bool pixel_data) {
    if (pixel_data) pixels_.pixel_data = true;
    if (group != 0x0028 || length < 2) return;
    std::uint8_t v[2];
    if (!Read(at, v, 2)) return;
    const int value = int(U16(v));
    switch (element) {
      case 0x0002: pixels_.samples = value; break;
      case 0x0010: pixels_.rows = value; break;
      case 0x0011: pixels_.columns = value; break;
      case 0x0100: pixels_.bits_allocated = value; break;
      case 0x0101: pixels_.bits_stored = value; break;
      default: break;
    }
  }

  // GDCM asserts on a Bits Allocated it has no codec for (12), on Bits
  // Stored above Bits Allocated or missing, and decodes a JPEG 2000 or RLE
  // stream that disagrees with the header past its buffers. So the image's
  // pixel module must hold together, and a compressed image's first fragment
  // must describe the image the header does.
  bool PixelModuleIsSound() {
    const PixelModule& p = pixels_;
    if (!p.pixel_data) return true;
    const bool bits_known = p.bits_allocated == 1 || p.bits_allocated == 8 || p.bits_allocated == 16 ||
                            p.bits_allocated == 32 || p.bits_allocated == 64;
    if (!bits_known || p.bits_stored < 1 || p.bits_stored > p.bits_allocated) return false;
    if (p.first_fragment < 0) return true;  // not encapsulated
    const bool j2k = transfer_syntax_.rfind("1.2.840.10008.1.2.4.9", 0) == 0;
    const bool rle = transfer_syntax_ == "1.2.840.10008.1.2.5";
    if (j2k) return J2kFitsHeader();
    if (rle) return RleFitsHeader();
    return true;
  }

  static std::uint32_t Be32(const std::uint8_t* b) {
    return std::uint32_t(b[0]) << 24 | std::uint32_t(b[1]) << 16 | std::uint32_t(b[2]) << 8 | b[3];
  }

  // A JPEG 2000 code stream (or a JP2 file's 'jp2c' box) whose SIZ marker
  // gives the header's columns, rows and samples.
  bool J2kFitsHeader() {
    const std::size_t n = std::min<std::size_t>(pixels_.fragment_length, 4096);
    std::vector<std::uint8_t> b(n);
    if (n < 42 || !Read(pixels_.first_fragment, b.data(), n)) return false;
    std::size_t c = 0;  // where the code stream starts
    if (b[0] != 0xff || b[1] != 0x4f) {
      const auto box = std::search(b.begin(), b.end(), std::begin("jp2c"), std::begin("jp2c") + 4);
      if (box == b.end()) return false;
      c = std::size_t(box - b.begin()) + 4;
    }
    if (c + 42 > n || b[c] != 0xff || b[c + 1] != 0x4f || b[c + 2] != 0xff || b[c + 3] != 0x51) return false;
    const std::uint8_t* siz = b.data() + c + 4;  // Lsiz, Rsiz, Xsiz, Ysiz, XOsiz, YOsiz, ..., Csiz
    const std::int64_t width = std::int64_t(Be32(siz + 4)) - Be32(siz + 12);
    const std::int64_t height = std::int64_t(Be32(siz + 8)) - Be32(siz + 16);
    const int components = int(siz[36]) << 8 | siz[37];
    return width == pixels_.columns && height == pixels_.rows && components == pixels_.samples;
  }

  // An RLE fragment's header: 1 to 15 segments, one per byte of each sample,
  // their offsets rising from 64 and inside the fragment.
  bool RleFitsHeader() {
    std::uint8_t header[64];
    if (pixels_.fragment_length < 64 || !Read(pixels_.first_fragment, header, 64)) return false;
    const std::uint32_t segments = U32(header);
    if (segments < 1 || segments > 15 || pixels_.bits_allocated < 8 ||
        segments != std::uint32_t(pixels_.samples) * std::uint32_t(pixels_.bits_allocated / 8)) {
      return false;
    }
    std::uint32_t previous = 63;
    for (std::uint32_t i = 0; i < segments; ++i) {
      const std::uint32_t offset = U32(header + 4 + 4 * i);
      if (offset <= previous || offset >= pixels_.fragment_length) return false;
      previous = offset;
    }
    return true;
  }

  // Elements up to the delimiter (FFFE,`delimiter`), which is consumed.
  bool Items(std::int64_t& at, std::int64_t end, bool explicit_vr, int depth, unsigned delimiter) {
    while (at + 8 <= end) {
      std::uint8_t h[4];
      if (!Read(at, h, 4)) return false;
      if (U16(h) == 0xfffe && U16(h + 2) == delimiter) {
        at += 8;
        return true;
      }
      if (!Element(at, end, explicit_vr, depth, false)) return false;
    }
    return false;
  }

  std::FILE* f_;
  std::int64_t size_;
  int elements_ = 0;
  std::string transfer_syntax_;  // from the file meta group
  PixelModule pixels_;
};

}  // namespace

bool StructureIsSound(const fs::path& path) {
  const file_checks::FileStream f = file_checks::OpenRegularStream(path);
  if (!f) return false;
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return !ec && DicomWalk(f.get(), std::int64_t(size)).File();
}

}  // namespace cinevol::formats::dicom
