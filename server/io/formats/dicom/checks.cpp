// The walk over a DICOM file's elements that GDCM's parser does not survive.
#include "io/formats/dicom/checks.h"

#include <fmt/format.h>
#include <gdcmDicts.h>
#include <gdcmGlobal.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/log_safe.h"
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

  // Empty where the file is sound; else what is wrong with it.
  std::string Problem() {
    if (File()) return {};
    const std::string why = problem_.empty() ? std::string("its elements do not parse") : problem_;
    return has_preamble_ ? why : "it has no DICOM preamble ('DICM' at byte 128), and as a bare data set " + why;
  }

 private:
  bool File() {
    std::uint8_t magic[4];
    std::int64_t at = 0;
    if (size_ >= 132 && Read(128, magic, 4) && std::memcmp(magic, "DICM", 4) == 0) {
      at = 132;
      has_preamble_ = true;
      // The file meta group: explicit VR little endian, group 0002.
      std::uint8_t h[4];
      while (at + 8 <= size_ && Read(at, h, 2) && U16(h) == 0x0002) {
        if (!Element(at, size_, true, 0, true)) return false;
      }
      // GDCM asserts reading a meta group that the file ends in (found by
      // fuzz_volume); a file without a data set holds no image anyway.
      if (at == size_) return Fail("it ends after its file meta group");
      // A deflated data set is walked inflated, as GDCM reads it.
      if (transfer_syntax_ == kDeflated && !Inflate(at)) return false;
    }
    if (at == size_) return true;
    // The data set, in the encoding GDCM first reads it in: the one the meta
    // group's transfer syntax names (GDCM allocates what an element declares
    // in that encoding before it would retry in another: 1.2 GB for a 3 KB
    // file whose syntax says explicit VR and whose elements have none). With
    // no syntax named, explicit VR where the bytes after the first tag read
    // as a VR, and the byte order GDCM guesses from that tag.
    big_endian_ = transfer_syntax_.empty() ? GuessesBigEndian(at) : transfer_syntax_ == kExplicitBigEndian;
    std::uint8_t h[6];
    const bool looks_explicit = at + 6 <= size_ && Read(at, h, 6) && IsVr(h + 4);
    const bool explicit_vr = transfer_syntax_.empty() ? looks_explicit : transfer_syntax_ != kImplicitLittleEndian;
    if (explicit_vr != looks_explicit) {
      return Fail(fmt::format("its transfer syntax {} says {} VR and its first element has {} VR",
                              LogSafe(transfer_syntax_), explicit_vr ? "explicit" : "implicit",
                              looks_explicit ? "an explicit" : "no"));
    }
    while (at < size_) {
      if (!Element(at, size_, explicit_vr, 0, false)) return false;
    }
    // GDCM reads the image module of a data set without Pixel Data all the
    // same (a Planar Configuration of 65535 and a palette of 24 bits
    // asserted; found by fuzz_dicom); cinevol reads images.
    if (!pixels_.pixel_data) return Fail("it has no Pixel Data (7FE0,0010)");
    return PixelModuleIsSound(pixels_, "") && PixelModuleIsSound(icon_, "its icon: ");
  }

  // GDCM's guess at a data set's byte order where no transfer syntax names
  // it (FileMetaInformation::ReadCompat), from the first tag read little
  // endian: big endian in group 0800 (ACR-NEMA), or where the tag is neither
  // in group 0008 nor a private creator's (gggg,0010), a VR follows it and
  // either number is above 0xff. A private element first made GDCM read a
  // file big endian that this walk had passed little endian (its item
  // reader asserted; found by fuzz_dicom).
  bool GuessesBigEndian(std::int64_t at) {
    std::uint8_t h[6];
    if (at + 6 > size_ || !Read(at, h, 6)) return false;
    const unsigned group = unsigned(h[0]) | unsigned(h[1]) << 8, element = unsigned(h[2]) | unsigned(h[3]) << 8;
    if (group == 0x0002 || group == 0x0008 || element == 0x0010) return false;
    return group == 0x0800 || (IsVr(h + 4) && (group > 0xff || element > 0xff));
  }

  static constexpr const char* kImplicitLittleEndian = "1.2.840.10008.1.2";
  static constexpr const char* kExplicitBigEndian = "1.2.840.10008.1.2.2";
  static constexpr const char* kDeflated = "1.2.840.10008.1.2.1.99";
  static constexpr const char* kRle = "1.2.840.10008.1.2.5";
  static constexpr const char* kJpeg2000Prefix = "1.2.840.10008.1.2.4.9";  // JPEG 2000 (.90-.93), JPIP (.94, .95)
  static constexpr const char* kCompressedPrefix = "1.2.840.10008.1.2.4.";  // JPEG, JPEG-LS, JPEG 2000, MPEG, HTJ2K

  // Records the first reason the walk stops at; always false.
  bool Fail(std::string why) {
    if (problem_.empty()) problem_ = std::move(why);
    return false;
  }
  static std::string TagName(unsigned group, unsigned element) { return fmt::format("({:04x},{:04x})", group, element); }

  // The data set's numbers, in its byte order (the file meta group's and an
  // RLE header's are little endian: big_endian_ is false while they are read).
  unsigned U16(const std::uint8_t* b) const {
    return big_endian_ ? unsigned(b[0]) << 8 | unsigned(b[1]) : unsigned(b[0]) | unsigned(b[1]) << 8;
  }
  std::uint32_t U32(const std::uint8_t* b) const {
    return big_endian_ ? std::uint32_t(U16(b)) << 16 | std::uint32_t(U16(b + 2))
                       : std::uint32_t(U16(b)) | std::uint32_t(U16(b + 2)) << 16;
  }
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
    if (at < 0 || at + std::int64_t(n) > size_) return false;
    if (!inflated_.empty() && at >= inflated_from_) {
      std::memcpy(out, inflated_.data() + (at - inflated_from_), n);
      return true;
    }
    return std::fseek(f_, long(at), SEEK_SET) == 0 && std::fread(out, 1, n, f_) == n;
  }

  // A short text value, its padding (trailing spaces and NULs) trimmed;
  // empty where it cannot be read.
  std::string ReadText(std::int64_t at, std::uint32_t length) {
    std::string text(length, '\0');
    if (!Read(at, reinterpret_cast<std::uint8_t*>(text.data()), length)) return {};
    while (!text.empty() && (text.back() == ' ' || text.back() == '\0')) text.pop_back();
    return text;
  }

  // Whether a decimal string's first value reads as zero.
  static bool SlopeIsZero(const std::string& text) {
    const char* begin = text.c_str();
    char* end = nullptr;
    const double value = std::strtod(begin, &end);
    return end != begin && value == 0.0;
  }

  // Deflated Explicit VR Little Endian: the data set from `at` on is one raw
  // deflate stream. It is inflated into memory (kMaxInflated at most: a
  // deflated image past that is a bomb, not a study), and the walk reads the
  // inflated bytes in its place, at the same offsets.
  static constexpr std::int64_t kMaxInflated = std::int64_t{256} << 20;
  bool Inflate(std::int64_t at) {
    if (std::fseek(f_, long(at), SEEK_SET) != 0) return Fail("its deflated data set cannot be read");
    z_stream z{};
    if (inflateInit2(&z, -15) != Z_OK) return Fail("its deflated data set cannot be inflated");
    struct End {
      z_stream* z;
      ~End() { inflateEnd(z); }
    } ender{&z};
    std::vector<unsigned char> in(std::size_t{1} << 16);
    std::string out;
    int ret = Z_OK;
    while (ret != Z_STREAM_END) {
      if (z.avail_in == 0) {
        const std::size_t n = std::fread(in.data(), 1, in.size(), f_);
        if (n == 0) return Fail("its deflated data set ends before its stream does");
        z.next_in = in.data();
        z.avail_in = uInt(n);
      }
      if (std::int64_t(out.size()) > kMaxInflated) {
        return Fail(fmt::format("its deflated data set inflates past {} MiB", kMaxInflated >> 20));
      }
      const std::size_t before = out.size(), room = std::size_t{1} << 20;
      out.resize(before + room);
      z.next_out = reinterpret_cast<unsigned char*>(out.data() + before);
      z.avail_out = uInt(room);
      ret = inflate(&z, Z_NO_FLUSH);
      out.resize(before + (room - z.avail_out));
      if (ret != Z_OK && ret != Z_STREAM_END) return Fail("its deflated data set is damaged");
    }
    if (out.empty()) return Fail("its deflated data set is empty");
    inflated_ = std::move(out);
    inflated_from_ = at;
    size_ = at + std::int64_t(inflated_.size());
    return true;
  }

  // One element at `at` (advanced past it) that must end by `end`.
  bool Element(std::int64_t& at, std::int64_t end, bool explicit_vr, int depth, bool meta) {
    if (depth > 16) return Fail("its sequences nest deeper than 16 levels");
    if (++elements_ > 200000) return Fail("it holds more than 200,000 elements");
    std::uint8_t h[12];
    if (at + 8 > end || !Read(at, h, 8)) return Fail(fmt::format("an element at byte {} runs past its end", at));
    const unsigned group = U16(h), element = U16(h + 2);
    const auto tag = [&] { return TagName(group, element); };  // for a problem only
    std::uint32_t length;
    bool sequence = false;
    // A sequence holds items alone: GDCM throws on anything else there. The
    // walk says so by name, and inside an undefined-length UN GDCM would read
    // the UN again as explicit VR (CP-246), a retry that asserted on other
    // damage (found by fuzz_dicom).
    const bool in_sequence = depth % 2 == 1;
    if (in_sequence && (group != 0xfffe || element == 0xe00d)) return Fail("an element stands where an item should");
    if (group == 0xfffe) {  // item or delimiter: tag and a 4-byte length, never a VR
      length = U32(h + 4);
      at += 8;
      if (element == 0xe00d || element == 0xe0dd) return length == 0 || Fail(tag() + ", a delimiter, has a length");
      if (element != 0xe000) return Fail(tag() + " stands where an item or an element should");
      // Items stand at odd depths, in sequences; elements at even ones. GDCM
      // asserts on an item where it reads an element (an implicit VR data
      // set with an item at its top level; found by fuzz_dicom).
      if (!in_sequence) return Fail("an item stands where an element should");
      const ItemScope item(*this);
      if (length == 0xffffffffu) return Items(at, end, explicit_vr, depth + 1, 0xe00d);
      if (length > std::uint64_t(end - at)) return Fail(fmt::format("an item declares {} bytes past its end", length));
      const std::int64_t item_end = at + length;
      while (at < item_end) {
        if (!Element(at, item_end, explicit_vr, depth + 1, false)) return false;
      }
      return true;
    }
    if (meta && group != 0x0002) return Fail(tag() + " stands in the file meta group");
    if (explicit_vr) {
      // The 64-bit VRs (an Extended Offset Table is OV): GDCM parses them, but
      // the reader's ITK asks GDCM for every element as text, which asserts.
      if (std::memcmp(h + 4, "OV", 2) == 0 || std::memcmp(h + 4, "SV", 2) == 0 || std::memcmp(h + 4, "UV", 2) == 0) {
        return Fail(tag() + " has a 64-bit VR (" + std::string(reinterpret_cast<const char*>(h + 4), 2) +
                    "), which the DICOM reader cannot take");
      }
      if (!IsVr(h + 4)) return Fail(tag() + " has no known VR");
      sequence = std::memcmp(h + 4, "SQ", 2) == 0;
      if (IsLongVr(h + 4)) {
        if (at + 12 > end || !Read(at + 8, h + 8, 4)) return Fail(tag() + " runs past its end");
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
    if (meta && (sequence || length == 0xffffffffu)) return Fail(tag() + " in the file meta group is a sequence");
    // GDCM keeps the first of a repeated tag, and reading an item it counts
    // the bytes of the elements it kept against the item's length: they
    // disagree, and it asserts (a Plane Position read back as no sequence,
    // an item's length "recovered" past its end, retries through its other
    // readers; found by fuzz_dicom). The standard names a tag once a data set.
    if (!item_tags_.empty() && !item_tags_.back().insert(std::uint32_t(group) << 16 | element).second) {
      return Fail(tag() + " is repeated in an item");
    }
    // GDCM takes a Modality LUT's output as the image's pixel format, which
    // ITK's rescaling asserts on (found by fuzz_dicom); cinevol applies
    // Rescale Slope and Intercept and would show the stored values.
    if (group == 0x0028 && element == 0x3000 && depth == 0) {
      return Fail("it has a Modality LUT Sequence (0028,3000); cinevol applies Rescale Slope and Intercept only");
    }
    const bool pixel_data = group == 0x7fe0 && element == 0x0010;
    const bool un = explicit_vr && std::memcmp(h + 4, "UN", 2) == 0;
    const std::string vr(reinterpret_cast<const char*>(h + 4), 2);
    // GDCM asserts on Pixel Data of another VR, and on an explicit VR that
    // its dictionary does not allow for a public element (Rows as OW).
    if (explicit_vr && pixel_data && vr != "OB" && vr != "OW" && !un) return Fail("Pixel Data has VR " + vr);
    if (explicit_vr && !meta && !un && !VrFitsDictionary(group, element, h + 4)) {
      return Fail(tag() + " has VR " + vr + ", which the DICOM dictionary does not give it");
    }
    if (length == 0xffffffffu) {
      // Undefined lengths: encapsulated Pixel Data (fragments, each an item
      // of plain bytes), or a sequence; GDCM asserts on any other, and on
      // nested UN sequences it repairs otherwise than this walk reads them.
      if (pixel_data) {
        // GDCM keeps a repeated Pixel Data's first (native Pixel Data, then
        // fragments, made its JPEG 2000 codec assert; found by fuzz_dicom).
        bool first = false;
        if (PixelModule* module = ModuleAt(depth)) first = !std::exchange(module->pixel_data, true);
        return Fragments(at, end, depth, depth == 0 && first);
      }
      if (explicit_vr && !sequence && !(un && depth == 0)) return Fail(tag() + " of VR " + vr + " has an undefined length");
      // Read as a sequence (a UN, or implicit VR), a public element that the
      // dictionary gives a value: GDCM's scanner asserts when it reads that
      // element as text (Slice Thickness as a sequence, found by fuzz_dicom).
      if (!sequence && group % 2 == 0) {
        const gdcm::VR expected = DictionaryVr(group, element);
        if (expected != gdcm::VR::INVALID && expected != gdcm::VR::SQ) {
          return Fail(tag() + " is a sequence (an undefined length), which the DICOM dictionary does not make it");
        }
      }
      const IconScope icon(*this, depth == 0 && group == 0x0088 && element == 0x0200);
      return Items(at, end, explicit_vr && !un, depth + 1, 0xe0dd);  // implicit VR inside an undefined-length UN
    }
    if (length > std::uint64_t(end - at)) return Fail(fmt::format("{} declares {} bytes past its end", tag(), length));
    // The standard's even lengths; GDCM asserts on an odd one in an item.
    if (depth > 0 && length % 2 != 0) return Fail(fmt::format("{} in a sequence has an odd length ({})", tag(), length));
    if (sequence) {
      // A sequence of defined length is walked like one of undefined length:
      // GDCM asserts on an odd length inside it when it parses its items (an
      // enhanced multi-frame file's functional groups, found by fuzz_dicom's seed).
      const IconScope icon(*this, depth == 0 && group == 0x0088 && element == 0x0200);
      const std::int64_t sequence_end = at + length;
      while (at < sequence_end) {
        if (!Element(at, sequence_end, explicit_vr, depth + 1, false)) return false;
      }
      return true;
    }
    if (PixelModule* module = ModuleAt(depth)) Remember(*module, group, element, at, length, pixel_data);
    // A Rescale Slope of 0, here or in a functional group, makes GDCM pick
    // the smallest integer type for the rescaled image, which ITK asserts is
    // no smaller than the stored one (found by fuzz_dicom); no image has it.
    if (group == 0x0028 && element == 0x1053 && length <= 64 && SlopeIsZero(ReadText(at, length))) {
      return Fail("(0028,1053) Rescale Slope is 0");
    }
    if (group == 0x0008 && element == 0x0010 && depth == 0 && !RecognitionCodeIsAcrNema(at, length)) {
      return Fail("(0008,0010) Recognition Code is not an ACR-NEMA version GDCM reads");
    }
    // (0002,0010) Transfer Syntax UID: in the file meta group, or in a file
    // without the preamble whose data set starts with one (GDCM reads that
    // meta group too, and decodes the pixels by its syntax).
    if (group == 0x0002 && element == 0x0010 && depth == 0 && transfer_syntax_.empty() && length <= 64) {
      transfer_syntax_ = ReadText(at, length);
    }
    // GDCM asserts that Samples per Pixel is 1, 3 or 4 (an abort, found by
    // fuzz_volume), in any image, icons included.
    if (group == 0x0028 && element == 0x0002 && !meta) {
      std::uint8_t v[2];
      if (length < 2 || !Read(at, v, 2) || (U16(v) != 1 && U16(v) != 3 && U16(v) != 4)) {
        return Fail("Samples per Pixel is not 1, 3 or 4");
      }
    }
    at += length;
    return true;
  }

  // (0008,0010) Recognition Code, retired: a file that has it, not empty, is
  // ACR-NEMA, and GDCM asserts that it names a version it knows (its DICOM
  // reader wants one of these prefixes, its ACR-NEMA reader one of these
  // values; an abort on a date there, found by fuzz_dicom).
  bool RecognitionCodeIsAcrNema(std::int64_t at, std::uint32_t length) {
    static const char* const kVersions[] = {"ACR-NEMA 1.0", "ACR-NEMA 2.0", "ACRNEMA_LIBIDO_1.0", "ACRNEMA_LIBIDO_1.1"};
    if (length == 0) return true;
    if (length > 18) return false;
    std::string value(length, '\0');
    if (!Read(at, reinterpret_cast<std::uint8_t*>(value.data()), length)) return false;
    return std::any_of(std::begin(kVersions), std::end(kVersions), [&](const char* v) { return value == v; });
  }

  // Items of plain bytes up to the sequence delimiter, which is consumed: the
  // basic offset table, then at least one fragment (GDCM asserts on none).
  // The top-level image's fragments are remembered, for its codec's check.
  bool Fragments(std::int64_t& at, std::int64_t end, int depth, bool top_level) {
    for (int items = 0; at + 8 <= end; ++items) {
      std::uint8_t h[8];
      if (!Read(at, h, 8) || U16(h) != 0xfffe || ++elements_ > 200000) {
        return Fail("Pixel Data's fragments are not items");
      }
      at += 8;
      if (U16(h + 2) == 0xe0dd) return items >= 2 || Fail("Pixel Data has no fragment after its offset table");
      const std::uint32_t length = U32(h + 4);
      if (U16(h + 2) != 0xe000 || length > std::uint64_t(end - at)) {
        return Fail("a fragment of Pixel Data runs past its end");
      }
      // GDCM counts an odd fragment padded to even, and in an item that
      // disagrees with the item's length: it asserts (an icon's Pixel Data;
      // a private UN's, through its CP-246 retry; found by fuzz_dicom). The
      // standard's fragments are even.
      if (depth > 0 && length % 2 != 0) return Fail("a fragment of Pixel Data in a sequence has an odd length");
      if (top_level && items >= 1) pixels_.fragments.push_back({at, length});
      at += length;
    }
    return Fail("Pixel Data's fragments have no end");
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
    int rows = -1, columns = -1, samples = -1, bits_allocated = -1, bits_stored = -1, high_bit = -1;
    int pixel_representation = 0, planar_configuration = 0;
    std::string photometric;  // trailing spaces trimmed
    long frames = 1;          // Number of Frames (0028,0008); 1 where it is none, 0 or no number
    bool pixel_data = false;
    std::set<unsigned> seen;  // the (0028,xxxx) elements remembered: each one's first occurrence
    struct Fragment {
      std::int64_t at;
      std::uint32_t length;
    };
    std::vector<Fragment> fragments;  // encapsulated: those after the offset table (the top-level image's only)
  };

  // The pixel module an element at `depth` belongs to: the data set's, or
  // its icon's (GDCM reads an Icon Image Sequence's image too); else none.
  PixelModule* ModuleAt(int depth) {
    if (depth == 0) return &pixels_;
    return in_icon_ && depth == 2 ? &icon_ : nullptr;
  }

  // While the walk is inside the data set's Icon Image Sequence (0088,0200).
  struct IconScope {
    IconScope(DicomWalk& walk, bool icon) : walk(walk), icon(icon) {
      if (icon) walk.in_icon_ = true;
    }
    ~IconScope() {
      if (icon) walk.in_icon_ = false;
    }
    DicomWalk& walk;
    bool icon;
  };

  // While the walk is inside an item: the tags it has met there.
  struct ItemScope {
    explicit ItemScope(DicomWalk& walk) : walk(walk) { walk.item_tags_.emplace_back(); }
    ~ItemScope() { walk.item_tags_.pop_back(); }
    DicomWalk& walk;
  };

  // An element the data set repeats counts as its first: GDCM keeps the
  // first of a tag and drops the others, so a walk that read the last one
  // checked another image than GDCM decodes (a Bits Stored of 8 where GDCM
  // had 16, and its buffer overrun; a Bits Allocated of 24 where the walk
  // had 16, and GDCM's assertion; found by fuzz_dicom).
  void Remember(PixelModule& module, unsigned group, unsigned element, std::int64_t at, std::uint32_t length,
                bool pixel_data) {
    if (pixel_data) module.pixel_data = true;
    if (group != 0x0028 || !module.seen.insert(element).second) return;
    if (element == 0x0004 && length <= 64) {  // Photometric Interpretation
      module.photometric = ReadText(at, length);
      return;
    }
    if (element == 0x0008 && length <= 16) {  // Number of Frames, an IS
      module.frames = std::max(1L, std::strtol(ReadText(at, length).c_str(), nullptr, 10));
      return;
    }
    if (length < 2) return;
    std::uint8_t v[2];
    if (!Read(at, v, 2)) return;
    const int value = int(U16(v));
    switch (element) {
      case 0x0002: module.samples = value; break;
      case 0x0006:
        module.planar_configuration = value;
        break;
      case 0x0010: module.rows = value; break;
      case 0x0011: module.columns = value; break;
      case 0x0100: module.bits_allocated = value; break;
      case 0x0101: module.bits_stored = value; break;
      case 0x0102: module.high_bit = value; break;
      case 0x0103: module.pixel_representation = value; break;
      default: break;
    }
  }

  // GDCM asserts on a Bits Allocated it has no codec for (12), on Bits
  // Stored above Bits Allocated or missing, on a High Bit other than Bits
  // Stored - 1 (which the CT and MR image modules require), on a Pixel
  // Representation other than 0 or 1, on palettes whose tables disagree,
  // and decodes a JPEG 2000 or RLE stream that disagrees with the header
  // past its buffers. So the image's pixel module must hold together and be
  // grey-scale (cinevol reads no other: series.cpp would refuse a colour
  // image after GDCM decoded it), and every frame's compressed stream must
  // describe the image the header does. The same holds for an icon's
  // (`which` names it in the problem), whose fragments are not checked.
  bool PixelModuleIsSound(const PixelModule& p, const std::string& which) {
    if (!p.pixel_data) return true;
    if (!p.photometric.empty() && p.photometric != "MONOCHROME1" && p.photometric != "MONOCHROME2") {
      return Fail(fmt::format("{}Photometric Interpretation '{}'; cinevol reads grey-scale series "
                              "(MONOCHROME1 or MONOCHROME2)",
                              which, LogSafe(p.photometric, 32)));
    }
    // A grey-scale image has one sample a pixel; GDCM takes one from the
    // photometric interpretation, and its JPEG 2000 decoder asserted on a
    // stream of three components, as Samples per Pixel said (found by fuzz_dicom).
    if (p.samples > 1) {
      return Fail(fmt::format("{}Samples per Pixel is {}; cinevol reads grey-scale series (one sample a pixel)", which,
                              p.samples));
    }
    if (p.pixel_representation != 0 && p.pixel_representation != 1) {
      return Fail(fmt::format("{}Pixel Representation is {}, not 0 or 1", which, p.pixel_representation));
    }
    if (p.planar_configuration != 0 && p.planar_configuration != 1) {
      return Fail(fmt::format("{}Planar Configuration is {}, not 0 or 1", which, p.planar_configuration));
    }
    // A Rows or Columns of 0 (or none) makes GDCM take them from a JPEG
    // stream's header, and assert where the stream's precision differs
    // (found by fuzz_dicom); the image module requires both.
    if (p.rows < 1 || p.columns < 1) {
      return Fail(
          fmt::format("{}an image of {} rows and {} columns", which, std::max(p.rows, 0), std::max(p.columns, 0)));
    }
    const bool bits_known = p.bits_allocated == 1 || p.bits_allocated == 8 || p.bits_allocated == 16 ||
                            p.bits_allocated == 32 || p.bits_allocated == 64;
    if (p.bits_allocated < 0 || p.bits_stored < 0 || p.high_bit < 0) {
      return Fail(which + "an image without Bits Allocated, Bits Stored or High Bit");
    }
    if (!bits_known) return Fail(fmt::format("{}Bits Allocated is {}, not 1, 8, 16, 32 or 64", which, p.bits_allocated));
    if (p.bits_stored < 1 || p.bits_stored > p.bits_allocated) {
      return Fail(fmt::format("{}Bits Stored is {} with Bits Allocated {}", which, p.bits_stored, p.bits_allocated));
    }
    if (p.high_bit != p.bits_stored - 1) {
      return Fail(fmt::format("{}High Bit is {}, not Bits Stored ({}) - 1", which, p.high_bit, p.bits_stored));
    }
    // GDCM clears the bits above Bits Stored in 16-bit samples only, and
    // asserts on any other with bits unused (Bits Allocated 32 with 16
    // stored, found by fuzz_dicom; 8 with 7).
    if (p.bits_stored != p.bits_allocated && p.bits_allocated != 16) {
      return Fail(fmt::format("{}Bits Stored is {} with Bits Allocated {}; only 16-bit samples may leave bits unused",
                              which, p.bits_stored, p.bits_allocated));
    }
    // GDCM's JPEG codec has none for samples past 16 bits, and asserts (Bits
    // Allocated 64 under JPEG Lossless, found by fuzz_dicom): JPEG and JPEG-LS
    // hold 16 bits at most.
    if (JpegFamily() && p.bits_allocated > 16) {
      return Fail(fmt::format("{}Bits Allocated is {} under JPEG, which holds 16 at most", which, p.bits_allocated));
    }
    const bool jpeg_2000 = transfer_syntax_.rfind(kJpeg2000Prefix, 0) == 0;
    const bool compressed = transfer_syntax_.rfind(kCompressedPrefix, 0) == 0 || transfer_syntax_ == kRle;
    // GDCM's JPEG and JPEG 2000 codecs read the image's Pixel Data of a
    // defined length as fragments all the same, and assert where its bytes
    // hold no offset table (2 bytes of Pixel Data, found by fuzz_dicom). The
    // standard encapsulates every compressed image.
    if (compressed && &p == &pixels_ && p.fragments.empty()) {
      return Fail(fmt::format("Pixel Data is not encapsulated, which its transfer syntax {} requires",
                              LogSafe(transfer_syntax_)));
    }
    if (p.fragments.empty()) return true;  // not encapsulated (or an icon's)
    if (jpeg_2000) {
      // A frame may span fragments: each one that starts a code stream (or
      // a JP2 file) is a frame's, and the first fragment must be one.
      for (std::size_t i = 0; i < p.fragments.size(); ++i) {
        const Fragment& f = p.fragments[i];
        if (i > 0 && !StartsJ2k(f)) continue;
        std::size_t code_stream = 0;
        if (!J2kFitsHeader(f, code_stream)) {
          return Fail(fmt::format("the JPEG 2000 stream of fragment {} describes another image than its header", i + 1));
        }
        if (!J2kMarkersChain(f, code_stream)) {
          return Fail(fmt::format("the JPEG 2000 stream of fragment {} has marker segments that run past it", i + 1));
        }
      }
    }
    // GDCM reads the JPEG header of the first fragment, and asserted on an
    // empty one (a precision of 0; found by fuzz_dicom).
    if (JpegFamily() && !StartsJpeg(p.fragments.front())) {
      return Fail("the first fragment holds no JPEG stream (it starts with no SOI marker)");
    }
    if (JpegFamily()) {
      switch (JpegHeaderIn(p.fragments.front())) {
        case JpegHeader::kWhole:
          break;
        case JpegHeader::kBroken:
          return Fail("the first fragment's JPEG marker segments do not lead from one to the next");
        case JpegHeader::kCut:
          return Fail("the first fragment ends inside its JPEG header (before the scan starts)");
      }
    }
    // Each frame is one JPEG stream (which may span fragments). GDCM decodes
    // fragment by fragment, and where one past the frames fails it asserts
    // (a single-frame image with three streams, found by fuzz_dicom).
    if (JpegFamily()) {
      const auto streams =
          std::count_if(p.fragments.begin(), p.fragments.end(), [&](const Fragment& f) { return StartsJpeg(f); });
      if (streams > p.frames) {
        return Fail(fmt::format("its fragments hold {} JPEG streams for {} frame(s)", streams, p.frames));
      }
    }
    if (transfer_syntax_ == kRle) {  // one fragment a frame
      for (std::size_t i = 0; i < p.fragments.size(); ++i) {
        if (!RleFitsHeader(p.fragments[i])) return Fail(fmt::format("the RLE segments of fragment {} do not fit its header", i + 1));
      }
    }
    return true;
  }

  using Fragment = PixelModule::Fragment;

  // The JPEG and JPEG-LS syntaxes (1.2.840.10008.1.2.4.50-.57, .70, .80, .81).
  bool JpegFamily() const {
    const std::string_view prefix = kCompressedPrefix;
    if (transfer_syntax_.size() != prefix.size() + 2 || transfer_syntax_.rfind(prefix, 0) != 0) return false;
    const char first = transfer_syntax_[prefix.size()];
    return first >= '5' && first <= '8';
  }

  // Whether the fragment begins a JPEG stream (SOI, then a marker).
  bool StartsJpeg(const Fragment& f) {
    std::uint8_t b[3];
    return f.length >= 4 && Read(f.at, b, 3) && b[0] == 0xff && b[1] == 0xd8 && b[2] == 0xff;
  }

  // What a JPEG stream's header, from SOI to its scan (SOS), looks like in
  // its first fragment, as far as its first 64 KiB go: whole, each marker
  // segment ending where the next marker starts; broken; or cut, going on
  // past the fragment. GDCM asserted reading a header whose table's length
  // landed inside the next segment (found by fuzz_dicom), and one whose
  // frame header went on in the next fragment: it reads the header from the
  // first fragment alone (found by cinevol-server-fuzz).
  enum class JpegHeader { kWhole, kBroken, kCut };
  JpegHeader JpegHeaderIn(const Fragment& f) {
    constexpr std::uint32_t kLooked = 1u << 16;
    // Where the fragment is longer than what is read, a header that runs past that is not judged.
    const JpegHeader past_the_end = f.length > kLooked ? JpegHeader::kWhole : JpegHeader::kCut;
    std::vector<std::uint8_t> b(std::min(f.length, kLooked));
    if (!Read(f.at, b.data(), b.size())) return JpegHeader::kBroken;
    std::size_t k = 2;  // after SOI
    while (k + 1 < b.size()) {
      if (b[k] != 0xff) return JpegHeader::kBroken;
      const std::uint8_t marker = b[k + 1];
      if (marker == 0xff) {  // a fill byte
        ++k;
      } else if (marker == 0xda) {
        return JpegHeader::kWhole;
      } else if (marker == 0xd8 || marker == 0xd9) {  // SOI or EOI before the scan
        return JpegHeader::kBroken;
      } else if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) {  // no length
        k += 2;
      } else {
        if (k + 3 >= b.size()) return past_the_end;
        k += 2 + (std::size_t(b[k + 2]) << 8 | b[k + 3]);
      }
    }
    return past_the_end;
  }

  // Whether the fragment begins a JPEG 2000 code stream (SOC, SIZ) or a JP2
  // file (its signature box).
  bool StartsJ2k(const Fragment& f) {
    static const std::uint8_t kCodeStream[4] = {0xff, 0x4f, 0xff, 0x51};
    static const std::uint8_t kJp2[8] = {0, 0, 0, 0x0c, 'j', 'P', ' ', ' '};
    std::uint8_t b[8];
    if (f.length < 8 || !Read(f.at, b, 8)) return false;
    return std::memcmp(b, kCodeStream, 4) == 0 || std::memcmp(b, kJp2, 8) == 0;
  }

  static std::uint32_t Be32(const std::uint8_t* b) {
    return std::uint32_t(b[0]) << 24 | std::uint32_t(b[1]) << 16 | std::uint32_t(b[2]) << 8 | b[3];
  }

  // A JPEG 2000 code stream (or a JP2 file's 'jp2c' box) whose SIZ marker
  // gives the header's columns, rows and samples, at a precision that fits.
  // `c` takes where the code stream starts in the fragment.
  bool J2kFitsHeader(const Fragment& f, std::size_t& c) {
    const std::size_t n = std::min<std::size_t>(f.length, 4096);
    std::vector<std::uint8_t> b(n);
    if (n < 42 || !Read(f.at, b.data(), n)) return false;
    c = 0;
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
    if (width != pixels_.columns || height != pixels_.rows || components != pixels_.samples) return false;
    // Each component's precision (Ssiz's low 7 bits, plus 1) within Bits
    // Allocated: GDCM takes its Bits Stored from the stream, and asserts on
    // one above Bits Allocated.
    if (c + 42 + 3 * std::size_t(components) > n) return false;
    for (int i = 0; i < components; ++i) {
      if ((siz[38 + 3 * i] & 0x7f) + 1 > pixels_.bits_allocated) return false;
    }
    return true;
  }

  // Whether a JPEG 2000 code stream's marker segments, from SOC (at
  // `start` in the fragment) to the first tile's data (SOD), each end inside
  // the fragment; a coding style (COD) at its standard length. GDCM's header
  // parser steps over a segment by its length unchecked, and read past the
  // fragment where one ran beyond it (a SEGV, found by fuzz_dicom). A code
  // stream's headers hold a few dozen segments: past kMaxSegments it is refused.
  bool J2kMarkersChain(const Fragment& f, std::size_t start) {
    constexpr int kMaxSegments = 4096;
    std::uint64_t k = start;
    for (int segments = 0; k + 2 <= f.length; ++segments) {
      std::uint8_t m[4];
      const std::size_t n = std::size_t(std::min<std::uint64_t>(4, f.length - k));
      if (segments == kMaxSegments || !Read(f.at + std::int64_t(k), m, n)) return false;
      const unsigned marker = unsigned(m[0]) << 8 | m[1];
      k += 2;
      if (marker == 0xff93) return true;  // SOD
      // SOC, EOC, EPH and the reserved FF30-FF3F carry no length.
      if (marker == 0xff4f || marker == 0xffd9 || marker == 0xff92 || (marker >= 0xff30 && marker <= 0xff3f)) continue;
      if (n < 4) return false;  // its length past the fragment
      const unsigned length = unsigned(m[2]) << 8 | m[3];
      if (length < 2 || (marker == 0xff52 && length < 12) || k + length > f.length) return false;
      k += length;
    }
    return true;  // the fragment ends between segments: GDCM's parser stops there
  }

  // An RLE fragment's header: 1 to 15 segments, one per byte of each sample,
  // their offsets rising from 64 and inside the fragment.
  bool RleFitsHeader(const Fragment& f) {
    std::uint8_t header[64];
    if (f.length < 64 || !Read(f.at, header, 64)) return false;
    const std::uint32_t segments = U32(header);
    if (segments < 1 || segments > 15 || pixels_.bits_allocated < 8 ||
        segments != std::uint32_t(pixels_.samples) * std::uint32_t(pixels_.bits_allocated / 8)) {
      return false;
    }
    std::uint32_t previous = 63;
    for (std::uint32_t i = 0; i < segments; ++i) {
      const std::uint32_t offset = U32(header + 4 + 4 * i);
      if (offset <= previous || offset >= f.length) return false;
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
    return Fail("a sequence or item of undefined length has no end");
  }

  std::FILE* f_;
  std::int64_t size_;
  int elements_ = 0;
  std::string transfer_syntax_;  // from the file meta group
  bool big_endian_ = false;      // the data set's byte order
  bool has_preamble_ = false;    // 'DICM' at byte 128
  std::string inflated_;         // a deflated data set, inflated: the bytes from inflated_from_ on
  std::int64_t inflated_from_ = 0;
  std::string problem_;          // the first reason the walk stopped
  PixelModule pixels_, icon_;  // the data set's image and its icon's
  bool in_icon_ = false;        // inside the Icon Image Sequence (IconScope)
  std::vector<std::set<std::uint32_t>> item_tags_;  // the items the walk is inside, innermost last (ItemScope)
};

}  // namespace

std::string StructureProblem(const fs::path& path) {
  const file_checks::FileStream f = file_checks::OpenRegularStream(path);
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (!f || ec) return "it cannot be opened as a regular file";
  return DicomWalk(f.get(), std::int64_t(size)).Problem();
}

}  // namespace cinevol::formats::dicom
