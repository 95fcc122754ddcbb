// `cinevol measurements store|load`: a session's measurements stored on a PACS as a DICOM SR measurement report,
// and a report read back (printed, or sent to a session as its measurements).
#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "commands.h"
#include "connection_options.h"
#include "core/error.h"
#include "text_output.h"

namespace cinevol::cli {
namespace {

struct MeasurementsOptions {
  ConnectionOptions connection;
  bool json = false;
  std::string session, to;
  v1::LoadMeasurementsRequest load;
};

void Store(const MeasurementsOptions& o) {
  const v1::StoredObject stored = Connect(o.connection).StoreMeasurements(o.session, o.to);
  if (o.json) return PrintJson(stored);
  fmt::print("stored in PACS '{}': study {}, series {}, instance {}\n", Printable(stored.pacs()), stored.study_uid(),
             stored.series_uid(), stored.sop_instance_uid());
}

double Length(const v1::Vec3& a, const v1::Vec3& b) {
  return std::hypot(double(a.x()) - b.x(), double(a.y()) - b.y(), double(a.z()) - b.z());
}

// What a reader reads off a measurement: "42.10 mm", "87.3 deg".
std::string Value(const v1::Measurement& m) {
  if (m.points_size() == 2) return fmt::format("{:.2f} mm", Length(m.points(0), m.points(1)));
  const v1::Vec3 &a = m.points(0), &v = m.points(1), &b = m.points(2);
  const double ux = a.x() - v.x(), uy = a.y() - v.y(), uz = a.z() - v.z();
  const double wx = b.x() - v.x(), wy = b.y() - v.y(), wz = b.z() - v.z();
  const double norms = std::hypot(ux, uy, uz) * std::hypot(wx, wy, wz);
  if (norms <= 0) return "-";
  const double cosine = std::clamp((ux * wx + uy * wy + uz * wz) / norms, -1.0, 1.0);
  return fmt::format("{:.1f} deg", std::acos(cosine) * 180 / std::numbers::pi);
}

std::string Points(const v1::Measurement& m) {
  std::string text;
  for (const v1::Vec3& p : m.points()) {
    text += fmt::format("{}({:.2f}, {:.2f}, {:.2f})", text.empty() ? "" : " ", p.x(), p.y(), p.z());
  }
  return text;
}

// The series the session's volume came from ("pacs:NAME/STUDY/SERIES..."), where this caller may see it; empty
// otherwise.
std::string SessionSeries(Client& client, const std::string& session) {
  const v1::ServerStatus status = client.Status();
  for (const v1::SessionStatus& s : status.sessions()) {
    if (s.session_id() != session) continue;
    const std::string source = client.DescribeVolume(s.volume_id()).source();
    if (source.rfind("pacs:", 0) != 0) return {};
    const std::size_t second = source.find('/', source.find('/') + 1);
    return second == std::string::npos ? std::string() : source.substr(second + 1, source.find('@') - second - 1);
  }
  return {};
}

void Load(const MeasurementsOptions& o) {
  Client client = Connect(o.connection);
  const v1::LoadMeasurementsResponse report = client.LoadMeasurements(o.load);
  if (!o.session.empty()) {
    const std::string shown = SessionSeries(client, o.session);
    if (!shown.empty() && !report.source_series_uid().empty() && shown != report.source_series_uid()) {
      fmt::print(stderr,
                 "note: the report measured series {}; session {} shows series {}: its points are patient "
                 "coordinates of frame of reference {}\n",
                 report.source_series_uid(), o.session, shown, report.frame_of_reference_uid());
    }
    v1::SessionEvent event;
    *event.mutable_measurements()->mutable_measurements() = report.measurements();
    client.SendEvents(o.session, {event});
  }
  if (o.json) return PrintJson(report);
  std::vector<TextRow> rows{{"NAME", "KIND", "VALUE", "POINTS (LPS mm)"}};
  for (const v1::Measurement& m : report.measurements()) {
    rows.push_back({Printable(m.name()), m.points_size() == 2 ? "distance" : "angle", Value(m), Points(m)});
  }
  PrintTable(rows);
  fmt::print("frame of reference {}, measured series {}\n", report.frame_of_reference_uid(),
             report.source_series_uid().empty() ? "(not named)" : report.source_series_uid());
  if (!o.session.empty()) {
    fmt::print("sent {} measurement{} to session {}\n", report.measurements_size(),
               report.measurements_size() == 1 ? "" : "s", o.session);
  }
}

CLI::App* AddSubcommand(CLI::App* parent, const std::string& name, const std::string& help,
                        std::function<void(const MeasurementsOptions&)> run, std::shared_ptr<MeasurementsOptions>& o) {
  auto* cmd = parent->add_subcommand(name, help);
  o = std::make_shared<MeasurementsOptions>();
  AddConnectionOptions(cmd, o->connection);
  AddCallTimeoutOption(cmd, o->connection);
  cmd->add_flag("--json", o->json, "Print the server's answer as proto3 JSON (one object)");
  cmd->callback([o, run] { run(*o); });
  return cmd;
}

}  // namespace

void AddMeasurementsCommand(CLI::App& app) {
  auto* measurements = app.add_subcommand(
      "measurements", "A session's measurements to and from a PACS, as a DICOM SR measurement report (docs/pacs.md)");
  measurements->require_subcommand(1);
  std::shared_ptr<MeasurementsOptions> o;
  auto* store =
      AddSubcommand(measurements, "store",
                    "Store a session's measurements into the study of its volume (loaded from a PACS)", Store, o);
  store->add_option("--session", o->session, "The session whose measurements are stored")->required();
  store->add_option("--to", o->to, "The PACS to store them on, by the name the server gives it")->required();

  auto* load = AddSubcommand(measurements, "load",
                             "Read a measurement report from a PACS; with --session, make them the session's", Load, o);
  load->add_option("--pacs", *o->load.mutable_pacs(), "The PACS by the name the server gives it")->required();
  load->add_option("--study", *o->load.mutable_study_uid(), "Study Instance UID")->required();
  load->add_option("--series", *o->load.mutable_series_uid(), "The report's Series Instance UID")->required();
  load->add_option("--instance", *o->load.mutable_sop_instance_uid(),
                   "The report's SOP Instance UID (default: the series' only instance)");
  load->add_option("--session", o->session, "Send them to this session as its measurements (replacing its own)");
}

}  // namespace cinevol::cli
