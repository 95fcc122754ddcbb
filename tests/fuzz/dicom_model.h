// DICOM files as a tree (preamble, file meta group, data set elements,
// sequences and their items, encapsulated pixel data fragments), written back
// byte for byte, and mutations at that level: tags, VRs, lengths (undefined
// and lying ones included), transfer syntaxes and data set encodings, the
// image pixel module (Photometric Interpretation, Samples per Pixel, Bits
// Allocated/Stored, Rows/Columns, frames, palettes), geometry, nesting, and
// the pixel data itself (native, or JPEG 2000 and other fragments, see
// j2k_model.h). fuzz_dicom's custom mutator and the server fuzz driver
// (server_fuzz.cpp) both use it; nothing here depends on libFuzzer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace cinevol::fuzz {

// A small, fast, seeded generator (splitmix64).
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // A number in [0, n); 0 when n is 0.
  std::size_t Below(std::size_t n) { return n == 0 ? 0 : std::size_t(Next() % n); }
  bool OneIn(std::size_t n) { return Below(n) == 0; }
  template <class T>
  const T& Pick(const std::vector<T>& from) { return from[Below(from.size())]; }

 private:
  std::uint64_t state_;
};

// Mutates `size` bytes at `data` in place (room for `max_size`) and returns
// the new size: libFuzzer's LLVMFuzzerMutate in fuzz_dicom, PlainByteMutator
// in the server driver.
using ByteMutator = std::function<std::size_t(std::uint8_t* data, std::size_t size, std::size_t max_size)>;

// Byte-level mutations without libFuzzer: bit flips, interesting bytes and
// integers, inserted, erased, copied and repeated runs.
ByteMutator PlainByteMutator(Random& random);

// `bytes` mutated by `mutate`, at most `max_size` long.
std::string MutateString(const std::string& bytes, const ByteMutator& mutate, std::size_t max_size);

struct Element;

struct Item {
  std::vector<Element> elements;
  bool undefined_length = false;               // ended by an item delimiter
  std::optional<std::uint32_t> stated_length;  // a length that lies (defined length only)
};

struct Element {
  enum class Kind {
    kValue,      // plain bytes
    kSequence,   // items of elements
    kFragments,  // encapsulated pixel data: items of plain bytes, the basic offset table first
  };
  std::uint16_t group = 0, element = 0;
  std::string vr = "UN";  // two characters; what an implicit VR data set would have
  Kind kind = Kind::kValue;
  std::string value;                   // kValue: the bytes, binary numbers little endian
  std::vector<Item> items;             // kSequence
  std::vector<std::string> fragments;  // kFragments
  bool undefined_length = false;       // kSequence: ended by a delimiter; kValue: 0xFFFFFFFF then the bytes (a lie)
  std::optional<std::uint32_t> stated_length;  // the length written instead of the true one (a lie)

  std::uint32_t tag() const { return std::uint32_t(group) << 16 | element; }
};

// How the data set after the file meta group is encoded. The transfer syntax
// UID says one thing; a mutation may make these say another.
struct Encoding {
  bool explicit_vr = true;
  bool big_endian = false;
  bool deflated = false;
};

struct DicomFile {
  bool preamble = true;            // 128 bytes, then "DICM"
  std::string preamble_bytes = std::string(128, '\0');
  std::vector<Element> meta;       // group 0002, explicit VR little endian
  std::optional<std::uint32_t> meta_group_length;  // (0002,0000)'s value when it lies; else recomputed
  Encoding encoding;
  std::vector<Element> data_set;
  std::string trailing;  // bytes from where parsing stopped, written after the data set as they were

  // Elements of the data set's top level.
  Element* Find(std::uint16_t group, std::uint16_t element);
  const Element* Find(std::uint16_t group, std::uint16_t element) const;
  // Sets a top-level element's value (the element added in tag order when absent).
  Element& Set(std::uint16_t group, std::uint16_t element, const std::string& vr, const std::string& value);
};

// A file's tree, from its bytes; nullopt when not even its start parses.
// Whatever does not parse past that is kept in `trailing`.
std::optional<DicomFile> ParseDicom(const std::uint8_t* data, std::size_t size);
// The file's bytes.
std::string WriteDicom(const DicomFile& file);

// The transfer syntax UID's encoding (explicit little endian for those that
// encapsulate pixel data or are unknown).
Encoding EncodingOf(const std::string& transfer_syntax_uid);
// A text value without its padding (trailing spaces and NULs).
std::string Trimmed(const std::string& value);
std::string TransferSyntax(const DicomFile& file);

// 1 to 3: how many slices fuzz_dicom and the server driver make of one
// input (the preamble's first byte; no preamble, one).
int SliceCount(const DicomFile& file);
// `count` copies of the file, the i-th moved i slice gaps along its normal
// (Image Position Patient rewritten): a series of `count` slices.
std::vector<std::string> Slices(const DicomFile& file, int count);

// One to a few mutations of the tree; byte-level ones go through `mutate`.
// The written file should stay within `max_size` (the caller checks).
void Mutate(DicomFile& file, Random& random, const ByteMutator& mutate, std::size_t max_size);
// Moves parts of `from` into `into`: its pixel module and pixel data, its
// transfer syntax with its pixel data, or some of its elements.
void CrossOver(DicomFile& into, const DicomFile& from, Random& random);

// The whole mutator on bytes: parsed, mutated and written, within
// `max_size`; byte-level when the input does not parse or the result is too
// long, and sometimes anyway.
std::string MutateDicomBytes(const std::uint8_t* data, std::size_t size, std::size_t max_size, Random& random,
                             const ByteMutator& mutate);
// Crossover on bytes; falls back to splicing the two byte strings.
std::string CrossOverDicomBytes(const std::uint8_t* a, std::size_t a_size, const std::uint8_t* b, std::size_t b_size,
                                std::size_t max_size, Random& random);

// The two as libFuzzer's custom mutator and crossover call them: seeded by
// `seed`, the result written over `data` (or into `out`), its size returned.
std::size_t MutateDicomInPlace(std::uint8_t* data, std::size_t size, std::size_t max_size, unsigned int seed,
                               const ByteMutator& mutate);
std::size_t CrossOverDicomInto(const std::uint8_t* a, std::size_t a_size, const std::uint8_t* b, std::size_t b_size,
                               std::uint8_t* out, std::size_t max_size, unsigned int seed);

}  // namespace cinevol::fuzz
