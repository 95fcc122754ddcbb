// LoadSeries: listing, limits, retrieve, the reader cage.
#include "runtime/series_load.h"

#include <fmt/format.h>

#include <filesystem>
#include <functional>

#include "core/error.h"
#include "core/volume.h"
#include "io/volume_loader.h"
#include "runtime/render_store.h"

namespace cinevol::service {
namespace {

namespace fs = std::filesystem;

// The voxels and bytes the listed instances will make, as far as the PACS
// said their matrix; instances it said nothing of count as none (the reader's
// own check from the headers still holds them to the limits).
struct SeriesSize {
  std::uint64_t voxels = 0, bytes = 0;
};

SeriesSize SizeOf(const std::vector<pacs::InstanceSummary>& instances) {
  SeriesSize size;
  for (const pacs::InstanceSummary& i : instances) {
    const std::uint64_t voxels = std::uint64_t(std::max<std::int64_t>(i.rows.value_or(0), 0)) *
                                 std::uint64_t(std::max<std::int64_t>(i.columns.value_or(0), 0)) *
                                 std::uint64_t(std::max<std::int64_t>(i.frames.value_or(1), 1));
    const VoxelType type = i.bits_allocated.value_or(16) > 16 ? VoxelType::kFloat32 : VoxelType::kInt16;
    size.voxels += voxels;
    size.bytes += Volume::BytesToLoad(type, voxels);
  }
  return size;
}

fs::path NewScratchFolder(const fs::path& under) {
  static std::atomic<int> counter{0};
  // Named by the server alone: nothing of the PACS's answer reaches a path.
  const fs::path folder = under / fmt::format("pacs-{}-{}", ::getpid(), counter++);
  fs::create_directories(folder);
  return folder;
}

// Retrieves the series `request` names into a new scratch folder with its
// progress; `check_listing` sees the PACS's listing before any instance comes
// (it throws to refuse). The folder goes if the retrieve fails.
using ListingCheck = std::function<void(const std::vector<pacs::InstanceSummary>&)>;
fs::path Retrieve(const pacs::DicomWebClient& pacs, VolumeRegistry& volumes, const v1::LoadSeriesRequest& request,
                  const ListingCheck& check_listing, const std::atomic<bool>* cancel, const SeriesProgress& progress) {
  const fs::path folder = NewScratchFolder(volumes.upload_dir());
  v1::LoadSeriesProgress news;
  news.set_stage("retrieving");
  pacs::RetrieveCallbacks callbacks;
  callbacks.on_listing = [&](const std::vector<pacs::InstanceSummary>& instances) {
    check_listing(instances);
    news.set_instances_total(instances.size());
    progress(news);
  };
  callbacks.on_instance = [&](const pacs::InstanceSummary&, const fs::path&, std::uint64_t bytes) {
    news.set_bytes(news.bytes() + bytes);
  };
  callbacks.on_progress = [&](std::size_t done, std::size_t total) {
    news.set_instances_done(done);
    news.set_instances_total(total);
    progress(news);
  };
  try {
    pacs.RetrieveSeries(request.study_uid(), request.series_uid(), folder, callbacks, cancel);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(folder, ec);
    throw;
  }
  news.set_stage("reading");
  progress(news);
  return folder;
}

// A SEG series holds one SEG; a series of more instances is another kind of series.
constexpr std::size_t kMaxSegInstances = 16;

// LoadSeriesRequest.labels_for: the SEG series as that volume's segmentation.
v1::VolumeInfo LoadSegmentationSeries(const pacs::DicomWebClient& pacs, VolumeRegistry& volumes,
                                      const v1::LoadSeriesRequest& request, const Principal& caller,
                                      const std::atomic<bool>* cancel, const SeriesProgress& progress) {
  volumes.RequireLabelsAllowed(request.labels_for(), caller, "labels_for");
  const std::string source = PacsSource({pacs.config().name, request.study_uid(), request.series_uid()}, "");
  const auto one_seg = [&](const std::vector<pacs::InstanceSummary>& instances) {
    if (instances.size() > kMaxSegInstances) {
      throw InputError(fmt::format("series_uid: series {} holds {} instances; a DICOM SEG series for labels_for holds "
                                   "one SEG (at most {} instances are fetched)",
                                   request.series_uid(), instances.size(), kMaxSegInstances));
    }
  };
  const fs::path folder = Retrieve(pacs, volumes, request, one_seg, cancel, progress);
  return volumes.AddRetrievedLabels(request.labels_for(), folder, source, caller, cancel);
}

}  // namespace

v1::VolumeInfo LoadSeries(const pacs::DicomWebClient& pacs, VolumeRegistry& volumes,
                          const v1::LoadSeriesRequest& request, const Principal& caller,
                          const std::atomic<bool>* cancel, const SeriesProgress& progress) {
  pacs::CheckUid(request.study_uid(), "study_uid");
  pacs::CheckUid(request.series_uid(), "series_uid");
  if (!request.orientation().empty()) ParseOrientation(request.orientation(), "orientation");
  if (!request.labels_for().empty()) return LoadSegmentationSeries(pacs, volumes, request, caller, cancel, progress);
  const ReadChoices choices{request.orientation(), request.resample_uneven()};
  const std::string source =
      PacsSource({pacs.config().name, request.study_uid(), request.series_uid()}, choices.Suffix());
  if (std::optional<v1::VolumeInfo> held = volumes.FindHeld(source, caller)) return *held;

  const auto within_limits = [&](const std::vector<pacs::InstanceSummary>& instances) {
    const SeriesSize size = SizeOf(instances);
    volumes.RequireRoom(size.voxels, size.bytes, caller, fmt::format("series {}", request.series_uid()));
  };
  const fs::path folder = Retrieve(pacs, volumes, request, within_limits, cancel, progress);
  return volumes.AddRetrievedSeries(folder, source, choices, caller, cancel);
}

}  // namespace cinevol::service
