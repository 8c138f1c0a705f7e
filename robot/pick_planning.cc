#include "robot/pick_planning.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <numbers>
#include <stdexcept>

namespace hnnstereo::robot {

std::string PickPlanningOptions::Check() const {
  if (!std::isfinite(approach_mm) || approach_mm < 0.0) return "approach_mm must be >= 0";
  if (!std::isfinite(retreat_mm) || retreat_mm < 0.0) return "retreat_mm must be >= 0";
  if (!(speed_fraction > 0.0 && speed_fraction <= 1.0)) return "speed_fraction must be in (0, 1]";
  return {};
}

double WrapYawDeg(double yaw_deg) {
  double wrapped = std::fmod(yaw_deg, 180.0);  // (-180, 180)
  if (wrapped > 90.0) wrapped -= 180.0;
  if (wrapped <= -90.0) wrapped += 180.0;
  return wrapped;
}

PickCommand PlanPick(const SensedObject& object, const Eigen::Isometry3d& robot_from_world,
                     const PickPlanningOptions& options, std::uint32_t sequence,
                     double capture_time_s) {
  if (auto error = options.Check(); !error.empty()) throw std::invalid_argument(error);
  PickCommand command;
  command.sequence = sequence;
  command.capture_time_s = capture_time_s;
  command.object_id = object.id;
  command.merged = object.merged;
  command.position_mm = robot_from_world * object.top_centre_world;
  const Eigen::Matrix3d rotation = robot_from_world.rotation();
  const double frame_yaw_deg = std::atan2(rotation(1, 0), rotation(0, 0)) * 180.0 / std::numbers::pi;
  command.yaw_deg = WrapYawDeg(object.yaw_deg + frame_yaw_deg);
  const double yaw_rad = command.yaw_deg * std::numbers::pi / 180.0;
  command.orientation = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                        Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitX());
  command.orientation.normalize();
  command.approach_mm = options.approach_mm;
  command.retreat_mm = options.retreat_mm;
  command.gripper = GripperAction::kClose;
  command.speed_fraction = options.speed_fraction;
  return command;
}

void SortTallestFirst(std::vector<SensedObject>* objects) {
  std::stable_sort(objects->begin(), objects->end(),
                   [](const SensedObject& a, const SensedObject& b) {
                     if (a.height_mm != b.height_mm) return a.height_mm > b.height_mm;
                     return a.id < b.id;
                   });
}

std::vector<SensedObject> SensedObjectsFromJson(const std::string& json_text) {
  const nlohmann::json json = nlohmann::json::parse(json_text, nullptr, false);
  if (json.is_discarded()) throw std::invalid_argument("OBJECTS.json is not valid JSON");
  if (!json.is_object() || !json.contains("objects") || !json["objects"].is_array()) {
    throw std::invalid_argument("OBJECTS.json has no 'objects' array");
  }
  std::vector<SensedObject> objects;
  for (const nlohmann::json& item : json["objects"]) {
    try {
      SensedObject object;
      object.id = item.at("id").get<int>();
      const auto& centroid = item.at("centroid");
      if (!centroid.is_array() || centroid.size() != 3) throw std::invalid_argument("centroid");
      object.top_centre_world = {centroid[0].get<double>(), centroid[1].get<double>(),
                                 centroid[2].get<double>()};
      object.height_mm = item.at("height").get<double>();
      // A round part has no orientation (yaw_deg null in OBJECTS.json): 0 is sent, no needless
      // wrist turn. Every other part needs a number.
      const bool round =
          item.contains("round") && item["round"].is_boolean() && item["round"].get<bool>();
      object.yaw_deg = round ? 0.0 : item.at("yaw_deg").get<double>();
      object.merged = item.value("merged", false);
      objects.push_back(object);
    } catch (const std::exception&) {
      throw std::invalid_argument(
          "OBJECTS.json: object " + std::to_string(objects.size() + 1) +
          " needs id, centroid [x, y, z], height and yaw_deg (numbers; yaw_deg may be "
          "null for a round part)");
    }
  }
  return objects;
}

}  // namespace hnnstereo::robot
