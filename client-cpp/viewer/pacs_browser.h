// The PACS browser (docs/viewer.md, "PACS"): the server's PACS, a search's
// studies, a study's series, and a series opened by what it is: images as
// the volume looked at, a measurement report (SR) as the session's
// measurements, a segmentation (SEG) as the open volume's labels, a
// presentation state (PR) as the series it presents in its scene; and the
// session's measurements stored back as a report.
// Its calls run on the connection's long lane; their answers come back on
// the UI thread. Patient fields stay here and on screen: never printed or logged.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "viewer/session_link.h"
#include "viewer/viewer_context.h"

namespace cinevol::viewer {

class PacsBrowser {
 public:
  // `open_volume`: what opening a series ends with, the view switched to the volume it became (in the scene of the
  // presentation state opened, where one was).
  using OpenVolume = std::function<void(const std::string& volume_id, std::optional<v1::Scene> scene)>;
  PacsBrowser(ViewerContext& context, SessionLink& link, OpenVolume open_volume);

  void ListPacs();  // each connection asks: the panel shows only where the server names a PACS
  void Search(v1::SearchStudiesRequest query);
  void SelectStudy(const std::string& pacs_name, const std::string& study_uid);
  void OpenSeries(const v1::LoadSeriesRequest& request);
  v1::LoadSeriesRequest SelectedSeries() const;
  // The session's measurements as a report in its study on PACS `pacs_name`.
  void StoreMeasurements(const std::string& pacs_name);
  // The connection closed: calls queued on it never run and those running
  // are not heard of, so nothing waits for them.
  void Forget();
  bool busy() const { return busy_ > 0; }  // calls under way (a script's settle waits for them)

  // What the panel shows and edits.
  std::vector<std::string> names;  // the server's PACS (ListPacs); none: no panel
  v1::SearchStudiesRequest query;  // the search fields and the PACS searched
  std::vector<v1::StudySummary> studies;
  std::string study_uid;                           // the study selected
  std::vector<v1::SeriesSummary> series;           // of the study selected
  std::string series_uid;                          // the series selected
  std::optional<v1::LoadSeriesProgress> progress;  // of the series being opened
  bool opening = false;
  std::string source;   // the PACS the studies and series listed came from
  std::string status;   // the panel's status line
  bool failed = false;  // it says what went wrong

 private:
  // Runs `call` on the requester; the function it returns (or the error)
  // then runs on the UI thread, unless the connection has closed since.
  void Call(const std::string& action, const std::string& pacs_name,
            std::function<std::function<void()>(Client&)> call);
  void ShowStudies(const v1::SearchStudiesRequest& query, const std::vector<v1::StudySummary>& studies);
  void ShowSeries(const std::string& pacs_name, const std::string& study_uid,
                  const std::vector<v1::SeriesSummary>& series);
  void Opened(const v1::LoadSeriesRequest& request, const v1::VolumeInfo& opened,
              std::optional<v1::Scene> scene = std::nullopt);
  // The modality of a series of the study listed ("" where it is not listed).
  std::string ModalityOf(const std::string& series_uid) const;
  void OpenMeasurements(const v1::LoadSeriesRequest& series);
  // The series a presentation state presents, loaded and opened in its scene.
  void OpenPresentation(const v1::LoadSeriesRequest& series);
  void Failed(const std::string& action, const std::string& pacs_name, grpc::StatusCode code,
              const std::string& message);

  ViewerContext& context_;
  SessionLink& link_;
  OpenVolume open_volume_;
  int busy_ = 0;
  std::uint64_t generation_ = 0;  // bumped when the connection closes: answers of its calls come to nothing
};

}  // namespace cinevol::viewer
