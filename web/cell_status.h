#pragma once
// What the cell's web page shows, as one immutable snapshot: the parts last sensed (exactly as
// OBJECTS.json) with what became of each pick, the left image they were sensed on, the link's
// state, the cycle counters and the recent cycles. The cell loop builds a new snapshot after each
// cycle (and while it waits for a trigger) and swaps it into a CellStatusBoard; the HTTP threads
// only ever read the latest one, so a slow or busy page never holds up a cycle.

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calib/calibration.h"
#include "robot/cell_loop.h"
#include "robot/link.h"

namespace hnnstereo::web {

/// One cycle as the page's plot and table show it.
struct CycleRecord {
  int cycle = 0;
  std::uint32_t request_sequence = 0;
  int objects = 0;
  int published = 0;
  int refused = 0;
  int status = 0;  ///< as the cell sees it: 2 result ready, or negative (PublishedStatusCode)
  std::string error;
  std::string ack;  ///< "acknowledged", "ack timeout", "stop", "peer lost"
  double sense_ms = 0.0, publish_ms = 0.0, ack_ms = 0.0, cycle_ms = 0.0;
  double unix_time_s = 0.0;  ///< when the cycle ended (wall clock)
};

/// Bytes made once, on first request, by whichever reader asks first; the others wait for them.
class LazyBytes {
 public:
  const std::string& Get(const std::function<std::string()>& make) const;

 private:
  mutable std::once_flag once_;
  mutable std::string bytes_;
};

/// Everything the page shows at one moment (plain data, copied by the recorder).
struct CellState {
  std::string mode = "serve";       ///< "serve" (the cell loop) or "view" (one pick result)
  std::uint64_t version = 0;        ///< +1 per snapshot published
  std::uint64_t image_version = 0;  ///< +1 whenever the objects and image change
  double unix_time_s = 0.0;         ///< when it was published (wall clock)

  nlohmann::json objects;  ///< OBJECTS.json, exactly; null before the first sensing
  int objects_cycle = 0;   ///< the cycle that sensed them (0: not from a cycle)
  cv::Mat left_image;      ///< the left image as captured (its own pixels); may be empty
  std::optional<calib::ProjectionMatrix> P1;  ///< to draw the parts on it; empty: no outlines
  /// A calibration with lens distortion refers P1 to undistorted pixels (docs/calibration.md):
  /// the outlines are projected with P1, then through K1 and D1 into left_image's pixels.
  std::optional<calib::Intrinsics> intrinsics;
  /// Per object id: what became of its pick in objects_cycle (absent: not offered to a link).
  std::map<int, robot::PickOutcome> outcomes;

  // The loop's counters since start (as CellLoopReport counts them).
  int cycles = 0, poses_published = 0, refused = 0, sense_errors = 0, ack_timeouts = 0,
      peer_lost = 0;
  std::deque<CycleRecord> recent_cycles;  ///< oldest first, at most kRecentCycles
  std::string last_error;                 ///< the last cycle's error that was not empty
  int last_error_cycle = 0;
  double last_error_unix_time_s = 0.0;

  // The link (absent in view mode).
  bool has_link = false;
  std::string link_transport;  ///< the link's Describe()
  robot::LinkStats link_stats;
  std::uint32_t last_request_sequence = 0;  ///< of the last trigger served
  std::uint32_t last_result_sequence = 0;   ///< the request the last published result answers
  std::uint32_t last_pick_sequence = 0;     ///< the last pick's sequence number, 0 = none yet
  double last_cycle_end_unix_s = 0.0;

  static constexpr std::size_t kRecentCycles = 100;

  /// The page's parts table with each part's outline, centre and yaw line in left-image pixels
  /// (when P1 and the image are known).
  nlohmann::json PartsJson() const;
  /// /api/status: everything but the images and the recent cycles.
  nlohmann::json StatusJson() const;
  /// /api/cycles.
  nlohmann::json CyclesJson() const;
  /// The left image with the parts' outlines, ids, centres and yaw lines; empty without an image.
  cv::Mat DrawOverlay() const;
};

/// A published state and its encodings, each made on first use and then shared by every request
/// for this snapshot (50 clients polling cost one PNG encoding per snapshot, on their threads).
struct CellSnapshot {
  explicit CellSnapshot(CellState data) : state(std::move(data)) {}
  const CellState state;
  const std::string& StatusText() const;
  const std::string& CyclesText() const;
  const std::string& ObjectsText() const;
  const std::string& LeftPng() const;     ///< empty without an image
  const std::string& OverlayPng() const;  ///< empty without an image

 private:
  LazyBytes status_, cycles_, objects_, left_png_, overlay_png_;
};

/// The latest snapshot, swapped under a mutex: the writer (the loop) replaces the pointer, readers
/// copy it. Neither holds the lock for more than a pointer copy.
class CellStatusBoard {
 public:
  void Publish(std::shared_ptr<const CellSnapshot> snapshot);
  /// Null before the first Publish.
  std::shared_ptr<const CellSnapshot> Latest() const;

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<const CellSnapshot> latest_;
};

/// The loop's side: keeps the counters and the recent cycles and publishes a fresh snapshot
/// to the board. Called only from the loop's thread.
class CellStatusRecorder {
 public:
  CellStatusRecorder(CellStatusBoard* board, std::string mode);

  /// The parts just sensed (OBJECTS.json), the left image as captured and the camera that saw
  /// it (P1, and the lens when the calibration has one: CellState::intrinsics). Published with
  /// the next RecordCycle (the cycle they belong to).
  void SetSensed(nlohmann::json objects, cv::Mat left_image,
                 std::optional<calib::ProjectionMatrix> P1,
                 std::optional<calib::Intrinsics> intrinsics = std::nullopt);
  /// After each cycle (CellLoopOptions::on_cycle): counts it, publishes.
  void RecordCycle(const robot::CycleLog& log, const robot::RobotLink& link);
  /// While waiting for a trigger (CellLoopOptions::on_idle): publishes the link's state.
  void RecordLink(const robot::RobotLink& link);
  /// Publishes what is known now (e.g. a view, or the state before the first cycle).
  void PublishNow(const robot::RobotLink* link = nullptr);

 private:
  CellStatusBoard* board_;
  CellState next_;  ///< the data of the next snapshot
  bool sensed_pending_ = false;
};

}  // namespace hnnstereo::web
