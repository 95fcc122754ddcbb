// The Scene panel's files: a still of the session (Take snapshot), a movie of
// it (Record movie), the session's scene written to a file (Save: camera and lights in patient
// coordinates beside its clipping, as cinevol render reads it) and a file's
// scene applied to the session (Open) as edits, which the server resolves.
#pragma once

#include <optional>
#include <string>

#include "viewer/session_link.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

class SceneFiles {
 public:
  SceneFiles(ViewerContext& context, SessionLink& link) : context_(context), link_(link) {}

  void Snapshot(const std::string& path, int spp);  // .png or .exr; the line under the panels follows it
  // A movie of the session's view (RenderMovie) along the path `request` names (an orbit, a sweep, or a
  // time series' phases), its seconds and spp; written to `path` (.mp4); the line under the panels follows it.
  void Movie(const std::string& path, v1::MovieRequest request);
  void Save(const std::string& path);
  void Open(const std::string& path);

  // The panel's fields.
  std::string scene_path = "view.json", snapshot_path = "snapshot.png", movie_file = "movie.mp4";
  int snapshot_spp = 256, movie_spp = 32;
  int movie_path = 0;  // the panel's choice: 0 orbit; 1, 2, 3 a sweep, axial, coronal, sagittal; 4 the phases
  float movie_seconds = 4;

 private:
  ViewerContext& context_;
  SessionLink& link_;
};

// Label styles as the session can take them: all of them where its volume
// has a segmentation, only the table's removal where it has a table (styles
// wait for a segmentation), nothing otherwise.
void SetLabelsFor(ShownSession& session, const std::optional<v1::VolumeInfo>& volume, const v1::Labels& labels);

}  // namespace cinevol::viewer
