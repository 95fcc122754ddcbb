// Writes the fuzz targets' seed corpora (tests/fuzz/corpus/): small valid
// volume files, one per format, each prefixed by the byte fuzz_volume reads
// its format from; session requests in wire form, each prefixed by the byte
// fuzz_requests reads the message type from; and DICOM files for fuzz_dicom
// (corpus/dicom/: each transfer syntax GDCM writes, JPEG 2000 among them,
// colour models, palettes, frames, an icon, 1 to 3 slices); and what a PACS
// answers for fuzz_pacs (corpus/pacs/). Run from the fuzz build:
//   build-fuzz/fuzz_seeds tests/fuzz/corpus
// fuzz_scene's seeds are examples/*.json (run.sh adds them). The inputs that
// once crashed (corpus/*/regression-*) are kept as they were found.
#include <gdcmAttribute.h>
#include <gdcmImage.h>
#include <gdcmImageChangeTransferSyntax.h>
#include <gdcmImageWriter.h>
#include <gdcmJPEG2000Codec.h>
#include <gdcmSmartPointer.h>
#include <google/protobuf/util/json_util.h>
#include <nifti/nifti1.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"
#include "dicom_model.h"
#include "pacs/handmade_sr.h"
#include "pacs/measurement_report.h"
#include "pacs/multipart.h"
#include "pacs/presentation_state.h"
#include "runtime/presentation_store.h"
#include "scene/scene_file.h"

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

std::string Nifti(int n, float spacing = 1.0f) {
  nifti_1_header h;
  std::memset(&h, 0, sizeof h);
  h.sizeof_hdr = 348;
  h.dim[0] = 3;
  h.dim[1] = h.dim[2] = h.dim[3] = short(n);
  h.datatype = DT_INT16;
  h.bitpix = 16;
  h.pixdim[1] = h.pixdim[2] = h.pixdim[3] = spacing;
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

// ---- fuzz_dicom's seeds

namespace fz = cinevol::fuzz;

struct DicomSeed {
  std::string name;
  gdcm::PixelFormat format = gdcm::PixelFormat::INT16;
  gdcm::PhotometricInterpretation::PIType photometric = gdcm::PhotometricInterpretation::MONOCHROME2;
  int size = 4;  // rows and columns
  int frames = 1;
  gdcm::TransferSyntax::TSType syntax = gdcm::TransferSyntax::ExplicitVRLittleEndian;
  bool lossy = false;  // JPEG 2000: irreversible, at a rate
  int slices = 1;      // what fuzz_dicom makes of it: the preamble's first byte
};

// A small image of `seed`'s kind as GDCM writes it, with the elements a
// series needs (position, orientation, series UID).
std::string GdcmDicom(const DicomSeed& seed) {
  const int n = seed.size;
  // GDCM's writers and filters hold their images by counted pointers: on the heap.
  const gdcm::SmartPointer<gdcm::Image> owned = new gdcm::Image;
  gdcm::Image& image = *owned;
  image.SetNumberOfDimensions(seed.frames > 1 ? 3 : 2);
  image.SetDimension(0, unsigned(n));
  image.SetDimension(1, unsigned(n));
  if (seed.frames > 1) image.SetDimension(2, unsigned(seed.frames));
  image.SetPixelFormat(seed.format);
  image.SetPhotometricInterpretation(seed.photometric);
  image.SetSpacing(0, 0.5);
  image.SetSpacing(1, 0.5);
  image.SetOrigin(0, -1.0);
  image.SetOrigin(1, -1.0);
  image.SetOrigin(2, 10.0);
  const double cosines[6] = {1, 0, 0, 0, 1, 0};
  image.SetDirectionCosines(cosines);
  if (seed.format.GetPixelRepresentation() == 1 && seed.format.GetSamplesPerPixel() == 1) {
    image.SetIntercept(-1024);
    image.SetSlope(1);
  }
  // Smooth ramps, which a coder shrinks: GDCM's JPEG 2000 encoder writes past
  // its output buffer (the raw image's size) when the code stream comes out
  // larger, as it does for noise or tiny images.
  const std::size_t samples = seed.format.GetSamplesPerPixel();
  const std::size_t sample_bytes = seed.format.GetBitsAllocated() / 8;
  const std::size_t bytes = std::size_t(n) * n * seed.frames * samples * sample_bytes;
  std::vector<char> pixels(bytes);
  for (std::size_t i = 0; i < bytes / sample_bytes; ++i) {
    const std::size_t p = i / samples, x = p % n, y = p / n % n, frame = p / (std::size_t(n) * n);
    const unsigned v = unsigned(10 * x + 7 * y + 30 * frame + 50 * (i % samples)) & 0x7f;
    for (std::size_t b = 0; b < sample_bytes; ++b) pixels[i * sample_bytes + b] = char(b == 0 ? v : 0);
  }
  gdcm::DataElement pixel(gdcm::Tag(0x7fe0, 0x0010));
  pixel.SetByteValue(pixels.data(), std::uint32_t(bytes));
  image.SetDataElement(pixel);
  const bool native = seed.syntax == gdcm::TransferSyntax::ExplicitVRLittleEndian ||
                      seed.syntax == gdcm::TransferSyntax::ImplicitVRLittleEndian ||
                      seed.syntax == gdcm::TransferSyntax::ExplicitVRBigEndian ||
                      seed.syntax == gdcm::TransferSyntax::DeflatedExplicitVRLittleEndian;
  gdcm::ImageWriter w;
  if (native) {
    image.SetTransferSyntax(seed.syntax);
    w.SetImage(image);
  } else {
    image.SetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
    gdcm::ImageChangeTransferSyntax change;
    change.SetTransferSyntax(seed.syntax);
    gdcm::JPEG2000Codec j2k;
    if (seed.lossy) {
      j2k.SetRate(0, 4);
      j2k.SetReversible(false);
      change.SetUserCodec(&j2k);
    }
    change.SetInput(image);
    if (!change.Change()) return "";
    w.SetImage(change.GetOutput());
  }
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
  std::ostringstream out;
  w.SetStream(out);
  if (!w.Write()) return "";
  return out.str();
}

// The file with the preamble's first byte asking fuzz_dicom for `slices`.
std::string WithSlices(std::string file, int slices) {
  if (file.size() > 132 && file.compare(128, 4, "DICM") == 0) file[0] = char(slices - 1);
  return file;
}

// A GDCM file changed through the tree: a palette, an icon.
std::string Edited(const std::string& bytes, const std::function<void(fz::DicomFile&)>& edit) {
  std::optional<fz::DicomFile> file = fz::ParseDicom(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  if (!file || !file->trailing.empty()) return "";
  edit(*file);
  return fz::WriteDicom(*file);
}

std::string Us(std::initializer_list<unsigned> values) {
  std::string out;
  for (unsigned v : values) out += std::string{char(v & 0xff), char(v >> 8)};
  return out;
}

bool WriteDicomSeeds(const fs::path& out) {
  fs::create_directories(out);
  using TS = gdcm::TransferSyntax;
  using PI = gdcm::PhotometricInterpretation;
  const std::vector<DicomSeed> seeds = {
      {"ct-int16.dcm"},
      {"ct-int16-3-slices.dcm", gdcm::PixelFormat::INT16, PI::MONOCHROME2, 4, 1, TS::ExplicitVRLittleEndian, false, 3},
      {"implicit-uint16-mono1.dcm", gdcm::PixelFormat::UINT16, PI::MONOCHROME1, 4, 1, TS::ImplicitVRLittleEndian},
      {"explicit-big-endian.dcm", gdcm::PixelFormat::INT16, PI::MONOCHROME2, 4, 1, TS::ExplicitVRBigEndian, false, 2},
      {"deflated.dcm", gdcm::PixelFormat::INT16, PI::MONOCHROME2, 4, 1, TS::DeflatedExplicitVRLittleEndian},
      {"j2k-lossless-int16.dcm", gdcm::PixelFormat::INT16, PI::MONOCHROME2, 16, 1, TS::JPEG2000Lossless, false, 2},
      {"j2k-lossy-uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 16, 1, TS::JPEG2000, true},
      {"j2k-lossless-uint16-3-slices.dcm", gdcm::PixelFormat::UINT16, PI::MONOCHROME2, 16, 1, TS::JPEG2000Lossless,
       false, 3},
      {"j2k-rgb.dcm", gdcm::PixelFormat(3, 8, 8, 7, 0), PI::RGB, 16, 1, TS::JPEG2000Lossless},
      {"j2k-multiframe-uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 16, 3, TS::JPEG2000Lossless},
      {"rle-uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 16, 1, TS::RLELossless},
      {"jpeg-baseline-uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 16, 1, TS::JPEGBaselineProcess1},
      {"jpeg-lossless-int16.dcm", gdcm::PixelFormat::INT16, PI::MONOCHROME2, 16, 1, TS::JPEGLosslessProcess14_1},
      {"jpegls-uint16.dcm", gdcm::PixelFormat::UINT16, PI::MONOCHROME2, 16, 1, TS::JPEGLSLossless},
      {"rgb-native.dcm", gdcm::PixelFormat(3, 8, 8, 7, 0), PI::RGB, 4, 1, TS::ExplicitVRLittleEndian},
      {"multiframe-uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 4, 3, TS::ExplicitVRLittleEndian},
      {"uint8.dcm", gdcm::PixelFormat::UINT8, PI::MONOCHROME2, 4, 1, TS::ExplicitVRLittleEndian},
  };
  std::map<std::string, std::string> written;
  for (const DicomSeed& seed : seeds) {
    const std::string bytes = GdcmDicom(seed);
    if (bytes.empty()) {
      std::cerr << "GDCM could not write " << seed.name << "\n";
      return false;
    }
    written[seed.name] = WithSlices(bytes, seed.slices);
  }
  // GDCM writes no position or orientation for a multi-frame image; a series needs them.
  for (const char* name : {"multiframe-uint8.dcm", "j2k-multiframe-uint8.dcm"}) {
    written[name] = Edited(written[name], [](fz::DicomFile& f) {
      f.Set(0x0020, 0x0032, "DS", "-1\\-1\\10");
      f.Set(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0 ");
    });
  }
  // An enhanced CT: the multi-frame image's plane, pixel measures and rescale
  // in its Shared Functional Groups, each frame's position and time (Temporal
  // Position Index, Nominal Cardiac Trigger Delay) in its Per-frame ones:
  // three phases of one slice.
  written["enhanced-ct-3-phases.dcm"] = Edited(written["multiframe-uint8.dcm"], [](fz::DicomFile& f) {
    const auto value = [](std::uint16_t g, std::uint16_t e, const char* vr, const std::string& v) {
      fz::Element x;
      x.group = g;
      x.element = e;
      x.vr = vr;
      x.value = v;
      return x;
    };
    const auto sequence = [](std::uint16_t g, std::uint16_t e, std::vector<std::vector<fz::Element>> items) {
      fz::Element x;
      x.group = g;
      x.element = e;
      x.vr = "SQ";
      x.kind = fz::Element::Kind::kSequence;
      for (auto& elements : items) x.items.push_back(fz::Item{std::move(elements)});
      return x;
    };
    std::erase_if(f.data_set, [](const fz::Element& e) { return e.tag() == 0x00200032 || e.tag() == 0x00200037; });
    f.Set(0x0008, 0x0016, "UI", std::string("1.2.840.10008.5.1.4.1.1.2.1") + '\0');  // Enhanced CT Image Storage
    f.Set(0x5200, 0x9229, "SQ", "") = sequence(
        0x5200, 0x9229,
        {{sequence(0x0020, 0x9116, {{value(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0 ")}}),
          sequence(0x0028, 0x9110, {{value(0x0018, 0x0050, "DS", "1 "), value(0x0028, 0x0030, "DS", "0.5\\0.5 ")}}),
          sequence(0x0028, 0x9145, {{value(0x0028, 0x1052, "DS", "0 "), value(0x0028, 0x1053, "DS", "1 ")}})}});
    std::vector<std::vector<fz::Element>> frames;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const double delay_ms = 40.0 * k;
      std::string ul(4, '\0'), fd(8, '\0');
      const std::uint32_t index = k + 1;
      std::memcpy(ul.data(), &index, 4);
      std::memcpy(fd.data(), &delay_ms, 8);
      frames.push_back({sequence(0x0018, 0x9118, {{value(0x0020, 0x9153, "FD", fd)}}),
                        sequence(0x0020, 0x9111, {{value(0x0020, 0x9128, "UL", ul)}}),
                        sequence(0x0020, 0x9113, {{value(0x0020, 0x0032, "DS", "-1\\-1\\10")}})});
    }
    f.Set(0x5200, 0x9230, "SQ", "") = sequence(0x5200, 0x9230, frames);
  });
  // A palette: 8-bit indices, three 256-entry 16-bit tables.
  written["palette-uint8.dcm"] = Edited(written["uint8.dcm"], [](fz::DicomFile& f) {
    f.Set(0x0028, 0x0004, "CS", "PALETTE COLOR ");
    std::string table;
    for (int i = 0; i < 256; ++i) table += Us({unsigned(i * 257)});
    for (std::uint16_t c = 0; c < 3; ++c) {
      f.Set(0x0028, std::uint16_t(0x1101 + c), "US", Us({256, 0, 16}));
      f.Set(0x0028, std::uint16_t(0x1201 + c), "OW", table);
    }
  });
  // An icon: a nested pixel module and pixel data, undefined lengths.
  written["icon-sequence.dcm"] = Edited(written["ct-int16.dcm"], [](fz::DicomFile& f) {
    fz::Item icon;
    icon.undefined_length = true;
    auto add = [&](std::uint16_t g, std::uint16_t e, const char* vr, const std::string& v) {
      fz::Element x;
      x.group = g;
      x.element = e;
      x.vr = vr;
      x.value = v;
      icon.elements.push_back(x);
    };
    add(0x0028, 0x0002, "US", Us({1}));
    add(0x0028, 0x0004, "CS", "MONOCHROME2 ");
    add(0x0028, 0x0010, "US", Us({2}));
    add(0x0028, 0x0011, "US", Us({2}));
    add(0x0028, 0x0100, "US", Us({8}));
    add(0x0028, 0x0101, "US", Us({8}));
    add(0x0028, 0x0102, "US", Us({7}));
    add(0x0028, 0x0103, "US", Us({0}));
    add(0x7fe0, 0x0010, "OB", std::string("\1\2\3\4", 4));
    fz::Element& seq = f.Set(0x0088, 0x0200, "SQ", "");
    seq.kind = fz::Element::Kind::kSequence;
    seq.undefined_length = true;
    seq.items = {icon};
  });
  for (const auto& [name, bytes] : written) {
    if (bytes.empty()) {
      std::cerr << "cannot make " << name << "\n";
      return false;
    }
    // The mutator's model must hold GDCM's files whole, byte for byte
    // (deflated ones: the same data set, compressed anew).
    const auto* data = reinterpret_cast<const std::uint8_t*>(bytes.data());
    const std::optional<fz::DicomFile> parsed = fz::ParseDicom(data, bytes.size());
    if (!parsed || !parsed->trailing.empty() || (!parsed->encoding.deflated && fz::WriteDicom(*parsed) != bytes)) {
      std::cerr << "dicom_model.h does not read " << name << " back as it was\n";
      return false;
    }
    std::ofstream(out / name, std::ios::binary) << bytes;
  }
  return true;
}

namespace v1 = cinevol::v1;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// fuzz_requests' kind 4: a volume's geometry at the extremes (dimensions 1
// to 2^31, spacing 1e-12 to 1e6 mm), then a slice request (oblique, a thick
// slab; axial).
void WriteGeometrySeeds(const fs::path& out) {
  struct Extreme {
    const char* name;
    std::uint32_t dims[3];
    float spacing[3];
  };
  const Extreme extremes[] = {{"tiny", {16, 16, 16}, {1e-12f, 1e-12f, 1e-12f}},
                              {"smallest", {8, 8, 8}, {1e-4f, 1e-4f, 1e-4f}},
                              {"sky", {2, 2, 2}, {0.62f, 1e4f, 1e4f}},
                              {"huge", {2147483647u, 1, 1}, {1e6f, 1e6f, 1e6f}},
                              {"widest", {8192, 8192, 16}, {0.5f, 0.5f, 1e-6f}}};
  for (const Extreme& e : extremes) {
    v1::SliceRequest slice;
    slice.set_axis(v1::OBLIQUE);
    slice.mutable_normal()->set_x(1);
    slice.mutable_normal()->set_z(1);
    slice.mutable_row()->set_y(1);
    slice.set_slab_mm(9999);
    slice.set_projection(v1::MEAN);
    std::string geometry(sizeof e.dims + sizeof e.spacing, '\0');
    std::memcpy(geometry.data(), e.dims, sizeof e.dims);
    std::memcpy(geometry.data() + sizeof e.dims, e.spacing, sizeof e.spacing);
    Write(out / (std::string("geometry-") + e.name), 4, geometry + slice.SerializeAsString());
    v1::SliceRequest axial;
    axial.set_axis(v1::AXIAL);
    axial.set_position_mm(1e-3);
    Write(out / (std::string("geometry-") + e.name + "-axial"), 4, geometry + axial.SerializeAsString());
  }
}

// fuzz_pacs' seeds, the first byte its kind (a Part 10 file's preamble): measurement reports as cinevol writes them
// and as OHIF does (3D and on an image), a presentation state, and a WADO-RS answer holding a report and a state.
void WritePacsSeeds(const fs::path& out) {
  namespace pacs = cinevol::pacs;
  namespace hand = cinevol::testing;
  fs::create_directories(out);
  pacs::SourceStudy study;
  study.patient_name = "Fuzz^Seed";
  study.patient_id = "FUZZ-1";
  study.study_uid = "2.25.3400900";
  study.series_uid = "2.25.3400900.1";
  pacs::ReportSource source;
  source.frame_of_reference_uid = "2.25.3400900.9";
  for (int i = 1; i <= 2; ++i)
    source.images.push_back({"1.2.840.10008.5.1.4.1.1.2", "2.25.3400900.1." + std::to_string(i)});
  const std::string report = pacs::MakeMeasurementReport(
      study, source,
      {{"aorta", {{-12.5, 45.5, -123.25}, {30.125, -80.5, 210.75}}}, {"angle", {{10, 20, 30}, {0, 0, 0}, {5, -7, 1}}}},
      "seed");
  std::ofstream(out / "sr-cinevol.dcm", std::ios::binary) << report;  // the preamble's first byte: 0
  const std::string ohif = hand::Report({
      hand::Group({hand::Tracking("Cornerstone3DTools@^0.1.0:Length"), hand::FreeTextFinding("aorta"),
                   hand::Num(hand::kLength, "mm", "42.1", hand::Scoord3d({1.5f, 2.5f, 3.5f, 10.25f, -20.5f, 30.75f}))}),
      hand::Group(
          {hand::Tracking("Cornerstone3DTools@^0.1.0:Length"), hand::FreeTextFinding("node"),
           hand::Num(hand::kLength, "mm", "28.3", hand::Scoord({10.5f, 20.5f, 30.5f, 40.5f}, "2.25.3400359.7.3"))}),
  });
  std::ofstream(out / "sr-ohif.dcm", std::ios::binary) << ohif;
  // A scene as a session stores one: patient coordinates, transfer-function points, a crop box and a capped plane.
  const v1::Scene scene = cinevol::ParseSceneJson(R"({
    "frame": "PATIENT_LPS",
    "transferFunction": {"preset": "ct-bone", "densityScale": 3, "points": [
      {"value": -200, "opacity": 0, "diffuse": {"r": 0.9, "g": 0.8, "b": 0.7}},
      {"value": 1500, "opacity": 1, "diffuse": {"r": 1, "g": 1, "b": 1}}]},
    "camera": {"eye": {"x": 10, "y": -600, "z": 40}, "target": {"x": 5, "y": -120, "z": 30},
               "up": {"x": 0, "y": 0, "z": 1}, "fovYDeg": 28},
    "render": {"width": 320, "height": 240, "spp": 64},
    "clipping": {"cropBox": {"center": {"x": 0, "y": -150, "z": -20}, "size": {"x": 250, "y": 200, "z": 400}},
                 "planes": [{"point": {"x": 30, "y": 0, "z": 0}, "normal": {"x": -1, "y": 0, "z": 0}, "cap": true}]}
  })");
  const cinevol::Volume volume({16, 16, 8}, {0.7f, 0.7f, 2.5f}, std::vector<float>(16 * 16 * 8, 0.0f), {});
  std::string state =
      pacs::MakePresentationState(study, source, cinevol::service::PresentationOf(scene, volume), "seed");
  state[0] = 1;
  std::ofstream(out / "presentation-state.dcm", std::ios::binary) << state;
  const std::string boundary = "fuzz-seed-boundary";
  Write(out / "wado-answer", 2,
        "multipart/related; type=\"application/dicom\"; boundary=" + boundary + "\n" +
            pacs::JoinMultipart({report, state}, boundary, "application/dicom"));
}

// fuzz_requests' kind 5: a frame number, then an instance's metadata: a
// single-frame axial image, and an enhanced one of two frames.
void WriteFrameSeeds(const fs::path& out) {
  const std::string matrix = R"("00280010":{"vr":"US","Value":[8]},"00280011":{"vr":"US","Value":[8]})";
  Write(out / "frame-single", 5,
        std::string(1, '\1') + "[{" + matrix + R"(,"00200032":{"vr":"DS","Value":[-8,-8,0]},)" +
            R"("00200037":{"vr":"DS","Value":[1,0,0,0,1,0]},"00280030":{"vr":"DS","Value":["2","2"]}}])");
  Write(
      out / "frame-enhanced", 5,
      std::string(1, '\2') + "[{" + matrix + R"(,"00280008":{"vr":"IS","Value":["2"]},)" +
          R"("52009229":{"vr":"SQ","Value":[{"00209116":{"vr":"SQ","Value":[{"00200037":{"vr":"DS",)" +
          R"("Value":[0,1,0,0,0,-1]}}]},"00289110":{"vr":"SQ","Value":[{"00280030":{"vr":"DS","Value":[1,1]}}]}}]},)" +
          R"("52009230":{"vr":"SQ","Value":[{"00209113":{"vr":"SQ","Value":[{"00200032":{"vr":"DS","Value":[0,0,1]}}]}},)" +
          R"({"00209113":{"vr":"SQ","Value":[{"00200032":{"vr":"DS","Value":[0,0,3]}}]}}]}}])");
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
  WriteGeometrySeeds(out);
  WriteFrameSeeds(out);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: fuzz_seeds CORPUS_DIR (tests/fuzz/corpus)\n";
    return 2;
  }
  WritePacsSeeds(fs::path(argv[1]) / "pacs");
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
  // Geometry at the extremes: refused by name, never a crash.
  Write(out / "nifti1-spacing-1e-12.nii", kNii, Nifti(4, 1e-12f));
  Write(out / "nifti1-spacing-1e6.nii", kNii, Nifti(4, 1e6f));
  Write(out / "huge-dims.nrrd", kNrrd,
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 2147483647 1 1\nspacings: 1e-12 1 1e6\nencoding: raw\n"
        "endian: little\n\n" +
            v);
  Write(out / "raw.nrrd", kNrrd,
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nspacings: 0.5 0.5 2\nencoding: raw\n"
        "endian: little\n\n" +
            v);
  Write(out / "gzip.nrrd", kNrrd,
        "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nspace: left-posterior-superior\n"
        "space directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (0,0,0)\nencoding: gzip\nendian: little\n\n" +
            Gzip(v));
  Write(out / "ascii.nrrd", kNrrd,
        "NRRD0004\ntype: float\ndimension: 2\nsizes: 3 2\nencoding: ascii\n\n1 2 3\n4 5 6\n");
  Write(out / "local.mha", kMha,
        "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementSpacing = 0.5 0.7 2.5\nModality = MET_MOD_CT\n"
        "ElementType = MET_SHORT\nElementDataFile = LOCAL\n" +
            v);
  Write(out / "compressed.mha", kMha,
        "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nCompressedData = True\n"
        "CompressedDataSize = " +
            std::to_string(Gzip(v).size()) + "\nElementDataFile = LOCAL\n" + Gzip(v));
  {
    std::string big;
    for (int i = 0; i < 64; ++i) big.push_back(char(i));
    Write(out / "uchar.mha", kMha,
          "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\nDimSize = 4 4 4\n"
          "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
              big);
  }
  {
    std::string be;  // big-endian int16 for VTK binary
    for (std::size_t i = 0; i < v.size(); i += 2) be += std::string{v[i + 1], v[i]};
    Write(out / "binary.vtk", kVtk,
          "# vtk DataFile Version 3.0\nseed\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 4 4\n"
          "SPACING 1 1 2\nORIGIN 0 0 0\nPOINT_DATA 64\nSCALARS s short 1\nLOOKUP_TABLE default\n" +
              be);
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
  if (!WriteDicomSeeds(fs::path(argv[1]) / "dicom")) return 1;
  std::cout << "wrote seeds under " << argv[1] << "\n";
  return 0;
}
