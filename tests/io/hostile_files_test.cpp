// Hostile volume files (issue 18): headers that name other files, FIFOs and
// devices, absurd sizes, gzip bombs. Each load must stay inside what its
// LoadPolicy allows, finish quickly, and name the label, never a server path.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <nifti/nifti1.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <future>
#include <iterator>
#include <limits>

#include "core/error.h"
#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr const char* kLabel = "upload:evil";

void WriteBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

// `data`, then `zeros` zero bytes (fed a MiB at a time), deflated with
// zlib's `window_bits`: 15 + 16 a gzip file, -15 a raw stream.
std::string Deflate(const std::string& data, int window_bits, std::size_t zeros = 0) {
  z_stream z{};
  deflateInit2(&z, 6, Z_DEFLATED, window_bits, 8, Z_DEFAULT_STRATEGY);
  std::string out;
  const std::string zero_chunk(std::min<std::size_t>(zeros, std::size_t{1} << 20), '\0');
  const auto feed = [&](const char* in, std::size_t n, int flush) {
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in));
    z.avail_in = uInt(n);
    do {
      char chunk[1 << 16];
      z.next_out = reinterpret_cast<Bytef*>(chunk);
      z.avail_out = sizeof chunk;
      deflate(&z, flush);
      out.append(chunk, sizeof chunk - z.avail_out);
    } while (z.avail_out == 0);
  };
  feed(data.data(), data.size(), Z_NO_FLUSH);
  for (std::size_t left = zeros; left > 0; left -= std::min(left, zero_chunk.size())) {
    feed(zero_chunk.data(), std::min(left, zero_chunk.size()), Z_NO_FLUSH);
  }
  feed(nullptr, 0, Z_FINISH);
  deflateEnd(&z);
  return out;
}

std::string Gzip(const std::string& data) { return Deflate(data, 15 + 16); }

// A NIfTI-1 header (4x4x4 int16) with the given magic, then `payload`.
std::string Nifti(const char* magic, const std::string& payload, float vox_offset = 352) {
  nifti_1_header h;
  std::memset(&h, 0, sizeof h);
  h.sizeof_hdr = 348;
  h.dim[0] = 3;
  h.dim[1] = h.dim[2] = h.dim[3] = 4;
  h.datatype = DT_INT16;
  h.bitpix = 16;
  h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 1.0f;
  h.vox_offset = vox_offset;
  h.scl_slope = 1.0f;
  std::memcpy(h.magic, magic, 4);
  return std::string(reinterpret_cast<const char*>(&h), sizeof h) + std::string(4, '\0') + payload;
}

LoadPolicy Upload() {
  LoadPolicy p;
  p.references = LoadPolicy::References::kNone;
  p.label = kLabel;
  return p;
}

LoadPolicy InsideRoots(const fs::path& root) {
  LoadPolicy p;
  p.references = LoadPolicy::References::kInsideRoots;
  p.roots = {fs::canonical(root)};
  return p;
}

// Runs `load` on a thread and returns its InputError message, or "(loaded)".
// A load still running after 2 s has blocked: the test fails, and each of
// `fifos` gets a writer so the blocked open returns and the thread ends.
std::string LoadMessage(const std::function<Volume()>& load, const std::vector<fs::path>& fifos = {}) {
  auto result = std::async(std::launch::async, [load]() -> std::string {
    try {
      load();
      return "(loaded)";
    } catch (const InputError& e) {
      return e.what();
    }
  });
  if (result.wait_for(2s) == std::future_status::timeout) {
    ADD_FAILURE() << "the load blocked";
    for (const fs::path& f : fifos) {
      const int fd = open(f.c_str(), O_RDWR | O_NONBLOCK);
      if (fd >= 0) close(fd);
    }
  }
  return result.get();
}

bool Has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A data root with a detached NRRD pair inside, and a secret outside it.
struct Layout {
  ScratchDir dir;
  fs::path root = dir / "root";
  fs::path secret = dir / "outside" / "secret.raw";
  Layout() {
    fs::create_directories(root);
    fs::create_directories(secret.parent_path());
    WriteBytes(secret, std::string(8, '\x7f'));
    WriteBytes(root / "in.raw", std::string("\1\2\3\4\5\6\7\x08", 8));
  }
};

std::string Nhdr(const std::string& data_file) {
  return "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n" + data_file + "\n";
}

// Every way a header names another file, one per format.
struct Reference {
  const char* name;
  std::string text;
  const char* field;
};

std::vector<Reference> References(const fs::path& secret) {
  const std::string s = secret.string();
  return {
      {"single.nhdr", Nhdr("data file: " + s), "data file"},
      {"spelling.nrrd", Nhdr("DATAFILE: " + s), "data file"},
      {"list.nhdr", Nhdr("data file: LIST\n" + s + "\n" + s), "data file"},
      {"pattern.nhdr", Nhdr("data file: " + secret.parent_path().string() + "/s%03d.raw 1 2 1"), "data file"},
      {"meta.mhd",
       "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = " + s + "\n",
       "ElementDataFile"},
      {"list.mha",
       "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST\n" + s + "\n" +
           s + "\n",
       "ElementDataFile"},
      {"pair.nii", Nifti("ni1", std::string(128, '\0')), "NIfTI/Analyze .hdr/.img pair"},
      {"pair.hdr", Nifti("ni1", ""), "NIfTI/Analyze .hdr/.img pair"},
  };
}

TEST(HostileFiles, UploadsThatNameAnotherFileAreRefused) {
  Layout l;
  WriteBytes(l.root / "pair.img", std::string(128, '\0'));
  for (const Reference& r : References(l.secret)) {
    WriteBytes(l.root / r.name, r.text);
    const std::string what = LoadMessage([&] { return LoadVolumeFile(l.root / r.name, Upload()); });
    EXPECT_TRUE(Has(what, std::string(kLabel) + ": the header names another file ('" + r.field + "')")) << what;
    EXPECT_TRUE(Has(what, "uploads must be self-contained")) << what;
    EXPECT_FALSE(Has(what, "secret")) << what;
    EXPECT_FALSE(Has(what, l.dir.path().string())) << what;
  }
}

TEST(HostileFiles, InsideRootsLoadsADetachedPairInside) {
  Layout l;
  WriteBytes(l.root / "pair.nhdr", Nhdr("data file: in.raw"));
  const Volume v = LoadVolumeFile(l.root / "pair.nhdr", InsideRoots(l.root));
  EXPECT_EQ(v.Value(1, 1, 1), 8.0f);
  // The other forms, inside the root, load too.
  WriteBytes(l.root / "s01.raw", std::string("\1\2\3\4", 4));
  WriteBytes(l.root / "s02.raw", std::string("\5\6\7\x08", 4));
  WriteBytes(l.root / "pattern.nhdr", Nhdr("data file: s%02d.raw 1 2 1"));
  WriteBytes(l.root / "list.nhdr", Nhdr("data file: LIST\ns01.raw\ns02.raw"));
  WriteBytes(l.root / "meta.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                                  "ElementDataFile = in.raw\n");
  for (const char* name : {"pattern.nhdr", "list.nhdr", "meta.mhd"}) {
    EXPECT_EQ(LoadVolumeFile(l.root / name, InsideRoots(l.root)).Value(1, 1, 1), 8.0f) << name;
  }
}

// A file that states no orientation says so in a note naming what was
// assumed; one that states its space does not.
TEST(HostileFiles, AnOrientationAssumedIsNoted) {
  Layout l;
  const std::string voxels(8, '\1');
  WriteBytes(l.root / "plain.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" + voxels);
  WriteBytes(l.root / "placed.nrrd",
             "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace: left-posterior-superior\n"
             "space directions: (1,0,0) (0,1,0) (0,0,1)\nencoding: raw\n\n" + voxels);
  WriteBytes(l.root / "plain.nii", Nifti("n+1", std::string(128, '\0')));
  auto noted = [&](const char* name) {
    const Volume v = LoadVolumeFile(l.root / name, InsideRoots(l.root));
    for (const std::string& note : v.metadata().notes) {
      if (Has(note, "the file states no orientation")) return note;
    }
    return std::string();
  };
  EXPECT_TRUE(Has(noted("plain.nrrd"), "taken as LPS")) << noted("plain.nrrd");
  EXPECT_EQ(noted("placed.nrrd"), "");
  EXPECT_TRUE(Has(noted("plain.nii"), "taken as LPS")) << "NIfTI without qform or sform: " << noted("plain.nii");
}

// A NIfTI-1 pair: the header in .hdr (348 bytes), the 4x4x4 int16 voxels in
// the .img from its vox_offset 0. Either name loads it, whole.
TEST(HostileFiles, InsideRootsLoadsANiftiPair) {
  Layout l;
  std::string voxels;
  for (std::int16_t i = 0; i < 64; ++i) voxels.append(reinterpret_cast<const char*>(&i), 2);
  WriteBytes(l.root / "pair.hdr", Nifti("ni1", "", 0).substr(0, 348));
  WriteBytes(l.root / "pair.img", voxels);
  for (const char* name : {"pair.hdr", "pair.img"}) {
    const Volume v = LoadVolumeFile(l.root / name, InsideRoots(l.root));
    EXPECT_EQ(v.dims().x, 4) << name;
    EXPECT_EQ(v.Value(1, 2, 3), 1.0f + 2 * 4 + 3 * 16) << name;
  }
  WriteBytes(l.root / "pair.img", voxels.substr(0, 100));  // cut short: refused, never padded with zeros
  const std::string what = LoadMessage([&] { return LoadVolumeFile(l.root / "pair.hdr", InsideRoots(l.root)); });
  EXPECT_TRUE(Has(what, "truncated")) << what;
}

TEST(HostileFiles, InsideRootsRefusesFilesOutsideAlikeWhetherTheyExistOrNot) {
  Layout l;
  fs::create_symlink(l.secret, l.root / "link.raw");
  for (const Reference& r : References(l.secret)) {
    if (Has(r.field, "NIfTI")) continue;  // pairs are siblings, never outside
    std::string text = r.text;
    WriteBytes(l.root / r.name, text);
    const std::string existing = LoadMessage([&] { return LoadVolumeFile(l.root / r.name, InsideRoots(l.root)); });
    for (std::size_t at; (at = text.find("secret")) != std::string::npos;) text.replace(at, 6, "absent");
    for (std::size_t at; (at = text.find("/s%03d")) != std::string::npos;) text.replace(at, 6, "/a%03d");
    WriteBytes(l.root / r.name, text);
    const std::string missing = LoadMessage([&] { return LoadVolumeFile(l.root / r.name, InsideRoots(l.root)); });
    EXPECT_TRUE(Has(existing, std::string("'") + r.field + "'")) << existing;
    EXPECT_TRUE(Has(existing, "not a regular file inside the data roots") || Has(existing, "cannot be checked"))
        << existing;
    EXPECT_EQ(existing, missing);
    EXPECT_FALSE(Has(existing, "secret")) << existing;
  }
  WriteBytes(l.root / "link.nhdr", Nhdr("data file: link.raw"));
  const std::string link = LoadMessage([&] { return LoadVolumeFile(l.root / "link.nhdr", InsideRoots(l.root)); });
  EXPECT_TRUE(Has(link, "'data file' names a file that is not a regular file inside the data roots")) << link;
  WriteBytes(l.root / "up.nhdr", Nhdr("data file: ../outside/secret.raw"));
  const std::string up = LoadMessage([&] { return LoadVolumeFile(l.root / "up.nhdr", InsideRoots(l.root)); });
  EXPECT_EQ(up.substr(up.find(": ")), link.substr(link.find(": ")));
  // The named file itself must be inside too.
  EXPECT_TRUE(
      Has(LoadMessage([&] { return LoadVolumeFile(l.secret, InsideRoots(l.root)); }), "outside the data roots"));
}

TEST(HostileFiles, FifoAsTheVolumeFileIsRefusedWithoutBlocking) {
  ScratchDir dir;
  ASSERT_EQ(mkfifo((dir / "v.nrrd").c_str(), 0600), 0);
  const std::string what = LoadMessage([&] { return LoadVolumeFile(dir / "v.nrrd"); }, {dir / "v.nrrd"});
  EXPECT_TRUE(Has(what, "not a regular file")) << what;
}

TEST(HostileFiles, FifoOrDeviceAsDataFileIsRefusedWithoutBlocking) {
  ScratchDir dir;
  ASSERT_EQ(mkfifo((dir / "pipe.raw").c_str(), 0600), 0);
  fs::create_symlink(dir / "pipe.raw", dir / "link.raw");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"fifo.nhdr", Nhdr("data file: pipe.raw")},
      {"fifo-link.nhdr", Nhdr("data file: link.raw")},
      {"zero.nhdr", Nhdr("data file: /dev/zero")},
      {"stdin.nhdr", Nhdr("data file: -")},
      {"fifo.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                   "ElementDataFile = pipe.raw\n"},
  };
  for (const auto& [name, text] : cases) {
    WriteBytes(dir / name, text);
    // The operator's own files (kAnywhere) too: only regular files are opened.
    const std::string what = LoadMessage([&] { return LoadVolumeFile(dir / name); }, {dir / "pipe.raw"});
    EXPECT_TRUE(Has(what, "names something other than a regular file")) << name << ": " << what;
  }
}

TEST(HostileFiles, FifoInADicomFolderIsSkippedWithoutBlocking) {
  ScratchDir dir;
  ASSERT_EQ(mkfifo((dir / "slice.dcm").c_str(), 0600), 0);
  const std::string what = LoadMessage([&] { return LoadDicomSeries(dir.path()); }, {dir / "slice.dcm"});
  EXPECT_TRUE(Has(what, "no DICOM files found (0 files looked at)")) << what;
  const std::string as_file = LoadMessage([&] { return LoadVolumeFile(dir.path()); }, {dir / "slice.dcm"});
  EXPECT_TRUE(Has(as_file, "no DICOM files found")) << as_file;
}

TEST(HostileFiles, DicomFolderUploadNamesTheLabel) {
  ScratchDir dir;
  WriteBytes(dir / "notes.txt", "hello");
  LoadPolicy p = Upload();
  const std::string what = LoadMessage([&] { return LoadDicomSeries(dir.path(), {}, p); });
  EXPECT_TRUE(Has(what, std::string(kLabel) + ": no DICOM files found")) << what;
  EXPECT_FALSE(Has(what, dir.path().string())) << what;
}

TEST(HostileFiles, VoxelLimitIsCheckedBeforeReading) {
  ScratchDir dir;
  // A few bytes declaring 32^3 voxels: refused for the limit, not the missing data.
  WriteBytes(dir / "big.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 32 32 32\nencoding: raw\n"
                               "endian: little\n\n");
  LoadPolicy p = Upload();
  p.max_voxels = 4096;
  const std::string what = LoadMessage([&] { return LoadVolumeFile(dir / "big.nrrd", p); });
  EXPECT_EQ(what, std::string(kLabel) + ": 32x32x32 = 32768 voxels exceeds this server's limit of 4096 voxels");
  // Absurd sizes in a tiny file, under the default limit.
  WriteBytes(dir / "huge.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 5000 5000 5000\nencoding: raw\n"
                                "endian: little\n\n");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "huge.nrrd"); }), "exceeds the limit of 1073741824"));
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
  EXPECT_EQ(LoadPolicy().max_voxels, 1073741824u);
}

TEST(HostileFiles, GzipNiftiBombIsNotInflated) {
  ScratchDir dir;
  // 4x4x4 voxels, then 4 GiB of zeros as 4096 concatenated gzip members of
  // 1 MiB each (zlib reads on across members): about 4 MB on disk.
  const std::string member = Gzip(std::string(1 << 20, '\0'));
  std::string bomb = Gzip(Nifti("n+1", std::string(128, '\3')));
  bomb.reserve(bomb.size() + 4096 * member.size());
  for (int i = 0; i < 4096; ++i) bomb += member;
  WriteBytes(dir / "bomb.nii.gz", bomb);
  const auto start = std::chrono::steady_clock::now();
  const std::string what = LoadMessage([&] { return LoadVolumeFile(dir / "bomb.nii.gz", Upload()); });
  EXPECT_EQ(what, "(loaded)");
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
  // A voxel offset far past the header would be inflated up to: refused. So is
  // one past any integer, or not a number (fuzz_volume: its conversion was undefined).
  for (const float far : {1e12f, 1.7e28f, std::numeric_limits<float>::quiet_NaN()}) {
    WriteBytes(dir / "far.nii.gz", Gzip(Nifti("n+1", std::string(128, '\3'), far)) + member);
    EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "far.nii.gz", Upload()); }), "vox_offset")) << far;
  }
}

TEST(HostileFiles, LabelsReplacePathsInItkMessages) {
  ScratchDir dir;
  WriteBytes(dir / "bad.nrrd", "NRRD0004\ntype: nonsense\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n" +
                                   std::string(8, '\0'));
  const std::string what = LoadMessage([&] { return LoadVolumeFile(dir / "bad.nrrd", Upload()); });
  EXPECT_EQ(what.rfind(std::string(kLabel) + ": ", 0), 0u) << what;
  EXPECT_FALSE(Has(what, dir.path().string())) << what;
  EXPECT_FALSE(Has(what, "bad.nrrd")) << what;
  EXPECT_FALSE(Has(what, ".cxx")) << what;
  EXPECT_FALSE(Has(what, "0x")) << what;  // no library internals
  EXPECT_TRUE(Has(what, "nonsense")) << what;
  // Without a label the path is named, as before.
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "bad.nrrd"); }), "bad.nrrd"));
  // A short payload is refused before teem reads it (teem leaked on it); that
  // message, like teem's own, names the label and never the file.
  WriteBytes(dir / "short.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 16 16 16\nencoding: raw\n"
                                 "endian: little\n\n" + std::string(100, '\1'));
  const std::string short_what = LoadMessage([&] { return LoadVolumeFile(dir / "short.nrrd", Upload()); });
  EXPECT_EQ(short_what.rfind(std::string(kLabel) + ": ", 0), 0u) << short_what;
  EXPECT_FALSE(Has(short_what, "short.nrrd")) << short_what;
  EXPECT_FALSE(Has(short_what, dir.path().string())) << short_what;
  EXPECT_TRUE(Has(short_what, "truncated")) << short_what;
}

TEST(HostileFiles, LenientNrrdRewriteKeepsThePolicy) {
  Layout l;
  const std::string spaced = "NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\n"
                             "sizes: 2 2 2\nspacings: 1 1 2\nencoding: raw\n";
  // Attached voxels: the copy reads them from the file itself.
  WriteBytes(l.root / "attached.nrrd", spaced + "\n" + std::string("\1\2\3\4\5\6\7\x08", 8));
  const Volume v = LoadVolumeFile(l.root / "attached.nrrd", Upload());
  EXPECT_EQ(v.Value(1, 1, 1), 8.0f);
  EXPECT_FLOAT_EQ(v.spacing_mm().z, 2.0f);
  // A detached pair inside the roots, in any spelling, loads; one leading out does not.
  WriteBytes(l.root / "in.nhdr", spaced + "datafile: in.raw\n");
  EXPECT_EQ(LoadVolumeFile(l.root / "in.nhdr", InsideRoots(l.root)).Value(1, 1, 1), 8.0f);
  WriteBytes(l.root / "out.nhdr", spaced + "datafile: ../outside/secret.raw\n");
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(l.root / "out.nhdr", InsideRoots(l.root)); }),
                  "not a regular file inside the data roots"));
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(l.root / "in.nhdr", Upload()); }), "self-contained"));
}

// Found by tests/fuzz (libFuzzer). Each was a crash, a leak or an unbounded
// allocation inside ITK, teem or GDCM; the loaders now refuse the input
// before those libraries see it.

// A LOCAL MetaImage short by less than its header: the file's whole size
// used to be compared with the voxels, so the header hid the shortfall.
TEST(HostileFiles, ShortLocalMetaImageIsTruncated) {
  ScratchDir dir;
  const std::string header = "ObjectType = Image\nNDims = 3\nDimSize = 8 8 8\nElementType = MET_SHORT\n"
                             "ElementDataFile = LOCAL\n";
  WriteBytes(dir / "m.mha", header + std::string(8 * 8 * 8 * 2 - 10, '\0'));
  const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / "m.mha", Upload()); });
  EXPECT_TRUE(Has(message, "truncated")) << message;
}

// MetaIO allocates CompressedDataSize bytes before reading: a few bytes of
// file declaring gigabytes.
TEST(HostileFiles, MetaImageCompressedDataSizeIsBoundedByTheFile) {
  ScratchDir dir;
  WriteBytes(dir / "c.mha", "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\n"
                            "CompressedData = True\nCompressedDataSize = 4000000000\nElementDataFile = LOCAL\n" +
                                Gzip(std::string(128, '\0')));
  const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / "c.mha", Upload()); });
  EXPECT_TRUE(Has(message, "CompressedDataSize")) << message;
}

// MetaIO inflated a compressed payload without checking zlib's answer: a
// damaged or short stream loaded as garbage, and its streamed reading leaked
// its buffers (33 bytes per load). The stream is inflated first now.
TEST(HostileFiles, DamagedCompressedMetaImageIsRefused) {
  ScratchDir dir;
  std::string voxels;
  for (int i = 0; i < 64; ++i) voxels += std::string{char(i), '\0'};  // int16 0..63, little-endian
  const std::string gz = Gzip(voxels);
  const std::string header = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\n"
                             "ElementByteOrderMSB = False\nCompressedData = True\n";
  auto local = [&](const std::string& stream, std::int64_t declared) {
    return header + (declared >= 0 ? "CompressedDataSize = " + std::to_string(declared) + "\n" : "") +
           "ElementDataFile = LOCAL\n" + stream;
  };
  auto load = [&](const std::string& name, const std::string& bytes) {
    WriteBytes(dir / name, bytes);
    return LoadMessage([&] { return LoadVolumeFile(dir / name, Upload()); });
  };
  // Sound streams load, with CompressedDataSize or without it.
  WriteBytes(dir / "good.mha", local(gz, std::int64_t(gz.size())));
  const Volume good = LoadVolumeFile(dir / "good.mha", Upload());
  EXPECT_EQ(good.Value(3, 3, 3), 63.0f);
  EXPECT_EQ(load("undeclared.mha", local(gz, -1)), "(loaded)");
  // A damaged stream: a flipped byte in the deflate data, or in the CRC.
  std::string bad = gz;
  bad[12] = char(bad[12] ^ 0x5a);
  std::string bad_crc = gz;
  bad_crc[bad_crc.size() - 6] = char(bad_crc[bad_crc.size() - 6] ^ 0x55);
  for (const auto& [name, bytes] : {std::pair{"bad.mha", local(bad, std::int64_t(bad.size()))},
                                    std::pair{"bad_undeclared.mha", local(bad, -1)},
                                    std::pair{"bad_crc.mha", local(bad_crc, std::int64_t(bad_crc.size()))},
                                    std::pair{"not_zlib.mha", local(std::string(40, 'x'), 40)}}) {
    const std::string message = load(name, bytes);
    EXPECT_EQ(message.rfind(std::string(kLabel) + ": compressed data are damaged", 0), 0u) << name << ": " << message;
  }
  // Short streams: cut in half, or CompressedDataSize 1 (the fuzzer's find).
  for (const auto& [name, bytes] : {std::pair{"half.mha", local(gz.substr(0, gz.size() / 2), -1)},
                                    std::pair{"one.mha", local(gz, 1)}}) {
    const std::string message = load(name, bytes);
    EXPECT_EQ(message.rfind(std::string(kLabel) + ": truncated", 0), 0u) << name << ": " << message;
  }
  // More voxels in the stream than the header describes.
  const std::string longer = Gzip(voxels + voxels);
  EXPECT_TRUE(Has(load("long.mha", local(longer, std::int64_t(longer.size()))), "damaged"));
  // CompressedDataSize past the file, or negative.
  EXPECT_TRUE(Has(load("negative.mha", local(gz, -5).replace(header.size(), 0, "CompressedDataSize = -5\n")),
                  "CompressedDataSize"));
}

// MetaIO copied a header run of 255+ characters into a 255-byte field name
// (a fortify abort): such headers are refused before MetaIO parses them.
TEST(HostileFiles, MetaImageLongHeaderRunNeverReachesMetaIO) {
  ScratchDir dir;
  const std::string rest = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                           std::string(8, '\0');
  const std::string long_key = std::string(300, 'K') + " = 1\n";
  for (const std::string& line : {"BinaryData = " + std::string(300, '\xab') + "\n", long_key,
                                  // The name in a value does not end the header for MetaIO.
                                  "Comment = ElementDataFile\n" + long_key}) {
    WriteBytes(dir / "long.mha", "ObjectType = Image\n" + line + rest);
    const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / "long.mha", Upload()); });
    EXPECT_TRUE(Has(message, "characters between separators")) << message;
  }
  // A line without '=' took the ElementDataFile line after it as its value,
  // and MetaIO read the data as header, into a long run (fuzz_volume, 2026-12-07).
  for (const std::string& line :
       {std::string("Compressed51\n"), std::string("eorCmp\x01ressed51\n"), std::string("Key\r")}) {
    WriteBytes(dir / "bare.mha", "ObjectType = Image\n" + line + rest + long_key);
    const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / "bare.mha", Upload()); });
    EXPECT_TRUE(Has(message, "header line 2 holds no '='")) << message;
  }
  // NDims -3 made MetaIO loop for hours (a fuzz_volume timeout); 11 overflows its arrays.
  for (const char* ndims : {"-3", "11", "2.5", "x"}) {
    WriteBytes(dir / "ndims.mha", std::string("ObjectType = Image\nNDims = ") + ndims + "\nDimSize = 2 2 2\n" +
                                      "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + std::string(8, '\0'));
    const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / "ndims.mha", Upload()); });
    EXPECT_TRUE(Has(message, "NDims")) << ndims << ": " << message;
  }
  // Blank lines, and lines that end in CR LF, are headers MetaIO reads.
  WriteBytes(dir / "ok.mha", "ObjectType = Image\r\n \t\n\n" + rest);
  EXPECT_EQ(LoadMessage([&] { return LoadVolumeFile(dir / "ok.mha", Upload()); }), "(loaded)");
}

// teem leaked its state (tens of KiB) on every NRRD whose voxels it could not
// read: damaged gzip, bad ASCII numbers, short raw data.
TEST(HostileFiles, NrrdPayloadIsCheckedBeforeTeemReadsIt) {
  ScratchDir dir;
  const std::string header = "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\n";
  std::string gz = Gzip(std::string(128, '\1'));
  gz[gz.size() - 6] ^= 0x55;  // the CRC
  WriteBytes(dir / "gz.nrrd", header + "encoding: gzip\n\n" + gz);
  WriteBytes(dir / "ascii.nrrd", header + "encoding: ascii\n\n1 2 3 x 5\n");
  WriteBytes(dir / "raw.nrrd", header + "encoding: raw\n\n" + std::string(100, '\0'));
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "gz.nrrd", Upload()); }), "damaged"));
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "ascii.nrrd", Upload()); }), "'x'"));
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "raw.nrrd", Upload()); }), "truncated"));
}

// GDCM asserted (aborting the server) on an unknown VR in the file meta
// group, and allocated an element's declared length (4 GiB) before reading.
TEST(HostileFiles, MalformedDicomNeverReachesGdcm) {
  ScratchDir dir;
  const std::string preamble = std::string(128, '\0') + "DICM";
  fs::create_directories(dir / "vr");
  WriteBytes(dir / "vr" / "x.dcm", preamble + std::string("\x02\0\0\0O6\x04\0\0\0\0\0", 12));
  // Only a file meta group, the file ending with it: GDCM asserted.
  fs::create_directories(dir / "meta_only");
  WriteBytes(dir / "meta_only" / "x.dcm", preamble + std::string("\x02\0\0\0UL\x04\0\xca\0\0\0", 12) +
                                              std::string("\x02\0\x01\0OB\0\0\x02\0\0\0\0\x01", 14));
  fs::create_directories(dir / "length");
  WriteBytes(dir / "length" / "x.dcm",
             preamble + std::string("\x02\0\x10\0UI\x14\0", 8) + "1.2.840.10008.1.2\0\0\0" +
                 std::string("\x08\0\x60\0\0\0\0\xf0", 8) + "CT");
  for (const char* name : {"vr", "length", "meta_only"}) {
    const std::string message = LoadMessage([&] { return LoadDicomSeries(dir / name, {}, Upload()); });
    EXPECT_TRUE(Has(message, "no DICOM files found")) << name << ": " << message;
  }
}

// A file of the fuzz corpora (`relative`: "dicom/NAME" or "volume/NAME").
std::string CorpusBytes(const std::string& relative) {
  std::ifstream in(fs::path(CINEVOL_SOURCE_DIR) / "tests/fuzz/corpus" / relative, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// `bytes` as x.dcm, the one file of folder `name` under `dir`, loaded as a
// DICOM series: what LoadMessage says of it.
std::string LoadDicomFile(const ScratchDir& dir, const std::string& name, const std::string& bytes) {
  fs::create_directories(dir / name);
  WriteBytes(dir / name / "x.dcm", bytes);
  return LoadMessage([&] { return LoadDicomSeries(dir / name, {}, Upload()); });
}

// GDCM asserted (an abort) on Samples per Pixel above 4: fuzz_volume's CT
// seed with (0028,0002) = 65281.
TEST(HostileFiles, DicomSamplesPerPixelAboveFourNeverReachesGdcm) {
  ScratchDir dir;
  std::string ct = CorpusBytes("volume/ct.dcm");
  ASSERT_GT(ct.size(), 1u);
  ct.erase(0, 1);  // fuzz_volume's format byte
  const std::string spp("\x28\0\x02\0\x02\0\0\0\x01\0", 10);  // implicit VR, US 1
  const auto at = ct.find(spp);
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(LoadDicomFile(dir, "good", ct), "(loaded)");
  ct[at + 9] = '\xff';
  const std::string message = LoadDicomFile(dir, "spp", ct);
  EXPECT_TRUE(Has(message, "no DICOM files found")) << message;
}

// GDCM's scanner asserted (an abort, in the reader's child) reading Slice
// Thickness as text where the file held a sequence there (fuzz_dicom,
// 2026-12-07): fuzz_volume's implicit-VR CT seed with (0018,0050) an
// undefined-length sequence of one empty item.
TEST(HostileFiles, DicomPublicValueAsASequenceNeverReachesGdcm) {
  ScratchDir dir;
  std::string ct = CorpusBytes("volume/ct.dcm");
  ASSERT_GT(ct.size(), 1u);
  ct.erase(0, 1);                                            // fuzz_volume's format byte
  const std::string thickness("\x18\0\x50\0\x02\0\0\0", 8);  // implicit VR, 2 bytes
  const auto at = ct.find(thickness);
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(LoadDicomFile(dir, "good", ct), "(loaded)");
  const std::string sequence(
      "\x18\0\x50\0\xff\xff\xff\xff"  // undefined length
      "\xfe\xff\0\xe0\0\0\0\0"        // an empty item
      "\xfe\xff\xdd\xe0\0\0\0\0",     // the sequence's end
      24);
  ct.replace(at, thickness.size() + 2, sequence);
  const std::string message = LoadDicomFile(dir, "sequence", ct);
  EXPECT_TRUE(Has(message, "no DICOM files found")) << message;
  EXPECT_TRUE(Has(message, "(0018,0050) is a sequence")) << message;
}

// GDCM asserted (an abort, in the reader's child) on an odd length inside a
// sequence of defined length, which the walk skipped whole: fuzz_dicom's
// enhanced CT seed, first written with a 9-byte Image Position in each
// frame's functional groups. The walk now goes into such sequences; the seed
// as written now loads.
TEST(HostileFiles, DicomOddLengthInsideADefinedLengthSequenceNeverReachesGdcm) {
  ScratchDir dir;
  const fs::path corpus = fs::path(CINEVOL_SOURCE_DIR) / "tests/fuzz/corpus/dicom";
  for (const char* name : {"regression-odd-length-in-defined-sequence.dcm", "enhanced-ct-3-phases.dcm"}) {
    fs::create_directories(dir / name);
    fs::copy_file(corpus / name, dir / name / "x.dcm");
  }
  const std::string odd = LoadMessage(
      [&] { return LoadDicomSeries(dir / "regression-odd-length-in-defined-sequence.dcm", {}, Upload()); });
  EXPECT_TRUE(Has(odd, "no DICOM files found")) << odd;
  v1::VolumeSource seed;
  seed.set_dicom_folder((dir / "enhanced-ct-3-phases.dcm").string());
  EXPECT_EQ(LoadVolumeSeries(seed, {}, Upload()).phases.size(), 3u);
}

// Inputs the fuzzers found that aborted GDCM or overran its buffers in the
// reader's child (tests/fuzz/corpus/dicom/regression-gdcm-*): each is now
// refused before GDCM sees it, by a refusal that names the file's problem.
TEST(HostileFiles, DicomFuzzFindingsAreRefusedNamingTheirProblem) {
  const struct {
    const char* file;
    const char* problem;
  } kFindings[] = {
      {"gdcm-j2k-larger-than-rows-columns-heap-overflow", "says explicit VR and its first element has no VR"},
      {"gdcm-rle-segment-count-read-overflow", "the RLE segments of fragment 1 do not fit its header"},
      {"gdcm-j2k-components-differ-from-samples-assert", "JPEG 2000 stream of fragment 1 describes another image"},
      {"gdcm-high-bit-above-bits-stored-raw-assert", "High Bit is 7, not Bits Stored (1) - 1"},
      {"gdcm-bits-allocated-12-raw-assert", "Bits Allocated is 12"},
      {"gdcm-explicit-syntax-walked-implicit-1g3-length",
       "its transfer syntax 1.2.840.10008.1.2.1 says explicit VR and its first element has no VR"},
      {"gdcm-scanner-declared-length-oom", "1.2.840.10008.1.2.2 says explicit VR"},
      // A file without the preamble whose data set starts with a meta group naming JPEG 2000:
      // GDCM decoded its 16x16 stream into a 4x4 frame (SIGSEGV in the server's fuzz run).
      {"j2k-bare-meta-group-larger-than-rows-columns", "the JPEG 2000 stream of fragment 1 describes another image"},
      // A palette icon whose tables disagree with their descriptors (GDCM read the icon's too); its
      // icon's item repeats Photometric Interpretation, which the walk meets first now.
      {"fuzz-20261205-e06a0a51", "(0028,0004) is repeated in an item"},
      // fuzz_dicom, 2026-12-07: a date as the Recognition Code (GDCM's DICOM reader asserted), and in a
      // bare data set, which GDCM reads as ACR-NEMA (its ACR-NEMA reader asserted).
      {"gdcm-recognition-code-not-acr-nema-assert", "(0008,0010) Recognition Code is not an ACR-NEMA version"},
      {"gdcm-acr-nema-libido-recognition-code-assert", "(0008,0010) Recognition Code is not an ACR-NEMA version"},
      // A repeated pixel module element, checked as GDCM reads it (the first).
      {"gdcm-repeated-bits-stored-raw-heap-overflow", "High Bit is 15, not Bits Stored (8) - 1"},
      {"gdcm-repeated-bits-allocated-24-overlay-cleanup-assert", "Bits Allocated is 24"},
      // A tag repeated in an item: GDCM's item lengths disagree, and it asserts.
      {"gdcm-repeated-in-plane-position-item-sqi2-assert", "(0020,0032) is repeated in an item"},
      {"gdcm-repeated-in-item-length-recovery-assert", "(0009,1011) is repeated in an item"},
      {"gdcm-repeated-in-item-odd-nested-length-assert", "it has a Modality LUT Sequence"},  // met first now
      // Kinds open since fuzz_dicom's 2026-12-05 run, each gone with the repeated element taken out of its item:
      // GDCM's retry through its meta group compatibility path (is.good()), its mixed explicit/implicit reader
      // ("Should not happen"), and a 2.4 GB allocation.
      {"gdcm-repeated-in-item-meta-read-compat-is-good-assert", "(0018,0050) is repeated in an item"},
      {"gdcm-repeated-in-item-read-pre-value-should-not-happen-assert", "(0028,0030) is repeated in an item"},
      {"gdcm-repeated-in-item-implicit-2g4-allocation-oom", "(0020,0032) is repeated in an item"},
      // 2 bytes of Pixel Data, not encapsulated, under JPEG 2000 (fuzz_dicom, 2026-12-05; open until now).
      {"gdcm-j2k-native-pixel-data-should-not-happen-assert", "Pixel Data is not encapsulated"},
      // fuzz_dicom seeds 31337 and 2718 (2026-12-07): no Pixel Data, whose image module GDCM reads all the
      // same (a Planar Configuration of 65535, a palette of 24 bits; an element's length and a 3.7 GB
      // allocation in its scanner); a private element first in a data set with no syntax named, which GDCM
      // reads big endian; Pixel Data repeated, native before its fragments, under JPEG 2000 (GDCM keeps
      // the first).
      {"gdcm-planar-configuration-without-pixel-data-assert", "it has no Pixel Data (7FE0,0010)"},
      {"gdcm-palette-of-24-bits-without-pixel-data-assert", "(0028,1053) Rescale Slope is 0"},  // met first now
      {"gdcm-without-pixel-data-value-length-assert",
       "a fragment of Pixel Data in a sequence has an odd length"},  // met first now: the same assertion as seed 6060's
      {"gdcm-without-pixel-data-3g7-allocation-oom", "an item stands where an element should"},  // met first now
      {"gdcm-private-element-first-read-big-endian-item-assert", "(0900,1010) declares 436207616 bytes past its end"},
      {"gdcm-j2k-repeated-pixel-data-native-first-assert", "Pixel Data is not encapsulated"},
      // fuzz_dicom seed 5555 (2026-12-07): a Modality LUT, whose output GDCM takes as the pixel format
      // (ITK's rescaling asserted); an item at an implicit VR data set's top level; a JPEG table whose
      // length does not end where the next marker starts (GDCM's JPEG header read asserted).
      {"itk-modality-lut-pixel-type-larger-than-output-assert", "it has a Modality LUT Sequence (0028,3000)"},
      {"itk-modality-lut-palette-pixel-type-assert", "it has a Modality LUT Sequence (0028,3000)"},
      {"gdcm-implicit-item-at-top-level-assert", "an item stands where an element should"},
      {"gdcm-jpeg-table-length-off-the-next-marker-assert",
       "the first fragment's JPEG marker segments do not lead from one to the next"},
      // fuzz_dicom seed 8888: a Rescale Slope of 0 in an enhanced CT's functional groups.
      {"itk-rescale-slope-zero-pixel-type-assert", "(0028,1053) Rescale Slope is 0"},
      // fuzz_dicom seed 5555, open until now: an undefined-length UN whose item holds Pixel Data with an odd
      // fragment; GDCM's implicit read of it failed, and its explicit VR retry (CP-246) asserted.
      {"gdcm-un-odd-fragment-cp246-assert", "a fragment of Pixel Data in a sequence has an odd length"},
      // fuzz_dicom seeds 6060 and 7070: an odd fragment in an item (GDCM counts it padded, against the item's
      // length); Columns 0 under JPEG (GDCM took the size from the stream's header, and asserted on its
      // precision); three JPEG streams for one frame (GDCM decodes past the frames); Bits Allocated 64 under
      // JPEG Lossless (GDCM's JPEG codec has none for it).
      {"gdcm-odd-fragment-in-icon-item-sq-length-assert", "a fragment of Pixel Data in a sequence has an odd length"},
      {"gdcm-zero-columns-with-native-icon-assert", "an image of 16 rows and 0 columns"},
      {"gdcm-zero-columns-jpeg-header-dimensions-assert", "an image of 16 rows and 0 columns"},
      {"gdcm-jpeg-streams-past-frames-nfrags-assert", "its fragments hold 3 JPEG streams for 1 frame(s)"},
      {"gdcm-jpeg-bits-allocated-64-no-codec-assert",
       "Bits Stored is 16 with Bits Allocated 64"},  // met first now; DicomJpegPast16BitsNeverReachesGdcm
      // fuzz_dicom seed 9191: a JPEG 2000 stream whose first fragment ends inside a marker segment (GDCM's
      // header parser read past it: a SEGV); three samples a pixel in a grey-scale image (its JPEG 2000
      // decoder asserted on the components); 16 bits stored of 32 (GDCM clears unused bits of 16 only).
      {"gdcm-j2k-segment-past-first-fragment-segv",
       "the JPEG 2000 stream of fragment 1 has marker segments that run past it"},
      {"gdcm-j2k-three-samples-monochrome-numcomps-assert", "Samples per Pixel is 3; cinevol reads grey-scale series"},
      {"gdcm-bits-allocated-32-stored-16-overlay-cleanup-assert",
       "Bits Stored is 16 with Bits Allocated 32; only 16-bit samples may leave bits unused"},
      // cinevol-server-fuzz seed 11 (2026-12-08): a JPEG stream whose header goes on past its first fragment
      // (GDCM read the frame header from that fragment alone, and asserted on a precision of 0).
      {"gdcm-jpeg-header-past-first-fragment-precision-assert",
       "the first fragment ends inside its JPEG header (before the scan starts)"},
  };
  ScratchDir dir;
  for (const auto& finding : kFindings) {
    const std::string message =
        LoadDicomFile(dir, finding.file, CorpusBytes(std::string("dicom/regression-") + finding.file + ".dcm"));
    EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: ")) << finding.file << ": " << message;
    EXPECT_TRUE(Has(message, finding.problem)) << finding.file << ": " << message;
  }
}

// An Explicit VR Big Endian file is walked in its own byte order (it went
// to GDCM unwalked, which asserted on a big-endian file's broken items).
TEST(HostileFiles, DicomBigEndianIsWalkedAndLoads) {
  ScratchDir dir;
  EXPECT_EQ(LoadDicomFile(dir, "be", CorpusBytes("dicom/explicit-big-endian.dcm")), "(loaded)");
  const std::string message =
      LoadDicomFile(dir, "broken", CorpusBytes("dicom/regression-gdcm-big-endian-nested-item-retry-assert.dcm"));
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads")) << message;
}

// A raw deflate stream inflated.
std::string InflateRaw(const std::string& data) {
  z_stream z{};
  inflateInit2(&z, -15);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = uInt(data.size());
  std::string out;
  int ret = Z_OK;
  while (ret == Z_OK) {
    char chunk[1 << 16];
    z.next_out = reinterpret_cast<Bytef*>(chunk);
    z.avail_out = sizeof chunk;
    ret = inflate(&z, Z_NO_FLUSH);
    out.append(chunk, sizeof chunk - z.avail_out);
  }
  inflateEnd(&z);
  return out;
}

// Where a DICOM file's meta group (explicit VR little endian, after the
// preamble) ends.
std::size_t MetaGroupEnd(const std::string& file) {
  std::size_t at = 132;
  const auto u16 = [&](std::size_t i) { return unsigned(std::uint8_t(file[i])) | unsigned(std::uint8_t(file[i + 1])) << 8; };
  while (at + 8 <= file.size() && u16(at) == 0x0002) {
    const std::string vr = file.substr(at + 4, 2);
    const bool long_vr = vr == "OB" || vr == "UN" || vr == "SQ" || vr == "UT";
    at += long_vr ? 12 + (u16(at + 8) | std::size_t(u16(at + 10)) << 16) : 8 + u16(at + 6);
  }
  return at;
}

// The 64-bit VRs (DICOM 2019): GDCM parses an Extended Offset Table
// (7FE0,0001-0002, OV), but ITK asks GDCM for each element as text, which
// asserts on them (the reader stopped by SIGABRT): refused by name.
TEST(HostileFiles, DicomExtendedOffsetTableIsRefusedByName) {
  ScratchDir dir;
  std::string file = CorpusBytes("dicom/j2k-lossless-int16.dcm");
  const std::string pixel_data("\xe0\x7f\x10\0OB\0\0\xff\xff\xff\xff", 12);
  const std::size_t at = file.find(pixel_data);
  ASSERT_NE(at, std::string::npos);
  const std::string offsets = std::string("\xe0\x7f\x01\0OV\0\0\x08\0\0\0", 12) + std::string(8, '\0');
  const std::string lengths = std::string("\xe0\x7f\x02\0OV\0\0\x08\0\0\0", 12) + std::string(8, '\0');
  file.insert(at, offsets + lengths);
  const std::string message = LoadDicomFile(dir, "eot", file);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: (7fe0,0001) has a 64-bit VR (OV)")) << message;
}

// Deflated Explicit VR Little Endian went to GDCM unwalked, and fuzz_dicom's
// deflated inputs aborted it a dozen ways (odd lengths in items, VRs the
// dictionary does not allow, ...): the data set is walked inflated now, and
// one that inflates past the walk's limit is refused before GDCM inflates it.
// The deflated seed's meta group, and its data set inflated; Rejoin deflates
// a data set (with `zeros` more bytes of zeros) behind the meta group.
struct DeflatedSeed {
  std::string meta, inflated;

  DeflatedSeed() {
    const std::string file = CorpusBytes("dicom/deflated.dcm");
    const std::size_t data_set = MetaGroupEnd(file);
    meta = file.substr(0, data_set);
    if (data_set < file.size()) inflated = InflateRaw(file.substr(data_set));
  }
  std::string Rejoin(std::size_t zeros = 0) const { return meta + Deflate(inflated, -15, zeros); }
};

TEST(HostileFiles, DicomDeflatedDataSetIsWalkedInflated) {
  ScratchDir dir;
  DeflatedSeed seed;
  const std::string bits_allocated("\x28\0\0\x01US\x02\0\x10\0", 10);
  const std::size_t at = seed.inflated.find(bits_allocated);
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(LoadDicomFile(dir, "sound", seed.Rejoin()), "(loaded)");
  seed.inflated[at + 8] = 12;
  const std::string bits = LoadDicomFile(dir, "bits", seed.Rejoin());
  EXPECT_TRUE(Has(bits, "x.dcm is not DICOM that cinevol reads: Bits Allocated is 12")) << bits;
  const std::string bomb = LoadDicomFile(dir, "bomb", seed.Rejoin(std::size_t{300} << 20));
  EXPECT_TRUE(Has(bomb, "its deflated data set inflates past 256 MiB")) << bomb;
}

// GDCM asserted (an abort, in the reader's child) reading the PET dose of
// every Deflated PET without a Radiopharmaceutical Information Sequence: its
// ReadSelectedTags seeks back in the inflating stream, which cannot (found
// by fuzz_dicom, 2026-12-07). The dose is read as the scanner reads; the
// deflated seed, made a PET, loads.
TEST(HostileFiles, DicomDeflatedPetWithoutDoseSequenceLoads) {
  ScratchDir dir;
  DeflatedSeed seed;
  const std::string modality("\x08\0\x60\0CS\x02\0CT", 10);
  const std::size_t at = seed.inflated.find(modality);
  ASSERT_NE(at, std::string::npos);
  seed.inflated.replace(at + 8, 2, "PT");
  EXPECT_EQ(LoadDicomFile(dir, "pet", seed.Rejoin()), "(loaded)");
}

// fuzz_volume's implicit-VR CT seed, without its format byte, with `bytes`
// inserted before the element that starts with `before`.
std::string CtSeedWith(const std::string& bytes, const std::string& before) {
  std::string ct = CorpusBytes("volume/ct.dcm");
  if (ct.size() < 2) return {};
  ct.erase(0, 1);
  const auto at = ct.find(before);
  if (at == std::string::npos) return {};
  return ct.insert(at, bytes);
}

// GDCM asserted (an abort, in the reader's child) on a Recognition Code
// (0008,0010) that names no ACR-NEMA version: the fuzzer had put a date
// there (fuzz_dicom, 2026-12-07).
TEST(HostileFiles, DicomRecognitionCodeNotAcrNemaNeverReachesGdcm) {
  ScratchDir dir;
  const std::string sop_class("\x08\0\x16\0", 4);
  const std::string empty = CtSeedWith(std::string("\x08\0\x10\0\0\0\0\0", 8), sop_class);
  ASSERT_FALSE(empty.empty());
  EXPECT_EQ(LoadDicomFile(dir, "empty", empty), "(loaded)");
  const std::string date = CtSeedWith(std::string("\x08\0\x10\0\x08\0\0\0", 8) + "20261126", sop_class);
  const std::string message = LoadDicomFile(dir, "date", date);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: (0008,0010) Recognition Code is not an ACR-NEMA"))
      << message;
}

// A data set that repeats a pixel module element: GDCM keeps the first, and
// the walk checked the last. An 8 for Bits Stored before the seed's 16 made
// GDCM copy pixels past its buffer (ASan); a 24 for Bits
// Allocated, an assertion (fuzz_dicom, 2026-12-07). The walk checks the first.
TEST(HostileFiles, DicomRepeatedPixelModuleElementIsCheckedAsGdcmReadsIt) {
  ScratchDir dir;
  const std::string bits_stored("\x28\0\x01\x01\x02\0\0\0", 8);  // implicit VR, 2 bytes
  const std::string later = CtSeedWith(bits_stored + std::string("\x08\0", 2), std::string("\x28\0\x02\x01", 4));
  ASSERT_FALSE(later.empty());
  EXPECT_EQ(LoadDicomFile(dir, "later", later), "(loaded)");  // the seed's 16 first
  const std::string first = CtSeedWith(bits_stored + std::string("\x08\0", 2), bits_stored);
  const std::string message = LoadDicomFile(dir, "first", first);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: High Bit is 15, not Bits Stored (8) - 1"))
      << message;
}

// GDCM keeps the first of a tag an item repeats, and reading the item it
// counts the kept elements' bytes against the item's length: it asserted
// three ways (a Plane Position read back as no sequence, an item's length
// "recovered" past it, an odd nested length; fuzz_dicom, 2026-12-07). The
// multi-frame seed with its third frame's Image Position (Patient) repeated
// in its Plane Position item is refused by name.
TEST(HostileFiles, DicomTagRepeatedInAnItemNeverReachesGdcm) {
  ScratchDir dir;
  std::string file = CorpusBytes("dicom/multiframe-uint8.dcm");
  const std::string position = std::string("\x20\0\x32\0DS\x08\0", 8) + "-1\\-1\\12";  // the third frame's
  const std::size_t at = file.find(position);
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(LoadDicomFile(dir, "sound", file), "(loaded)");
  file.insert(at + position.size(), position);  // the item's lengths are undefined: nothing else changes
  const std::string message = LoadDicomFile(dir, "repeated", file);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: (0020,0032) is repeated in an item")) << message;
}

// GDCM's JPEG and JPEG 2000 codecs read native Pixel Data of a defined
// length as fragments all the same and asserted on 2 bytes of it ("Should
// not happen", fuzz_dicom): a compressed syntax's image must be encapsulated.
TEST(HostileFiles, DicomCompressedPixelDataNotEncapsulatedNeverReachesGdcm) {
  ScratchDir dir;
  const std::pair<const char*, const char*> seeds[] = {{"j2k-lossless-int16.dcm", "1.2.840.10008.1.2.4.90"},
                                                       {"jpeg-lossless-int16.dcm", "1.2.840.10008.1.2.4.70"},
                                                       {"rle-uint8.dcm", "1.2.840.10008.1.2.5"}};
  for (const auto& [seed, syntax] : seeds) {
    std::string file = CorpusBytes(std::string("dicom/") + seed);
    const std::string pixel_data("\xe0\x7f\x10\0OB\0\0\xff\xff\xff\xff", 12);
    const std::size_t at = file.find(pixel_data);
    ASSERT_NE(at, std::string::npos) << seed;
    EXPECT_EQ(LoadDicomFile(dir, std::string("sound-") + seed, file), "(loaded)") << seed;
    file.replace(at, std::string::npos, std::string("\xe0\x7f\x10\0OW\0\0\x02\0\0\0\xfe\xff", 14));
    const std::string message = LoadDicomFile(dir, std::string("native-") + seed, file);
    EXPECT_TRUE(Has(message, std::string("x.dcm is not DICOM that cinevol reads: Pixel Data is not encapsulated, "
                                         "which its transfer syntax ") +
                                 syntax + " requires"))
        << message;
  }
}

// GDCM reads the JPEG header of an image's first fragment, and asserted on
// an empty one (a precision of 0; fuzz_dicom): it must start a JPEG stream.
TEST(HostileFiles, DicomJpegFirstFragmentWithoutAStreamNeverReachesGdcm) {
  ScratchDir dir;
  for (const char* seed : {"jpeg-baseline-uint8.dcm", "jpeg-lossless-int16.dcm", "jpegls-uint16.dcm"}) {
    std::string file = CorpusBytes(std::string("dicom/") + seed);
    const std::string pixel_data("\xe0\x7f\x10\0OB\0\0\xff\xff\xff\xff", 12);
    const std::size_t at = file.find(pixel_data);
    ASSERT_NE(at, std::string::npos) << seed;
    EXPECT_EQ(LoadDicomFile(dir, std::string("sound-") + seed, file), "(loaded)") << seed;
    // After the offset table's item: an empty fragment first.
    const std::size_t table = at + pixel_data.size();
    ASSERT_LE(table + 8, file.size());
    const std::size_t table_length = std::uint8_t(file[table + 4]) | std::size_t(std::uint8_t(file[table + 5])) << 8;
    file.insert(table + 8 + table_length, std::string("\xfe\xff\0\xe0\0\0\0\0", 8));
    const std::string message = LoadDicomFile(dir, std::string("empty-") + seed, file);
    EXPECT_TRUE(Has(message, "the first fragment holds no JPEG stream")) << seed << ": " << message;
  }
}

// GDCM's JPEG codec has coders for 8, 12 and 16 bits a sample, none past:
// it asserted on Bits Allocated 64 under JPEG Lossless (fuzz_dicom, seed 6060).
TEST(HostileFiles, DicomJpegPast16BitsNeverReachesGdcm) {
  ScratchDir dir;
  std::string file = CorpusBytes("dicom/jpeg-lossless-int16.dcm");
  for (const char element : {'\x00', '\x01'}) {  // Bits Allocated and Bits Stored: 32
    const std::string bits = std::string("\x28\0", 2) + element + std::string("\x01US\x02\0\x10\0", 7);
    const std::size_t at = file.find(bits);
    ASSERT_NE(at, std::string::npos);
    file[at + 8] = '\x20';
  }
  const std::string high_bit("\x28\0\x02\x01US\x02\0\x0f\0", 10);
  const std::size_t at = file.find(high_bit);
  ASSERT_NE(at, std::string::npos);
  file[at + 8] = '\x1f';
  const std::string message = LoadDicomFile(dir, "jpeg32", file);
  EXPECT_TRUE(
      Has(message, "x.dcm is not DICOM that cinevol reads: Bits Allocated is 32 under JPEG, which holds 16 at most"))
      << message;
}

// GDCM reads a JPEG stream's header from its first fragment alone: a frame header that goes on in the next
// fragment made it assert on a precision of 0 (cinevol-server-fuzz, seed 11). A stream whose scan alone goes on
// in later fragments is a frame split as the standard allows, and loads.
TEST(HostileFiles, DicomJpegHeaderIsReadFromTheFirstFragment) {
  const std::string file = CorpusBytes("dicom/jpeg-baseline-uint8.dcm");
  // Pixel Data (OB, undefined length), the empty offset table, then the stream's one fragment.
  const std::string pixel_data("\xe0\x7f\x10\x00OB\0\0\xff\xff\xff\xff", 12);
  const std::string item("\xfe\xff\x00\xe0", 4);
  const std::size_t table = file.find(pixel_data) + pixel_data.size();
  ASSERT_EQ(file.compare(table, 8, item + std::string(4, '\0')), 0);
  const std::size_t fragment = table + 8;
  ASSERT_EQ(file.compare(fragment, 4, item), 0);
  std::uint32_t length = 0;
  std::memcpy(&length, file.data() + fragment + 4, 4);
  const std::string stream = file.substr(fragment + 8, length);
  const std::size_t scan = stream.find("\xff\xda");
  ASSERT_GT(scan, 100u);
  const auto split_at = [&](std::size_t cut) {
    const auto item_of = [&](const std::string& bytes) {
      const std::uint32_t n = std::uint32_t(bytes.size());
      return item + std::string(reinterpret_cast<const char*>(&n), 4) + bytes;
    };
    return file.substr(0, fragment) + item_of(stream.substr(0, cut)) + item_of(stream.substr(cut)) +
           file.substr(fragment + 8 + length);
  };
  ScratchDir dir;
  for (const std::size_t cut : {std::size_t{20}, scan - scan % 2}) {  // in the first table; just before the scan
    const std::string message = LoadDicomFile(dir, "cut" + std::to_string(cut), split_at(cut));
    EXPECT_TRUE(Has(message,
                    "x.dcm is not DICOM that cinevol reads: the first fragment ends inside its JPEG "
                    "header (before the scan starts)"))
        << cut << ": " << message;
  }
  EXPECT_EQ(LoadDicomFile(dir, "scan-split", split_at(scan + 20 - scan % 2)), "(loaded)");
}

// GDCM asserted on a Planar Configuration other than 0 or 1 (fuzz_dicom).
TEST(HostileFiles, DicomPlanarConfigurationBeyondOneNeverReachesGdcm) {
  ScratchDir dir;
  std::string file = CorpusBytes("dicom/uint8.dcm");
  const std::string rows("\x28\0\x10\0US\x02\0", 8);
  const std::size_t at = file.find(rows);
  ASSERT_NE(at, std::string::npos);
  file.insert(at, std::string("\x28\0\x06\0US\x02\0\x02\0", 10));
  const std::string message = LoadDicomFile(dir, "planar", file);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: Planar Configuration is 2, not 0 or 1")) << message;
}

// With no transfer syntax named, GDCM guesses the data set's byte order
// from its first tag: a private element whose numbers pass 0xff makes it
// read the file big endian, where the walk had read it little endian and
// passed it (GDCM's item reader asserted; fuzz_dicom, 2026-12-07). The walk
// reads such a file as GDCM does; a private creator first reads little endian.
TEST(HostileFiles, DicomWithoutASyntaxIsWalkedInTheByteOrderGdcmGuesses) {
  ScratchDir dir;
  const std::string file = CorpusBytes("dicom/uint8.dcm");
  const std::string preamble = file.substr(0, 132), data_set = file.substr(MetaGroupEnd(file));
  const std::string creator = preamble + std::string("\x09\0\x10\0LO\x04\0", 8) + "ACME" + data_set;
  EXPECT_EQ(LoadDicomFile(dir, "creator", creator), "(loaded)");
  const std::string element = preamble + std::string("\x09\0\x10\x10LO\x04\0", 8) + "ACME" + data_set;
  const std::string message = LoadDicomFile(dir, "element", element);
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: (0900,1010)")) << message;
}

// An undefined-length UN holds a sequence in implicit VR (CP-246). Where
// GDCM's implicit read of it fails, GDCM reads it again as explicit VR, and
// that retry asserted on a UN whose item held Pixel Data with an odd fragment
// (fuzz_dicom seed 5555, 2026-12-07): GDCM counts the fragment padded to even,
// against the item's length. The walk refuses what fails the first read, by
// name: an odd fragment in a sequence, and anything but an item directly in
// a sequence.
TEST(HostileFiles, DicomUnSequencesAreWalkedAsGdcmReadsThem) {
  ScratchDir dir;
  const std::string file = CorpusBytes("dicom/uint8.dcm");
  const std::size_t data_set = MetaGroupEnd(file);
  const auto le32 = [](std::uint32_t v) {
    return std::string{char(v & 0xff), char(v >> 8 & 0xff), char(v >> 16 & 0xff), char(v >> 24)};
  };
  const auto mark = [&](char element, std::uint32_t length) {  // (FFFE,E0xx)
    return std::string("\xfe\xff", 2) + element + '\xe0' + le32(length);
  };
  // ACME's private (0009,1011), an undefined-length UN holding `items`.
  const auto with_un = [&](const std::string& items) {
    const std::string creator = std::string("\x09\0\x10\0LO\x04\0", 8) + "ACME";
    const std::string un = std::string("\x09\0\x11\x10UN\0\0", 8) + le32(0xffffffffu) + items + mark('\xdd', 0);
    return file.substr(0, data_set) + creator + un + file.substr(data_set);
  };
  const std::string element = std::string("\x09\0\x12\x10", 4) + le32(4) + "ABCD";  // implicit VR
  EXPECT_EQ(LoadDicomFile(dir, "item", with_un(mark('\0', 0xffffffffu) + element + mark('\x0d', 0))), "(loaded)");
  std::string message = LoadDicomFile(dir, "bare", with_un(element));
  EXPECT_TRUE(Has(message, "x.dcm is not DICOM that cinevol reads: an element stands where an item should")) << message;
  // An item of defined length holding encapsulated Pixel Data: even fragments load, an odd one does not.
  const auto pixels_item = [&](const std::string& fragment) {
    const std::string fragments =
        mark('\0', 0) + mark('\0', std::uint32_t(fragment.size())) + fragment + mark('\xdd', 0);
    const std::string pixel_data = std::string("\xe0\x7f\x10\0", 4) + le32(0xffffffffu) + fragments;
    return mark('\0', std::uint32_t(pixel_data.size())) + pixel_data;
  };
  EXPECT_EQ(LoadDicomFile(dir, "even", with_un(pixels_item("\xff\xd8\xff\xd9"))), "(loaded)");
  message = LoadDicomFile(dir, "odd", with_un(pixels_item(std::string("\xff\xd8\xff\xd9\0", 5))));
  EXPECT_TRUE(
      Has(message, "x.dcm is not DICOM that cinevol reads: a fragment of Pixel Data in a sequence has an odd length"))
      << message;
}

// ITK's factory let GDCM parse any file the volume formats declined (a
// DICOM meta group in a ".nii.gz" made GDCM assert): a single file is never
// read as DICOM.
TEST(HostileFiles, DicomContentInAVolumeFileNeverReachesGdcm) {
  ScratchDir dir;
  const std::string ct = CorpusBytes("volume/ct.dcm");
  ASSERT_GT(ct.size(), 1u);
  for (const char* name : {"x.nii.gz", "x.nii", "x.dcm"}) {
    WriteBytes(dir / name, ct.substr(1));
    const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / name, Upload()); });
    EXPECT_FALSE(message == "(loaded)") << name;
  }
}

// A NaN or infinity in a NIfTI header's orientation made ITK's vnl_svd
// abort the process (found by fuzz_volume); huge srow values made it run for
// minutes. Such headers are refused before ITK reads them.
TEST(HostileFiles, NonFiniteNiftiOrientationNeverReachesItk) {
  ScratchDir dir;
  const std::string good = Nifti("n+1", std::string(128, '\0'));
  const auto with = [&](const std::function<void(nifti_1_header&)>& edit) {
    nifti_1_header h;
    std::memcpy(&h, good.data(), sizeof h);
    edit(h);
    return std::string(reinterpret_cast<const char*>(&h), sizeof h) + good.substr(sizeof h);
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {with([](nifti_1_header& h) { h.sform_code = 1, h.srow_x[0] = NAN; }), "not a finite number"},
      {with([](nifti_1_header& h) { h.qform_code = 1, h.quatern_b = INFINITY; }), "not a finite number"},
      {with([](nifti_1_header& h) { h.pixdim[2] = NAN; }), "not a finite number"},
      {with([](nifti_1_header& h) {
         h.sform_code = 1;
         for (float* row : {h.srow_x, h.srow_y, h.srow_z}) std::fill(row, row + 4, 1e38f);
       }),
       "beyond 1000000 mm"},
  };
  for (const auto& [bytes, expected] : cases) {
    for (const char* name : {"x.nii", "x.nii.gz"}) {
      WriteBytes(dir / name, std::string(name) == "x.nii" ? bytes : Gzip(bytes));
      const std::string message = LoadMessage([&] { return LoadVolumeFile(dir / name, Upload()); });
      EXPECT_TRUE(Has(message, "the header's spacing, orientation or scaling holds a value") && Has(message, expected))
          << name << ": " << message;
    }
  }
  // Byte-swapped (the reader takes the byte order from dim[0]): the same check.
  std::string swapped = cases[0].first;
  nifti_1_header h;
  std::memcpy(&h, swapped.data(), sizeof h);
  const auto swap = [](auto& v) {
    auto* b = reinterpret_cast<unsigned char*>(&v);
    std::reverse(b, b + sizeof v);
  };
  swap(h.sizeof_hdr), swap(h.sform_code), swap(h.srow_x[0]), swap(h.datatype), swap(h.bitpix), swap(h.vox_offset);
  for (auto& d : h.dim) swap(d);
  for (auto& d : h.pixdim) swap(d);
  std::memcpy(swapped.data(), &h, sizeof h);
  WriteBytes(dir / "swapped.nii", swapped);
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "swapped.nii", Upload()); }), "not a finite number"));
  // The NIfTI-1 magic makes it a NIfTI-1 header whatever sizeof_hdr says (a fuzz_volume find).
  h.sizeof_hdr = 0x7D00015C;
  std::memcpy(swapped.data(), &h, sizeof h);
  WriteBytes(dir / "bad-size.nii", swapped);
  EXPECT_TRUE(Has(LoadMessage([&] { return LoadVolumeFile(dir / "bad-size.nii", Upload()); }), "not a finite number"));
  WriteBytes(dir / "ok.nii", with([](nifti_1_header& h) {
               h.sform_code = 1, h.srow_x[0] = h.srow_y[1] = h.srow_z[2] = 1, h.srow_x[3] = -1e5f;
             }));
  EXPECT_EQ(LoadMessage([&] { return LoadVolumeFile(dir / "ok.nii", Upload()); }), "(loaded)");
}

}  // namespace
}  // namespace cinevol
