// Session scripts: a timeline of events with times, in JSON Lines (one JSON
// object per line, so every problem names its line). docs/client.md gives
// the schema; examples/scripts/ has examples.
//
//   {"session": {"volume": "phantom:head", "preset": "ct-bone", "viewport": {"width": 640, "height": 360}}}
//   {"session": {"load": "ct/head.nii.gz"}}         (or "upload": "local/file.nrrd", relative to the script)
//   {"session": {"load": "ct/body.nii.gz", "labels": {"load": "ct/seg.nii.gz", "table": "ct/labels.tsv"}}}
//   {"session": {"series": {"pacs": "main", "studyUid": "1.2.840...", "seriesUid": "1.2.840..."}}}
//   {"at": 0.0, "orbit": {"degrees": 90, "seconds": 3}}
//   {"at": 3.5, "transferFunction": {"preset": "ct-soft-tissue"}}
//   {"at": 4.0, "render": {"spp": 4}}
//   {"at": 5.0, "slice": {"axis": "CORONAL", "positionMm": 10, "windowPreset": "bone", "out": "coronal.png"}}
//   {"at": 5.0, "pick": {"x": 320, "y": 180, "threshold": 0.5}}
//
// An event line is "at" (seconds from the start) plus one field of
// cinevol.v1.SessionEvent in its proto3 JSON form; "orbit" expands into
// camera events around the volume. "slice" and "pick" lines are reading
// calls beside the stream: a cinevol.v1.SliceRequest (plus "out", the PNG's
// file name) or PickRequest in proto3 JSON form, the session id left out.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cinevol/v1/service.pb.h"

namespace cinevol::cli {

// "labels" on the session line: a segmentation of the session's volume,
// loaded before the session starts. On the server (under its data roots):
//   {"load": "ct/seg.nii.gz", "table": "ct/labels.tsv"}
// or local files, relative to the script:
//   {"upload": "seg.nii.gz", "table": "labels.tsv"}
struct ScriptLabels {
  std::string load, server_table;             // on the server
  std::filesystem::path upload, local_table;  // local files
  bool empty() const { return load.empty() && upload.empty(); }
};

// What the "session" line says; unset parts take the defaults noted. At most
// one of volume, load, upload and series is set.
struct ScriptSession {
  std::string volume;                           // an id the server holds; none of the three: the server's first
  std::string load;                             // a path on the server, under its data roots, to load first
  std::filesystem::path upload;                 // a local file to upload first (relative paths: to the script's folder)
  std::optional<v1::LoadSeriesRequest> series;  // a series to load first from a PACS the server names
  std::string preset;                           // used without a scene; empty: the volume's default preset
  std::optional<v1::Scene> scene;               // "scene": a scene file, relative to the script
  v1::Viewport viewport;                        // default 640x360
  v1::StreamSettings stream;
  ScriptLabels labels;
};

// A camera orbit: `degrees` about the volume's vertical axis over `seconds`,
// as camera events at `hz`, from `start_degrees` (0: in front, -y), at
// `distance_scale` times the distance that frames the whole volume.
struct Orbit {
  double degrees = 360, seconds = 4, hz = 30, start_degrees = 0, elevation_degrees = 0, distance_scale = 1;
};

// A "slice" or "pick" line: a reading call on the session (docs/reading.md),
// its session id filled in by the player.
struct ScriptCall {
  std::optional<v1::SliceRequest> slice;
  std::string out;  // the slice's file name ("NAME.png", no folder): written under the run's slices/
  std::optional<v1::PickRequest> pick;
};

struct ScriptStep {
  double at = 0;  // seconds from the start
  int line = 0;   // in the script file; 0 for generated steps
  bool is_orbit = false;
  Orbit orbit;
  v1::SessionEvent event;  // when not an orbit, a UI action or a call
  // "ui": an action for cinevol-viewer (its JSON object, e.g. {"panel": "lights"});
  // `cinevol play` skips these lines. docs/viewer.md lists the actions.
  std::string ui;
  std::optional<ScriptCall> call;  // "slice" and "pick" lines (SessionScript::calls)
};

struct SessionScript {
  std::string name;  // the file, for messages
  ScriptSession session;
  std::vector<ScriptStep> steps;  // events, orbits and UI actions, sorted by time
  // The "slice" and "pick" lines, sorted by time. Kept apart from `steps`,
  // so that a player that knows only events and UI actions (cinevol-viewer,
  // loadtest, demo) passes over them; WithCalls puts them among the steps.
  std::vector<ScriptStep> calls;
};

// Reads and checks a script; throws InputError "FILE line N: FIELD: what".
SessionScript LoadScript(const std::filesystem::path& file);
SessionScript ParseScript(const std::string& text, const std::string& name, const std::filesystem::path& base_dir = {});

// The camera `degrees` about the volume's vertical (+z) axis from the front
// (-y, anterior for LPS data), `elevation` above, framing the whole volume.
v1::Camera OrbitCamera(const v1::VolumeInfo& volume, double degrees, double elevation_degrees = 0,
                       double distance_scale = 1);

// The steps with every orbit turned into its camera events.
std::vector<ScriptStep> ExpandOrbits(const std::vector<ScriptStep>& steps, const v1::VolumeInfo& volume);

// `steps` with `calls` among them, by time and then by line: a call comes
// after the steps of its time that the file has before it.
std::vector<ScriptStep> WithCalls(std::vector<ScriptStep> steps, const std::vector<ScriptStep>& calls);

// The request that starts the script's session on `volume`: its scene, else
// its preset, else neither (the volume's default preset).
v1::CreateSessionRequest SessionRequest(const ScriptSession& session, const std::string& volume_id);

// Says on stderr that scene file `file` names no lights, so that a session
// of it takes the volume's default lights (the server adds them).
void SayWhenUnlit(const v1::Scene& scene, const std::string& file);

}  // namespace cinevol::cli
