// LoadVolume: one entry point for every kind of volume source.
#include "io/volume_loader.h"

#include <fmt/format.h>

#include <charconv>

#include "core/error.h"
#include "io/file_checks.h"
#include "io/formats/dicom/folder.h"
#include "io/formats/format.h"
#include "io/phantom.h"
#include "io/reader_cage.h"

namespace fs = std::filesystem;

namespace cinevol {
namespace {

fs::path Resolve(const std::string& path, const fs::path& base_dir) {
  const fs::path p(path);
  return p.is_absolute() || base_dir.empty() ? p : base_dir / p;
}

float ParseFloat(std::string_view text, std::string_view key) {
  float v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size()) {
    throw InputError(fmt::format("phantom parameter {}: '{}' is not a number", key, text));
  }
  return v;
}

v1::Phantom ParsePhantomSpec(std::string_view spec) {
  v1::Phantom p;
  const std::string_view name = spec.substr(0, spec.find('?'));
  if (name == "head") {
    p.set_kind(v1::Phantom::HEAD);
  } else if (name == "cube") {
    p.set_kind(v1::Phantom::CUBE);
  } else if (name == "sphere") {
    p.set_kind(v1::Phantom::SPHERE);
  } else {
    throw InputError(fmt::format("unknown phantom '{}': use head, cube or sphere", name));
  }
  if (name.size() == spec.size()) return p;
  std::string_view rest = spec.substr(name.size() + 1);
  while (!rest.empty()) {
    const std::string_view item = rest.substr(0, rest.find('&'));
    rest.remove_prefix(std::min(rest.size(), item.size() + 1));
    const auto eq = item.find('=');
    if (eq == std::string_view::npos) {
      throw InputError(fmt::format("phantom parameter '{}': expected key=value", item));
    }
    const std::string_view key = item.substr(0, eq);
    const float v = ParseFloat(item.substr(eq + 1), key);
    if (key == "size") {
      if (v < 1 || v > 1024 || v != static_cast<int>(v)) {
        throw InputError(fmt::format("phantom parameter size: {} is not an integer in [1, 1024]", v));
      }
      p.set_size(static_cast<std::uint32_t>(v));
    } else if (key == "spacing") {
      p.set_spacing(v);
    } else if (key == "value") {
      p.set_value(v);
    } else if (key == "background") {
      p.set_background(v);
    } else if (key == "radius") {
      p.set_radius(v);
    } else {
      throw InputError(
          fmt::format("unknown phantom parameter '{}': use size, spacing, value, background or radius", key));
    }
  }
  return p;
}

LoadPolicy Labelled(LoadPolicy policy, const fs::path& path) {
  policy.label = file_checks::Shown(path, policy);
  return policy;
}

VolumeSeries SeriesFromFolder(const fs::path& folder, const std::string& series_uid, const LoadPolicy& policy) {
  const LoadPolicy labelled = Labelled(policy, folder);
  return reader_cage::ReadDicomSeries(formats::dicom::FolderFiles(folder, labelled, labelled.label), series_uid,
                                      labelled);
}

VolumeSeries SeriesFromFile(const fs::path& path, const LoadPolicy& policy) {
  const std::string shown = file_checks::Shown(path, policy);
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw InputError(fmt::format("{}: no such file", shown));
  if (fs::is_directory(status)) return SeriesFromFolder(path, {}, policy);
  file_checks::RequireRegularFile(path, shown);
  file_checks::RequireInsideRoots(path, policy, shown);
  // Before any reader sees the file: the files its header names, found with
  // our own bounded scan of the header's text and checked against the policy.
  const formats::References refs = formats::FindReferences(path, shown);
  file_checks::CheckReferences(refs, policy, shown);
  return reader_cage::ReadVolumeFile(path, refs, policy);
}

// The one volume of `series`; a time series is refused, naming it.
Volume OnlyPhase(VolumeSeries series) {
  if (series.phases.size() > 1) {
    throw InputError(
        fmt::format("{}: a time series of {} phases, where one volume is read (a server reads every "
                    "phase: LoadVolume, docs/time-and-fusion.md)",
                    series.phases.front().metadata().source, series.phases.size()));
  }
  return std::move(series.phases.front());
}

}  // namespace

Volume LoadVolumeFile(const fs::path& path, const LoadPolicy& policy) {
  return OnlyPhase(SeriesFromFile(path, policy));
}

std::vector<DicomSeriesInfo> ListDicomSeries(const fs::path& folder, const LoadPolicy& policy) {
  const LoadPolicy labelled = Labelled(policy, folder);
  return reader_cage::ListDicomSeries(formats::dicom::FolderFiles(folder, labelled, labelled.label), labelled);
}

Volume LoadDicomSeries(const fs::path& folder, const std::string& series_uid, const LoadPolicy& policy) {
  return OnlyPhase(SeriesFromFolder(folder, series_uid, policy));
}

v1::VolumeSource ParseVolumeSpec(std::string_view spec) {
  v1::VolumeSource source;
  constexpr std::string_view kPhantom = "phantom:";
  std::error_code ec;
  if (spec.rfind(kPhantom, 0) == 0) {
    *source.mutable_phantom() = ParsePhantomSpec(spec.substr(kPhantom.size()));
  } else if (fs::is_directory(fs::path(spec), ec)) {
    source.set_dicom_folder(std::string(spec));
  } else {
    source.set_file(std::string(spec));
  }
  return source;
}

std::array<double, 9> ParseOrientation(const std::string& code, const std::string& field) {
  const auto direction = DirectionOfCode(code);
  if (!direction) {
    throw InputError(
        fmt::format("{}: '{}' is not an orientation: three letters naming where index axes x, y and z "
                    "point, one of L/R, one of P/A and one of S/I (e.g. LPS, or LPI for a head stored "
                    "top down)",
                    field, code.substr(0, 16)));
  }
  return *direction;
}

void ApplyOrientation(Volume& volume, const std::string& code, const std::string& field) {
  if (!code.empty()) volume.Reorient(ParseOrientation(code, field), code);
}

VolumeSeries LoadVolumeSeries(const v1::VolumeSource& source, const fs::path& base_dir, const LoadPolicy& policy) {
  if (!source.orientation().empty()) ParseOrientation(source.orientation(), "volume.orientation");  // before reading
  VolumeSeries series = [&] {
    switch (source.source_case()) {
      case v1::VolumeSource::kFile:
        return SeriesFromFile(Resolve(source.file(), base_dir), policy);
      case v1::VolumeSource::kDicomFolder: {
        LoadPolicy series_policy = policy;
        series_policy.resample_uneven = policy.resample_uneven || source.resample_uneven();
        return SeriesFromFolder(Resolve(source.dicom_folder(), base_dir), source.series_uid(), series_policy);
      }
      case v1::VolumeSource::kPhantom: {
        VolumeSeries one;
        one.phases.push_back(MakePhantom(source.phantom()));
        return one;
      }
      default:
        throw InputError("volume: no source given (file, dicomFolder or phantom)");
    }
  }();
  for (Volume& phase : series.phases) ApplyOrientation(phase, source.orientation(), "volume.orientation");
  return series;
}

Volume LoadVolume(const v1::VolumeSource& source, const fs::path& base_dir, const LoadPolicy& policy) {
  return OnlyPhase(LoadVolumeSeries(source, base_dir, policy));
}

}  // namespace cinevol
