// `cinevol info PATH`: what a volume file, DICOM folder or phantom holds.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "commands.h"
#include "core/error.h"
#include "io/label_volume.h"
#include "io/volume_loader.h"
#include "scene/presets.h"
#include "scene/volume_kind.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct InfoOptions {
  std::string path;
  std::string orientation;  // overrides the file's ("LPI")
  bool resample_uneven = false;
  std::string labels, label_table;  // a segmentation of it, and the table naming its labels
};

// A time series' phases and their times (the fields above are the first phase's).
void PrintPhases(const VolumeSeries& series) {
  fmt::print("phases:       {} (a time series; the fields here are the first phase's)\n", series.phases.size());
  if (series.seconds.empty()) {
    fmt::print("phase times:  not given by the input\n");
    return;
  }
  std::string times;
  for (double t : series.seconds) times += fmt::format("{}{:.3f}", times.empty() ? "" : " ", t);
  fmt::print("phase times:  {} s\n", times);
}

void PrintInfo(const InfoOptions& o) {
  const std::string& spec = o.path;
  v1::VolumeSource source = ParseVolumeSpec(spec);
  source.set_orientation(o.orientation);
  source.set_resample_uneven(o.resample_uneven);
  if (source.has_dicom_folder()) {
    const auto series = ListDicomSeries(source.dicom_folder());
    fmt::print("series:       {} in the folder (the largest loads)\n", series.size());
    for (const auto& s : series) {
      fmt::print("  {:<40} {:>5} files  {} {} '{}'\n", s.uid.empty() ? "(no SeriesInstanceUID)" : s.uid, s.file_count,
                 s.modality, s.size, s.description);
    }
  }
  const VolumeSeries series = LoadVolumeSeries(source);
  const Volume& v = series.phases.front();
  const auto& m = v.metadata();
  const Vec3i d = v.dims();
  const Vec3f s = v.spacing_mm(), e = v.extent_mm();
  fmt::print("source:       {}\n", m.source);
  fmt::print("modality:     {}\n", m.modality.empty() ? "unknown" : m.modality);
  fmt::print("dimensions:   {} x {} x {} voxels\n", d.x, d.y, d.z);
  fmt::print("spacing:      {:g} x {:g} x {:g} mm\n", s.x, s.y, s.z);
  fmt::print("extent:       {:g} x {:g} x {:g} mm\n", e.x, e.y, e.z);
  fmt::print("voxel type:   {} in the source, held as {}\n", m.original_type, ToString(v.storage()));
  fmt::print("value range:  {:g} .. {:g}{}\n", v.min_value(), v.max_value(),
             m.value_unit.empty() ? "" : " " + m.value_unit);
  fmt::print("orientation:  {} (index axes point to patient L/R, P/A, S/I){}\n", OrientationCode(m.direction),
             m.orientation_override.empty() ? "" : ", given with --orientation");
  fmt::print("origin:       {:g}, {:g}, {:g} mm (LPS)\n", m.origin_mm[0], m.origin_mm[1], m.origin_mm[2]);
  if (series.phases.size() > 1) PrintPhases(series);
  if (m.suv_factor > 0) {
    fmt::print("SUVbw:        value x {:.6g}\n", m.suv_factor);
  } else if (!m.suv_refused.empty()) {
    fmt::print("SUVbw:        none ({})\n", m.suv_refused);
  }
  std::size_t bytes = 0;
  for (const Volume& phase : series.phases) bytes += phase.MemoryBytes();
  fmt::print("memory:       {:.1f} MiB\n", bytes / 1048576.0);
  const VolumeKindJudgement kind = JudgeVolumeKind(v);
  fmt::print("kind:         {} ({})\n", v1::VolumeKind_Name(kind.kind), kind.reason);
  fmt::print("preset:       {} (the default for this kind)\n", DefaultPreset(kind.kind));
  if (m.non_finite_replaced > 0) {
    fmt::print("sanitised:    {} NaN/Inf voxels replaced by the finite range's ends\n", m.non_finite_replaced);
  }
  for (const std::string& note : m.notes) fmt::print("note:         {}\n", note);
  if (!o.labels.empty()) {
    v1::VolumeSource segmentation;
    segmentation.set_labels(o.labels);
    segmentation.set_label_table(o.label_table);
    PrintLabels(ToLabelSet(*LoadSceneLabels(segmentation, v)));
  } else if (!o.label_table.empty()) {
    throw InputError("--label-table: names the labels of --labels; give that too");
  }
}

}  // namespace

void AddInfoCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Print what a volume file, DICOM folder or phantom holds");
  auto o = std::make_shared<InfoOptions>();
  cmd->add_option("path", o->path, "Volume file, DICOM folder, or phantom:head|cube|sphere[?size=N&...]")->required();
  cmd->add_flag("--resample-uneven", o->resample_uneven, kResampleUnevenHelp);
  cmd->add_option("--orientation", o->orientation,
                  "Where index axes x, y, z point in the patient, overriding the file's: three letters from L/R, "
                  "P/A, S/I (e.g. LPS; LPI for a head stored top down)");
  cmd->add_option("--labels", o->labels, "A segmentation of it (label volume, NIfTI or NRRD): print its labels");
  cmd->add_option("--label-table", o->label_table, "The table naming the labels (`value<TAB>name` lines)");
  cmd->callback([o] { PrintInfo(*o); });
}

}  // namespace cinevol::cli
