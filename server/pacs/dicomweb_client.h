// A DICOMweb client for one configured PACS: QIDO-RS to search studies and
// series, WADO-RS to retrieve a series' instances in parallel, STOW-RS to store
// instances. Every request goes to the PACS's base URL plus UIDs checked to be
// UIDs; nothing a caller passes becomes a URL.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "pacs/pacs_config.h"

namespace cinevol::pacs {

// A QIDO-RS study search. Empty fields do not constrain the search. Text
// fields take DICOM matching (`*` and `?` wildcards) and at most 64
// characters, without control characters or backslashes.
struct StudyQuery {
  std::string study_uid;     // one study, exactly
  std::string patient_name;  // e.g. "DOE^J*"
  std::string patient_id;
  std::string study_date_from;  // YYYYMMDD; with study_date_to, an inclusive range, either end open
  std::string study_date_to;    // YYYYMMDD
  std::string modality;         // one modality in the study: 1 to 16 of A-Z, 0-9, _ ("CT", "MR")
  std::string accession_number;
  std::string study_description;
  int limit = 50;  // [1; PacsConfig::max_search_results] - studies in this page
  int offset = 0;  // [0; 1000000] - studies skipped before it
};

// What a study list shows; text fields are empty and counts absent where the
// PACS did not say. Patient fields go to the caller who asked, never to logs.
struct StudySummary {
  std::string study_uid;
  std::string patient_name;  // the PN's alphabetic form, "FAMILY^GIVEN"
  std::string patient_id;
  std::string study_date;  // YYYYMMDD as the PACS wrote it
  std::string description;
  std::string accession_number;
  std::vector<std::string> modalities;
  std::optional<std::int64_t> series_count;
  std::optional<std::int64_t> instance_count;
  // What a render sent back into the study copies; empty where the PACS did not say.
  std::string study_time, study_id, referring_physician, patient_birth_date, patient_sex;
};

struct SeriesSummary {
  std::string series_uid;
  std::string modality;
  std::string description;
  std::optional<std::int64_t> series_number;
  std::optional<std::int64_t> instance_count;
};

// One instance of a series as QIDO-RS lists it; the matrix, where the PACS
// says it, lets a caller count memory before a byte of pixels arrives.
struct InstanceSummary {
  std::string sop_instance_uid;
  std::optional<std::int64_t> instance_number;
  std::optional<std::int64_t> rows;
  std::optional<std::int64_t> columns;
  std::optional<std::int64_t> bits_allocated;
  std::optional<std::int64_t> frames;
};

struct RetrieveCallbacks {
  // Before any instance is fetched, with the instances the PACS lists (at most
  // max_instances of them): throw to refuse the series (its memory, say).
  std::function<void(const std::vector<InstanceSummary>&)> on_listing;
  // Each instance once its DICOM Part 10 file is written, in any order: the
  // file, and its size in bytes. Called from the fetching threads but one
  // call at a time; throwing stops the retrieve with that exception.
  std::function<void(const InstanceSummary& instance, const std::filesystem::path& file, std::uint64_t bytes)>
      on_instance;
  // Instances done of the total, after each on_instance.
  std::function<void(std::size_t done, std::size_t total)> on_progress;
};

struct RetrieveStats {
  std::size_t instances = 0;
  std::uint64_t bytes = 0;       // the multipart bodies received
  int most_fetches_at_once = 0;  // never more than parallel_fetches
};

struct StoreResult {
  std::vector<std::string> stored_sop_instance_uids;  // as the PACS acknowledged them
};

class DicomWebClient {
 public:
  // Checks `config` (ValidatePacsConfig).
  explicit DicomWebClient(PacsConfig config);

  const PacsConfig& config() const { return config_; }

  // QIDO-RS /studies: at most min(query.limit, max_search_results) studies.
  // InputError for a bad query field (named), PacsError for a failing PACS.
  std::vector<StudySummary> SearchStudies(const StudyQuery& query, const std::atomic<bool>* cancel = nullptr) const;

  // QIDO-RS /studies/{study}/series: at most max_search_results series.
  std::vector<SeriesSummary> SearchSeries(const std::string& study_uid,
                                          const std::atomic<bool>* cancel = nullptr) const;

  // QIDO-RS /studies/{study}/series/{series}/instances; OverLimit when the
  // series has more than max_instances.
  std::vector<InstanceSummary> ListInstances(const std::string& study_uid, const std::string& series_uid,
                                             const std::atomic<bool>* cancel = nullptr) const;

  // Lists the series' instances, then fetches each (WADO-RS, multipart/related,
  // as stored: no transcoding on the PACS) on at most parallel_fetches threads
  // into `folder` (which must exist): each answer streams to disk as it comes
  // (memory stays flat whatever the PACS sends), its one instance is cut out
  // to `NNNNNN.dcm` (its index in the listing) and handed to
  // `callbacks.on_instance`. Before any fetch: OverLimit past max_instances,
  // InputError for a bad UID. While fetching: OverLimit past
  // max_response_bytes for one instance or max_series_bytes for all, PacsError
  // for a failing PACS or a malformed answer, Cancelled once `cancel` is set
  // (within about a second); the transfers in flight are aborted on any of
  // these. Returns once every instance was handed over; what it wrote stays
  // in `folder`, the caller's to remove.
  RetrieveStats RetrieveSeries(const std::string& study_uid, const std::string& series_uid,
                               const std::filesystem::path& folder, const RetrieveCallbacks& callbacks,
                               const std::atomic<bool>* cancel = nullptr) const;

  // STOW-RS: posts `instances` (DICOM Part 10 files of study `study_uid`) to
  // /studies/{study} as one multipart/related body. Throws PacsError unless the
  // PACS stored every one (HTTP 200, or 202 without failures), naming the
  // failures it reported; OverLimit past max_instances or max_series_bytes;
  // InputError for a bad UID or a part that is not a Part 10 file.
  StoreResult StoreInstances(const std::string& study_uid, const std::vector<std::string>& instances,
                             const std::atomic<bool>* cancel = nullptr) const;

 private:
  PacsConfig config_;
};

// Throws InputError naming `field` unless `uid` is a valid UID (IsValidUid).
void CheckUid(const std::string& uid, const char* field);

}  // namespace cinevol::pacs
