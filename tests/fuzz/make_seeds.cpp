// Writes the fuzz targets' seed corpora (tests/fuzz/corpus/): small valid
// volume files, one per format, each prefixed by the byte fuzz_volume reads
// its format from, and session requests in wire form, each prefixed by the
// byte fuzz_requests reads the message type from. Run from the fuzz build:
//   build-fuzz/fuzz_seeds tests/fuzz/corpus
// fuzz_scene's seeds are examples/*.json (run.sh adds them).
#include <gdcmAttribute.h>
#include <gdcmImage.h>
#include <gdcmImageWriter.h>
#include <google/protobuf/util/json_util.h>
#include <nifti/nifti1.h>
#include <zlib.h>

#include <sstream>

#include "cinevol/v1/service.pb.h"

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

// fuzz_volume's format bytes.
enum : char { kNii = 0, kNiiGz = 1, kNrrd = 2, kMha = 3, kVtk = 4, kDicom = 5 };

void Write(const fs::path& path, char format, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << format << bytes;
}

std::string Gzip(const std::string& data) {
  std::string out(compressBound(uLong(data.size())) + 32, '\0');
  z_stream z{};
  deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = uInt(data.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = uInt(out.size());
  deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

// n^3 int16 voxels: a small gradient.
std::string Voxels(int n) {
  std::string v;
  for (int i = 0; i < n * n * n; ++i) {
    const std::int16_t x = std::int16_t(i * 7 - 100);
    v.append(reinterpret_cast<const char*>(&x), 2);
  }
  return v;
}

std::string Nifti(int n) {
  nifti_1_header h;
  std::memset(&h, 0, sizeof h);
  h.sizeof_hdr = 348;
  h.dim[0] = 3;
  h.dim[1] = h.dim[2] = h.dim[3] = short(n);
  h.datatype = DT_INT16;
  h.bitpix = 16;
  h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = 1.0f;
  h.vox_offset = 352;
  h.scl_slope = 1.0f;
  h.qform_code = 1;
  h.quatern_d = 1.0f;
  std::memcpy(h.magic, "n+1", 4);
  return std::string(reinterpret_cast<const char*>(&h), sizeof h) + std::string(4, '\0') + Voxels(n);
}

bool WriteDicom(const fs::path& path) {
  constexpr int n = 4;
  gdcm::ImageWriter w;
  gdcm::Image& image = w.GetImage();
  image.SetNumberOfDimensions(2);
  image.SetDimension(0, n);
  image.SetDimension(1, n);
  image.SetPixelFormat(gdcm::PixelFormat::INT16);
  image.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
  image.SetSpacing(0, 0.5);
  image.SetSpacing(1, 0.5);
  image.SetOrigin(0, -1.0);
  image.SetOrigin(1, -1.0);
  image.SetOrigin(2, 10.0);
  const double cosines[6] = {1, 0, 0, 0, 1, 0};
  image.SetDirectionCosines(cosines);
  image.SetIntercept(-1024);
  image.SetSlope(1);
  std::vector<std::int16_t> pixels(n * n);
  for (int i = 0; i < n * n; ++i) pixels[i] = std::int16_t(1000 + 10 * i);
  gdcm::DataElement pixel(gdcm::Tag(0x7fe0, 0x0010));
  pixel.SetByteValue(reinterpret_cast<const char*>(pixels.data()), std::uint32_t(pixels.size() * 2));
  image.SetDataElement(pixel);
  gdcm::DataSet& ds = w.GetFile().GetDataSet();
  gdcm::Attribute<0x0008, 0x0060> modality{"CT"};
  ds.Replace(modality.GetAsDataElement());
  gdcm::Attribute<0x0020, 0x000e> series{"1.2.826.0.1.3680043.2.1125.1.1"};
  ds.Replace(series.GetAsDataElement());
  gdcm::Attribute<0x0020, 0x000d> study{"1.2.826.0.1.3680043.2.1125.1.2"};
  ds.Replace(study.GetAsDataElement());
  gdcm::Attribute<0x0008, 0x0018> sop{"1.2.826.0.1.3680043.2.1125.1.3"};
  ds.Replace(sop.GetAsDataElement());
  gdcm::Attribute<0x0008, 0x0016> sop_class{"1.2.840.10008.5.1.4.1.1.2"};
  ds.Replace(sop_class.GetAsDataElement());
  gdcm::Attribute<0x0020, 0x0013> number{1};
  ds.Replace(number.GetAsDataElement());
  gdcm::Attribute<0x0018, 0x0050> thickness{1.0};
  ds.Replace(thickness.GetAsDataElement());
  w.GetFile().GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  w.SetFileName(path.c_str());
  return w.Write();
}

namespace v1 = cinevol::v1;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// fuzz_requests' seeds: the message type byte, then the wire form.
void WriteMessage(const fs::path& path, char kind, const google::protobuf::Message& m) {
  Write(path, kind, m.SerializeAsString());
}

bool WriteRequestSeeds(const fs::path& out) {
  fs::create_directories(out);
  v1::CreateSessionRequest create;
  create.set_volume_id("head");
  create.mutable_viewport()->set_width(64);
  create.mutable_viewport()->set_height(48);
  create.set_preset("ct-bone");
  create.mutable_stream()->set_denoiser(v1::DENOISER_SVGF);
  create.mutable_stream()->set_jpeg_quality(60);
  WriteMessage(out / "create-preset", 0, create);
  v1::Scene example;
  for (const char* name : {"ct-bone", "mr-head"}) {
    v1::Scene scene;
    if (!google::protobuf::util::JsonStringToMessage(
             ReadText(fs::path(CINEVOL_SOURCE_DIR) / "examples" / (std::string(name) + ".json")), &scene)
             .ok()) {
      return false;
    }
    v1::CreateSessionRequest c = create;
    *c.mutable_scene() = scene;
    WriteMessage(out / (std::string("create-") + name), 0, c);
    if (example.lights_size() == 0) example = scene;
  }
  v1::SessionEvent e;
  e.set_seq(1);
  *e.mutable_camera() = example.camera();
  WriteMessage(out / "event-camera", 1, e);
  *e.mutable_lights()->mutable_lights() = example.lights();
  WriteMessage(out / "event-lights", 1, e);
  *e.mutable_transfer_function() = example.transfer_function();
  WriteMessage(out / "event-tf", 1, e);
  e.mutable_render()->set_spp(4);
  e.mutable_render()->set_max_bounces(3);
  e.mutable_render()->set_seed(7);
  WriteMessage(out / "event-render", 1, e);
  e.mutable_stream()->set_target_spp(128);
  e.mutable_stream()->set_chroma(v1::CHROMA_444);
  WriteMessage(out / "event-stream", 1, e);
  e.mutable_resize()->set_width(320);
  e.mutable_resize()->set_height(200);
  WriteMessage(out / "event-resize", 1, e);
  e.mutable_pause();
  WriteMessage(out / "event-pause", 1, e);
  v1::SnapshotRequest snap;
  snap.set_session_id("s");
  snap.set_spp(64);
  snap.set_format(v1::ImageFormat(1));
  WriteMessage(out / "snapshot", 2, snap);
  v1::StreamSettings stream;
  stream.set_denoiser(v1::DENOISER_KNN);
  stream.set_demodulate(true);
  stream.set_final_jpeg_quality(90);
  stream.set_target_spp(64);
  WriteMessage(out / "stream", 3, stream);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: fuzz_seeds CORPUS_DIR (tests/fuzz/corpus)\n";
    return 2;
  }
  if (!WriteRequestSeeds(fs::path(argv[1]) / "requests")) {
    std::cerr << "cannot read the example scenes\n";
    return 1;
  }
  const fs::path out = fs::path(argv[1]) / "volume";
  fs::create_directories(out);
  const std::string v = Voxels(4);
  Write(out / "nifti1.nii", kNii, Nifti(4));
  std::string pair = Nifti(3);
  std::memcpy(pair.data() + 344, "ni1\0", 4);  // a .hdr/.img pair's magic: an upload refuses it
  Write(out / "nifti1-pair-magic.nii", kNii, pair);
  Write(out / "nifti1.nii.gz", kNiiGz, Gzip(Nifti(4)));
  Write(out / "raw.nrrd", kNrrd,
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nspacings: 0.5 0.5 2\nencoding: raw\n"
        "endian: little\n\n" + v);
  Write(out / "gzip.nrrd", kNrrd,
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nspace: left-posterior-superior\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\nencoding: gzip\nendian: little\n\n" +
            Gzip(v));
  Write(out / "ascii.nrrd", kNrrd,
        "NRRD0004\ntype: float\ndimension: 2\nsizes: 3 2\nencoding: ascii\n\n1 2 3\n4 5 6\n");
  Write(out / "local.mha", kMha,
        "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementSpacing = 0.5 0.7 2.5\nModality = MET_MOD_CT\n"
        "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" + v);
  Write(out / "compressed.mha", kMha,
        "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nCompressedData = True\n"
        "CompressedDataSize = " + std::to_string(Gzip(v).size()) + "\nElementDataFile = LOCAL\n" + Gzip(v));
  {
    std::string big;
    for (int i = 0; i < 64; ++i) big.push_back(char(i));
    Write(out / "uchar.mha", kMha,
          "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nDimSize = 4 4 4\n"
          "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" + big);
  }
  {
    std::string be;  // big-endian int16 for VTK binary
    for (std::size_t i = 0; i < v.size(); i += 2) be += std::string{v[i + 1], v[i]};
    Write(out / "binary.vtk", kVtk,
          "# vtk DataFile Version 3.0\nseed\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 4 4\n"
          "SPACING 1 1 2\nORIGIN 0 0 0\nPOINT_DATA 64\nSCALARS s short 1\nLOOKUP_TABLE default\n" + be);
    Write(out / "ascii.vtk", kVtk,
          "# vtk DataFile Version 3.0\nseed\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\n"
          "SPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA 8\nSCALARS s float 1\nLOOKUP_TABLE default\n"
          "0 1 2 3 4 5 6 7\n");
  }
  const fs::path dicom = fs::temp_directory_path() / "cinevol-seed.dcm";
  if (!WriteDicom(dicom)) {
    std::cerr << "cannot write the DICOM seed\n";
    return 1;
  }
  std::ifstream in(dicom, std::ios::binary);
  Write(out / "ct.dcm", kDicom, std::string(std::istreambuf_iterator<char>(in), {}));
  fs::remove(dicom);
  std::cout << "wrote seeds under " << argv[1] << "\n";
  return 0;
}
