// `cinevol volumes list|load|upload|describe|unload --server ADDR`: the
// volumes a server holds, as tables for people or proto3 JSON (--json).
#include <filesystem>

#include <fmt/format.h>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct VolumesOptions {
  ConnectionOptions connection;
  bool json = false;
  std::string argument;  // the path, file or id the subcommand acts on
  std::string series;    // load: a DICOM folder's series
  std::string orientation;  // load, upload: overrides the file's ("LPI")
  bool resample_uneven = false;  // load: a DICOM series' uneven gaps resampled
  std::string volume_id, table;  // labels: the volume they segment, and their label table
  bool upload = false;           // labels: the path is a local file to send
};

constexpr const char* kOrientationHelp =
    "Where index axes x, y, z point in the patient, overriding the file's: three letters from L/R, P/A, S/I "
    "(e.g. LPS; LPI for a head stored top down)";

// A volume the server answered with: all its fields, or its JSON.
void Show(const v1::VolumeInfo& volume, bool json) {
  if (json) return PrintJson(volume);
  PrintVolume(volume);
}

void List(const VolumesOptions& o) {
  const std::vector<v1::VolumeInfo> volumes = Connect(o.connection).ListVolumes();
  if (!o.json) return PrintVolumeTable(volumes);
  v1::ListVolumesResponse response;
  response.mutable_volumes()->Assign(volumes.begin(), volumes.end());
  PrintJson(response);
}

void Load(const VolumesOptions& o) {
  Show(Connect(o.connection).LoadVolume(o.argument, o.series, o.orientation, o.resample_uneven), o.json);
}

void Upload(const VolumesOptions& o) {
  if (!std::filesystem::is_regular_file(o.argument)) {
    throw InputError(fmt::format("{}: not a file that can be read", o.argument));
  }
  Show(Connect(o.connection).UploadVolume(o.argument, o.orientation), o.json);
}

void Labels(const VolumesOptions& o) {
  Client client = Connect(o.connection);
  if (!o.upload) return Show(client.LoadLabels(o.volume_id, o.argument, o.table), o.json);
  for (const std::string& file : {o.argument, o.table}) {
    if (!file.empty() && !std::filesystem::is_regular_file(file)) {
      throw InputError(fmt::format("{}: not a file that can be read", file));
    }
  }
  Show(client.UploadLabels(o.volume_id, o.argument, o.table), o.json);
}

void Describe(const VolumesOptions& o) { Show(Connect(o.connection).DescribeVolume(o.argument), o.json); }

void Unload(const VolumesOptions& o) {
  Connect(o.connection).UnloadVolume(o.argument);
  if (o.json) return PrintJson(v1::UnloadVolumeResponse());
  fmt::print("unloaded {}\n", o.argument);
}

// Runs `run`; a call past its deadline says which flag gives it more time.
void RunWithTimeout(const std::string& name, void (*run)(const VolumesOptions&), const VolumesOptions& o) {
  try {
    run(o);
  } catch (const RpcError& e) {
    if (e.code() != grpc::StatusCode::DEADLINE_EXCEEDED) throw;
    throw RpcError({grpc::StatusCode::DEADLINE_EXCEEDED,
                    fmt::format("volumes {}: the server did not answer within {:g} s, so the call (and the server's "
                                "work on it) was cancelled: a large volume takes longer; give --timeout more seconds",
                                name, o.connection.call_seconds)});
  }
}

// A subcommand of `volumes` with the connection options, --timeout and
// --json that calls `run`; `o` receives the options it fills, for the
// subcommand's own to add to.
CLI::App* AddVolumesSubcommand(CLI::App* volumes, const std::string& name, const std::string& help,
                               void (*run)(const VolumesOptions&), std::shared_ptr<VolumesOptions>& o) {
  auto* cmd = volumes->add_subcommand(name, help);
  o = std::make_shared<VolumesOptions>();
  AddConnectionOptions(cmd, o->connection);
  AddCallTimeoutOption(cmd, o->connection);
  cmd->add_flag("--json", o->json, "Print the server's answer as proto3 JSON (one object)");
  cmd->callback([o, run, name] { RunWithTimeout(name, run, *o); });
  return cmd;
}

}  // namespace

void AddVolumesCommand(CLI::App& app) {
  auto* volumes = app.add_subcommand(
      "volumes", "List, load, upload, describe or unload a server's volumes, or load their segmentations");
  volumes->require_subcommand(1);
  std::shared_ptr<VolumesOptions> o;
  AddVolumesSubcommand(volumes, "list", "The volumes the server holds", List, o);

  auto* load =
      AddVolumesSubcommand(volumes, "load", "Load a file or DICOM folder under the server's data roots", Load, o);
  load->add_option("path", o->argument, "Path on the server: absolute, or relative to its first data root")
      ->required();
  load->add_option("--series", o->series, "DICOM folders: the SeriesInstanceUID to load (default the largest)");
  load->add_option("--orientation", o->orientation, kOrientationHelp);
  load->add_flag("--resample-uneven", o->resample_uneven, kResampleUnevenHelp);

  auto* upload = AddVolumesSubcommand(
      volumes, "upload", "Send a local volume file (.nii, .nii.gz, .nrrd, .nrrd.gz, .mha, .vtk) to the server", Upload,
      o);
  upload->add_option("file", o->argument, "Local volume file; its voxels must be in the same file")->required();
  upload->add_option("--orientation", o->orientation, kOrientationHelp);

  auto* labels = AddVolumesSubcommand(
      volumes, "labels",
      "Load a segmentation (a label volume, NIfTI or NRRD; or a DICOM SEG, .dcm) for a volume the server holds",
      Labels, o);
  labels->add_option("id", o->volume_id, "Volume id the labels segment")->required();
  labels->add_option("path", o->argument,
                     "Label volume or DICOM SEG (a .dcm, or on the server a folder holding one): a path on the "
                     "server, or a local file with --upload")
      ->required();
  labels->add_option("--table", o->table, "Label table (`value<TAB>name` lines), on the server or local with --upload");
  labels->add_flag("--upload", o->upload, "Send local files instead of naming files on the server");

  auto* describe =
      AddVolumesSubcommand(volumes, "describe", "Every field of one volume, its histogram drawn", Describe, o);
  describe->add_option("id", o->argument, "Volume id (see `cinevol volumes list`)")->required();

  auto* unload = AddVolumesSubcommand(volumes, "unload", "Free a volume no session renders", Unload, o);
  unload->add_option("id", o->argument, "Volume id")->required();
}

}  // namespace cinevol::cli
