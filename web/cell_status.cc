#include "web/cell_status.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "vision/stereo/lens_distortion.h"
#include "vision/stereo/overlay.h"
#include "vision/sensing/plots.h"

namespace hnnstereo::web {
namespace {

double UnixNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

const char* AckName(robot::AckKind ack) {
  switch (ack) {
    case robot::AckKind::kAcknowledged:
      return "acknowledged";
    case robot::AckKind::kTimeout:
      return "ack timeout";
    case robot::AckKind::kStop:
      return "stop";
    case robot::AckKind::kPeerLost:
      return "peer lost";
  }
  return "?";
}

// A part where the page draws it: its top face's outline, centre and yaw line in left-image
// pixels, projected with P1 at the top face's height (and through the lens, when there is one).
struct PartPixels {
  std::vector<cv::Point2d> outline;  ///< closed polygon; empty when the file has no top face
  cv::Point2d centre;
  std::optional<cv::Point2d> yaw_tip;  ///< none for a round part
};

constexpr double kYawLineMm = 40.0;  // as vision::DrawObjectOverlay

// The left camera: P1, and its lens when P1 maps to undistorted pixels.
struct LeftCamera {
  const calib::ProjectionMatrix& P1;
  const calib::Intrinsics* lens = nullptr;  ///< K1, D1; null or empty D1: pinhole
};

std::optional<cv::Point2d> Project(const LeftCamera& camera, const Eigen::Vector3d& x) {
  const Eigen::Vector3d h = camera.P1 * x.homogeneous();
  if (!(h.z() > 0.0) || !std::isfinite(h.x() / h.z()) || !std::isfinite(h.y() / h.z())) {
    return std::nullopt;
  }
  if (camera.lens == nullptr || camera.lens->D1.empty()) {
    return cv::Point2d(h.x() / h.z(), h.y() / h.z());
  }
  const Eigen::Vector2f undistorted = h.hnormalized().cast<float>();
  const Eigen::Vector2f pixel =
      vision::DistortPoints({undistorted}, camera.lens->K1, camera.lens->D1).front();
  return cv::Point2d(pixel.x(), pixel.y());
}

// The part's yaw (deg); none for a round part (yaw_deg null or round true) or a missing one.
std::optional<double> YawOf(const nlohmann::json& object) {
  if (object.value("round", false)) return std::nullopt;
  const auto yaw = object.find("yaw_deg");
  if (yaw == object.end() || !yaw->is_number()) return std::nullopt;
  return yaw->get<double>();
}

// Null when the object lacks a centroid or a point falls behind the camera.
std::optional<PartPixels> PartInImage(const nlohmann::json& object, const LeftCamera& camera) {
  try {
    const auto& c = object.at("centroid");
    const Eigen::Vector3d centre(c.at(0).get<double>(), c.at(1).get<double>(),
                                 c.at(2).get<double>());
    PartPixels pixels;
    const auto centre_px = Project(camera, centre);
    if (!centre_px) return std::nullopt;
    pixels.centre = *centre_px;
    // A round part (yaw_deg null) has no orientation, so no yaw line.
    if (const auto yaw_deg = YawOf(object)) {
      const double yaw = *yaw_deg * std::numbers::pi / 180.0;
      const auto tip_px =
          Project(camera, centre + kYawLineMm * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0.0));
      if (!tip_px) return std::nullopt;
      pixels.yaw_tip = *tip_px;
    }
    std::vector<Eigen::Vector3d> outline;
    if (object.value("round", false) && object.contains("top_circle")) {
      const auto& circle = object.at("top_circle");
      const double r = circle.at("radius").get<double>();
      const double cx = circle.at("centre").at(0).get<double>();
      const double cy = circle.at("centre").at(1).get<double>();
      for (int k = 0; k < 36; ++k) {
        const double a = 2.0 * std::numbers::pi * k / 36.0;
        outline.emplace_back(cx + r * std::cos(a), cy + r * std::sin(a), centre.z());
      }
    } else if (object.contains("top_rectangle")) {
      const auto& rectangle = object.at("top_rectangle");
      const double a = rectangle.at("yaw_deg").get<double>() * std::numbers::pi / 180.0;
      const Eigen::Vector3d along(std::cos(a), std::sin(a), 0.0),
          across(-std::sin(a), std::cos(a), 0.0);
      const Eigen::Vector3d middle(rectangle.at("centre").at(0).get<double>(),
                                   rectangle.at("centre").at(1).get<double>(), centre.z());
      const double half_length = 0.5 * rectangle.at("length").get<double>();
      const double half_width = 0.5 * rectangle.at("width").get<double>();
      for (const auto& [s, t] : {std::pair{1, 1}, {-1, 1}, {-1, -1}, {1, -1}}) {
        outline.push_back(middle + s * half_length * along + t * half_width * across);
      }
    }
    for (const Eigen::Vector3d& corner : outline) {
      const auto px = Project(camera, corner);
      if (!px) return std::nullopt;
      pixels.outline.push_back(*px);
    }
    return pixels;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

std::string HexColour(const cv::Scalar& bgr) {
  char text[8];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", static_cast<int>(bgr[2]),
                static_cast<int>(bgr[1]), static_cast<int>(bgr[0]));
  return text;
}

nlohmann::json PointJson(const cv::Point2d& p) {
  return {std::round(p.x * 10.0) / 10.0, std::round(p.y * 10.0) / 10.0};
}

std::string EncodePng(const cv::Mat& image) {
  if (image.empty()) return {};
  std::vector<unsigned char> bytes;
  // Fast compression: the page polls, and the encoding runs on the HTTP threads.
  cv::imencode(".png", image, bytes, {cv::IMWRITE_PNG_COMPRESSION, 1});
  return {bytes.begin(), bytes.end()};
}

const nlohmann::json& ObjectList(const nlohmann::json& objects) {
  static const nlohmann::json empty = nlohmann::json::array();
  if (objects.is_object() && objects.contains("objects") && objects["objects"].is_array()) {
    return objects["objects"];
  }
  return empty;
}

}  // namespace

const std::string& LazyBytes::Get(const std::function<std::string()>& make) const {
  std::call_once(once_, [&] { bytes_ = make(); });
  return bytes_;
}

nlohmann::json CellState::PartsJson() const {
  nlohmann::json parts = nlohmann::json::array();
  const nlohmann::json& list = ObjectList(objects);
  for (std::size_t index = 0; index < list.size(); ++index) {
    const nlohmann::json& object = list[index];
    nlohmann::json part = {{"id", object.value("id", static_cast<int>(index) + 1)},
                           {"height", object.value("height", 0.0)},
                           {"yaw_deg", YawOf(object) ? nlohmann::json(*YawOf(object))
                                                     : nlohmann::json(nullptr)},
                           {"points", object.value("points", 0)},
                           {"colour", HexColour(vision::LabelColour(static_cast<int>(index)))}};
    if (object.contains("centroid") && object["centroid"].is_array() &&
        object["centroid"].size() == 3) {
      part["x"] = object["centroid"][0];
      part["y"] = object["centroid"][1];
      part["z"] = object["centroid"][2];
    }
    const int id = part["id"].get<int>();
    if (const auto outcome = outcomes.find(id); outcome != outcomes.end()) {
      part["pick"] = outcome->second.admitted ? "sent" : "refused";
      part["reason"] = outcome->second.reason;
      part["sequence"] = outcome->second.sequence;
    } else {
      part["pick"] = has_link ? "not offered" : "no link";
      part["reason"] = "";
    }
    if (P1 && !left_image.empty()) {
      if (const auto pixels = PartInImage(object, {*P1, intrinsics ? &*intrinsics : nullptr})) {
        part["centre_px"] = PointJson(pixels->centre);
        if (pixels->yaw_tip) part["yaw_tip_px"] = PointJson(*pixels->yaw_tip);
        nlohmann::json outline = nlohmann::json::array();
        for (const cv::Point2d& p : pixels->outline) outline.push_back(PointJson(p));
        part["outline_px"] = outline;
      }
    }
    parts.push_back(part);
  }
  return parts;
}

nlohmann::json CellState::StatusJson() const {
  nlohmann::json status = {
      {"mode", mode},
      {"version", version},
      {"image_version", image_version},
      {"time", unix_time_s},
      {"objects_cycle", objects_cycle},
      {"image", left_image.empty()
                    ? nlohmann::json(nullptr)
                    : nlohmann::json{{"width", left_image.cols}, {"height", left_image.rows}}},
      {"outlines", P1.has_value() && !left_image.empty()},
      {"parts", PartsJson()},
      {"counters",
       {{"cycles", cycles},
        {"poses_published", poses_published},
        {"refused", refused},
        {"sense_errors", sense_errors},
        {"ack_timeouts", ack_timeouts},
        {"peer_lost", peer_lost}}},
      {"last_cycle", nullptr},
      {"last_error", nullptr},
      {"link", nullptr}};
  if (!recent_cycles.empty()) status["last_cycle"] = CyclesJson()["cycles"].back();
  if (!last_error.empty()) {
    status["last_error"] = {
        {"message", last_error}, {"cycle", last_error_cycle}, {"time", last_error_unix_time_s}};
  }
  if (has_link) {
    const robot::LinkStats& s = link_stats;
    status["link"] = {{"transport", link_transport},
                      {"peer_connected", nullptr},
                      {"seconds_since_peer_heard", nullptr},
                      {"connections", s.connections},
                      {"reconnects", s.reconnects},
                      {"triggers", s.triggers},
                      {"duplicate_triggers", s.duplicate_triggers},
                      {"malformed", s.malformed},
                      {"cycles_published", s.cycles_published},
                      {"poses_sent", s.poses_sent},
                      {"dropped_on_reconnect", s.dropped_on_reconnect},
                      {"transport_refused", s.transport_refused},
                      {"gate_refusals", refused},
                      {"last_request_sequence", last_request_sequence},
                      {"last_result_sequence", last_result_sequence},
                      {"last_pick_sequence", last_pick_sequence},
                      {"last_cycle_time", last_cycle_end_unix_s}};
    if (s.peer_connected) status["link"]["peer_connected"] = *s.peer_connected;
    if (s.peer_heard_steady_s > 0.0) {
      const double now_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
              .count();
      // Frozen into the snapshot: the page adds the snapshot's age itself.
      status["link"]["seconds_since_peer_heard"] = std::max(0.0, now_s - s.peer_heard_steady_s);
    }
  }
  return status;
}

nlohmann::json CellState::CyclesJson() const {
  nlohmann::json cycles_json = nlohmann::json::array();
  for (const CycleRecord& r : recent_cycles) {
    cycles_json.push_back({{"cycle", r.cycle},
                           {"request_sequence", r.request_sequence},
                           {"objects", r.objects},
                           {"published", r.published},
                           {"refused", r.refused},
                           {"status", r.status},
                           {"error", r.error},
                           {"ack", r.ack},
                           {"sense_ms", r.sense_ms},
                           {"publish_ms", r.publish_ms},
                           {"ack_ms", r.ack_ms},
                           {"cycle_ms", r.cycle_ms},
                           {"time", r.unix_time_s}});
  }
  return {{"version", version}, {"cycles", cycles_json}};
}

cv::Mat CellState::DrawOverlay() const {
  if (left_image.empty()) return {};
  cv::Mat canvas = vision::ToColour8(left_image) * 0.8;
  if (!P1) return canvas;
  const nlohmann::json& list = ObjectList(objects);
  for (std::size_t index = 0; index < list.size(); ++index) {
    const auto pixels = PartInImage(list[index], {*P1, intrinsics ? &*intrinsics : nullptr});
    if (!pixels) continue;
    const cv::Scalar colour = vision::LabelColour(static_cast<int>(index));
    if (!pixels->outline.empty()) {
      std::vector<cv::Point> polygon;
      for (const cv::Point2d& p : pixels->outline) polygon.emplace_back(cvRound(p.x), cvRound(p.y));
      cv::polylines(canvas, polygon, true, colour, 2, cv::LINE_AA);
    }
    cv::drawMarker(canvas, pixels->centre, colour, cv::MARKER_CROSS, 14, 2, cv::LINE_AA);
    if (pixels->yaw_tip) {
      cv::arrowedLine(canvas, pixels->centre, *pixels->yaw_tip, colour, 2, cv::LINE_AA, 0, 0.2);
    }
    const int id = list[index].value("id", static_cast<int>(index) + 1);
    char label[64];
    std::snprintf(label, sizeof label, "%d: %.1f mm", id, list[index].value("height", 0.0));
    const cv::Point origin(cvRound(pixels->centre.x) + 8, cvRound(pixels->centre.y) - 8);
    cv::putText(canvas, label, origin, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar::all(0), 3,
                cv::LINE_AA);
    cv::putText(canvas, label, origin, cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv::LINE_AA);
  }
  return canvas;
}

const std::string& CellSnapshot::StatusText() const {
  return status_.Get([this] { return state.StatusJson().dump(); });
}
const std::string& CellSnapshot::CyclesText() const {
  return cycles_.Get([this] { return state.CyclesJson().dump(); });
}
const std::string& CellSnapshot::ObjectsText() const {
  return objects_.Get([this] { return state.objects.dump(2) + "\n"; });
}
const std::string& CellSnapshot::LeftPng() const {
  return left_png_.Get([this] {
    return state.left_image.empty() ? std::string()
                                    : EncodePng(vision::ToColour8(state.left_image));
  });
}
const std::string& CellSnapshot::OverlayPng() const {
  return overlay_png_.Get([this] { return EncodePng(state.DrawOverlay()); });
}

void CellStatusBoard::Publish(std::shared_ptr<const CellSnapshot> snapshot) {
  std::shared_ptr<const CellSnapshot> previous;
  {
    std::lock_guard lock(mutex_);
    previous = std::move(latest_);
    latest_ = std::move(snapshot);
  }
  // `previous` is released here, outside the lock (or later by the last reader holding it).
}

std::shared_ptr<const CellSnapshot> CellStatusBoard::Latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

CellStatusRecorder::CellStatusRecorder(CellStatusBoard* board, std::string mode) : board_(board) {
  next_.mode = std::move(mode);
}

void CellStatusRecorder::SetSensed(nlohmann::json objects, cv::Mat left_image,
                                   std::optional<calib::ProjectionMatrix> P1,
                                   std::optional<calib::Intrinsics> intrinsics) {
  next_.objects = std::move(objects);
  next_.left_image = std::move(left_image);
  next_.P1 = std::move(P1);
  next_.intrinsics = std::move(intrinsics);
  next_.outcomes.clear();
  next_.objects_cycle = 0;
  ++next_.image_version;
  sensed_pending_ = true;
}

void CellStatusRecorder::RecordCycle(const robot::CycleLog& log, const robot::RobotLink& link) {
  CellState& s = next_;
  ++s.cycles;
  s.poses_published += log.published;
  s.refused += log.refused;
  if (log.status == robot::kErrorSensingFailed) ++s.sense_errors;
  if (log.ack == robot::AckKind::kTimeout) ++s.ack_timeouts;
  if (log.ack == robot::AckKind::kPeerLost) ++s.peer_lost;
  const double now = UnixNow();
  s.recent_cycles.push_back({log.cycle, log.request_sequence, log.objects, log.published,
                             log.refused, robot::PublishedStatusCode(log.status), log.error,
                             AckName(log.ack), log.sense_ms,
                             log.publish_ms, log.ack_ms, log.cycle_ms, now});
  while (s.recent_cycles.size() > CellState::kRecentCycles) s.recent_cycles.pop_front();
  if (!log.error.empty()) {
    s.last_error = "status " + std::to_string(log.status) + ": " + log.error;
    s.last_error_cycle = log.cycle;
    s.last_error_unix_time_s = now;
  }
  if (sensed_pending_) {
    s.objects_cycle = log.cycle;
    s.outcomes.clear();
    for (const robot::PickOutcome& outcome : log.picks) s.outcomes[outcome.object_id] = outcome;
    sensed_pending_ = false;
  }
  s.last_request_sequence = log.request_sequence;
  s.last_result_sequence = log.request_sequence;
  for (const robot::PickOutcome& outcome : log.picks) {
    if (outcome.admitted) s.last_pick_sequence = std::max(s.last_pick_sequence, outcome.sequence);
  }
  s.last_cycle_end_unix_s = now;
  PublishNow(&link);
}

void CellStatusRecorder::RecordLink(const robot::RobotLink& link) { PublishNow(&link); }

void CellStatusRecorder::PublishNow(const robot::RobotLink* link) {
  if (link != nullptr) {
    next_.has_link = true;
    next_.link_transport = link->Describe();
    next_.link_stats = link->Stats();
  }
  ++next_.version;
  next_.unix_time_s = UnixNow();
  board_->Publish(std::make_shared<const CellSnapshot>(next_));
}

}  // namespace hnnstereo::web
