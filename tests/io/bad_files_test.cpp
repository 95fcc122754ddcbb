// Malformed volume files, generated here: each gets a clear InputError that
// names the file and the problem, never a crash.
#include <gtest/gtest.h>
#include <nifti/nifti1.h>
#include <zlib.h>

#include <cstring>
#include <fstream>
#include <limits>

#include "core/error.h"
#include "io/volume_loader.h"
#include "support/test_paths.h"

namespace cinevol {
namespace {

using testing::ScratchDir;
namespace fs = std::filesystem;

void WriteBytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

template <class T>
std::string Raw(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

// A NIfTI-1 single file with the given datatype and payload.
std::string Nifti(int nx, int ny, int nz, short datatype, short bitpix, const std::string& payload) {
  nifti_1_header h;
  std::memset(&h, 0, sizeof h);
  h.sizeof_hdr = 348;
  h.dim[0] = 3;
  h.dim[1] = nx;
  h.dim[2] = ny;
  h.dim[3] = nz;
  h.datatype = datatype;
  h.bitpix = bitpix;
  h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 1.0f;
  h.vox_offset = 352;
  h.scl_slope = 1.0f;
  std::memcpy(h.magic, "n+1\0", 4);
  return std::string(reinterpret_cast<const char*>(&h), sizeof h) + std::string(4, '\0') + payload;
}

std::string Gzip(const std::string& data) {
  uLongf size = compressBound(data.size()) + 32;
  std::string out(size, '\0');
  z_stream z{};
  deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);  // +16: gzip wrapper
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = data.size();
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = out.size();
  deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

// Expects LoadVolumeFile(path) to throw InputError whose message holds
// `fragment` and the file name.
void ExpectLoadError(const fs::path& path, const std::string& fragment) {
  try {
    const Volume v = LoadVolumeFile(path);
    ADD_FAILURE() << path << " loaded (" << v.dims().x << "x" << v.dims().y << "x" << v.dims().z
                  << ") but should have been rejected";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path.filename().string()), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << "expected '" << fragment << "' in: " << what;
  }
}

TEST(BadFiles, MissingFile) {
  ScratchDir dir;
  ExpectLoadError(dir / "absent.nii", "no such file");
}

TEST(BadFiles, UnknownFormat) {
  ScratchDir dir;
  WriteBytes(dir / "notes.txt", "hello");
  ExpectLoadError(dir / "notes.txt", "not a volume format");
}

TEST(BadFiles, TruncatedNrrd) {
  ScratchDir dir;
  WriteBytes(dir / "t.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 16 16 16\nencoding: raw\n"
                             "endian: little\n\n" + std::string(100, '\1'));
  ExpectLoadError(dir / "t.nrrd", "t.nrrd");
}

TEST(BadFiles, TruncatedNifti) {
  ScratchDir dir;
  WriteBytes(dir / "t.nii", Nifti(16, 16, 16, DT_INT16, 16, std::string(1000, '\0')));
  ExpectLoadError(dir / "t.nii", "t.nii");
}

TEST(BadFiles, TruncatedGzipNifti) {
  ScratchDir dir;
  const std::string whole = Gzip(Nifti(32, 32, 32, DT_INT16, 16, std::string(32 * 32 * 32 * 2, '\7')));
  WriteBytes(dir / "t.nii.gz", whole.substr(0, whole.size() / 2));
  ExpectLoadError(dir / "t.nii.gz", "t.nii.gz");
}

TEST(BadFiles, TruncatedGzipNrrd) {
  ScratchDir dir;
  const std::string data = Gzip(std::string(32 * 32 * 32 * 2, '\5'));
  WriteBytes(dir / "g.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 32 32 32\nencoding: gzip\n"
                             "endian: little\n\n" + data.substr(0, data.size() / 2));
  ExpectLoadError(dir / "g.nrrd", "g.nrrd");
}

TEST(BadFiles, TruncatedMetaImage) {
  ScratchDir dir;
  WriteBytes(dir / "m.raw", std::string(100, '\0'));
  WriteBytes(dir / "m.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 16 16 16\n"
                            "ElementType = MET_SHORT\nElementDataFile = m.raw\n");
  ExpectLoadError(dir / "m.mhd", "m.mhd");
}

TEST(BadFiles, TruncatedVtk) {
  ScratchDir dir;
  WriteBytes(dir / "s.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_POINTS\n"
                            "DIMENSIONS 16 16 16\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 4096\n"
                            "SCALARS s short 1\nLOOKUP_TABLE default\n" + std::string(100, '\1'));
  ExpectLoadError(dir / "s.vtk", "s.vtk");
}

TEST(BadFiles, HeaderSizeMismatch) {
  ScratchDir dir;
  WriteBytes(dir / "m.raw", std::string(32 * 32 * 31 * 2, '\0'));  // one slice short
  WriteBytes(dir / "m.nhdr", "NRRD0004\ntype: short\ndimension: 3\nsizes: 32 32 32\nencoding: raw\n"
                             "endian: little\ndata file: m.raw\n");
  ExpectLoadError(dir / "m.nhdr", "m.nhdr");
}

TEST(BadFiles, AbsurdDimensionsAreRefusedBeforeReading) {
  ScratchDir dir;
  WriteBytes(dir / "huge.nhdr", "NRRD0004\ntype: short\ndimension: 3\nsizes: 100000 100000 100000\n"
                                "encoding: raw\nendian: little\ndata file: huge.raw\n");
  WriteBytes(dir / "huge.raw", "");
  ExpectLoadError(dir / "huge.nhdr", "outside [1, 8192]");
}

TEST(BadFiles, MultiComponentVoxelsAreUnsupported) {
  ScratchDir dir;
  WriteBytes(dir / "rgb.nrrd", "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 4 4 4\n"
                               "kinds: RGB-color domain domain domain\nencoding: raw\n\n" +
                                   std::string(3 * 64, '\1'));
  ExpectLoadError(dir / "rgb.nrrd", "components per voxel");
}

TEST(BadFiles, ComplexVoxelsAreUnsupported) {
  ScratchDir dir;
  WriteBytes(dir / "c.nii", Nifti(4, 4, 4, DT_COMPLEX64, 64, std::string(64 * 8, '\0')));
  EXPECT_THROW(LoadVolumeFile(dir / "c.nii"), InputError);
}

// A 4-D file is a time series (issue 59): its phases where a server reads
// them, refused by name where one volume is read; 5-D is no volume.
TEST(BadFiles, FourDimensionalFilesAreTimeSeriesAndFiveAreRefused) {
  ScratchDir dir;
  WriteBytes(dir / "t4.nrrd", "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 4 4 4 5\n"
                              "kinds: domain domain domain domain\nencoding: raw\n\n" +
                                  std::string(4 * 4 * 4 * 5, '\1'));
  ExpectLoadError(dir / "t4.nrrd", "a time series of 5 phases");
  v1::VolumeSource source;
  source.set_file((dir / "t4.nrrd").string());
  EXPECT_EQ(LoadVolumeSeries(source).phases.size(), 5u);
  WriteBytes(dir / "t5.nrrd", "NRRD0004\ntype: uchar\ndimension: 5\nsizes: 4 4 4 2 2\n"
                              "kinds: domain domain domain domain domain\nencoding: raw\n\n" +
                                  std::string(4 * 4 * 4 * 4, '\1'));
  ExpectLoadError(dir / "t5.nrrd", "5-D");
}

TEST(BadFiles, NonFiniteVoxelsAreSanitisedAndCounted) {
  ScratchDir dir;
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> v(8, 5.0f);
  v[1] = std::nanf("");
  v[2] = inf;
  v[3] = -inf;
  v[4] = 9.0f;
  WriteBytes(dir / "nan.nrrd", "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                               "endian: little\n\n" + Raw(v));
  const Volume vol = LoadVolumeFile(dir / "nan.nrrd");
  EXPECT_EQ(vol.metadata().non_finite_replaced, 3u);
  EXPECT_EQ(vol.min_value(), 5.0f);
  EXPECT_EQ(vol.max_value(), 9.0f);
  EXPECT_EQ(vol.Value(1, 0, 0), 5.0f);  // NaN -> smallest finite
  EXPECT_EQ(vol.Value(0, 1, 0), 9.0f);  // +Inf -> largest finite
}

TEST(GoodFiles, MetaImageWithSpacing) {
  ScratchDir dir;
  std::vector<std::int16_t> v(4 * 3 * 2);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = std::int16_t(i) - 1000;
  WriteBytes(dir / "m.raw", Raw(v));
  WriteBytes(dir / "m.mhd", "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementSpacing = 0.5 0.7 2.5\n"
                            "ElementType = MET_SHORT\nModality = MET_MOD_CT\nElementDataFile = m.raw\n");
  const Volume vol = LoadVolumeFile(dir / "m.mhd");
  EXPECT_EQ(vol.dims(), (Vec3i{4, 3, 2}));
  EXPECT_FLOAT_EQ(vol.spacing_mm().y, 0.7f);
  EXPECT_EQ(vol.Value(3, 2, 1), 23.0f - 1000.0f);
  EXPECT_EQ(vol.metadata().modality, "CT");
  EXPECT_EQ(vol.metadata().value_unit, "HU");
}

TEST(GoodFiles, VtkLegacyStructuredPoints) {
  ScratchDir dir;
  std::string text =
      "# vtk DataFile Version 3.0\ncinevol test\nASCII\nDATASET STRUCTURED_POINTS\n"
      "DIMENSIONS 3 2 2\nSPACING 1.5 1.5 3\nORIGIN 0 0 0\nPOINT_DATA 12\n"
      "SCALARS density float 1\nLOOKUP_TABLE default\n";
  for (int i = 0; i < 12; ++i) text += std::to_string(i * 0.5) + "\n";
  WriteBytes(dir / "s.vtk", text);
  const Volume vol = LoadVolumeFile(dir / "s.vtk");
  EXPECT_EQ(vol.dims(), (Vec3i{3, 2, 2}));
  EXPECT_FLOAT_EQ(vol.spacing_mm().z, 3.0f);
  EXPECT_FLOAT_EQ(vol.Value(2, 1, 1), 5.5f);
  EXPECT_EQ(vol.storage(), VoxelStorage::kFloat32);
}

TEST(GoodFiles, TwoDimensionalImageIsOneSlice) {
  ScratchDir dir;
  WriteBytes(dir / "s.nrrd", "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 5 4\nencoding: raw\n\n" +
                                 std::string(20, '\3'));
  const Volume vol = LoadVolumeFile(dir / "s.nrrd");
  EXPECT_EQ(vol.dims(), (Vec3i{5, 4, 1}));
  EXPECT_EQ(vol.Value(4, 3, 0), 3.0f);
}

}  // namespace
}  // namespace cinevol
