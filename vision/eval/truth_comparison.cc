#include "vision/eval/truth_comparison.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace hnnstereo::vision {

TruthComparison CompareWithTruth(const std::vector<ObjectPose>& detected,
                                 const std::vector<SceneObject>& truth,
                                 double max_pairing_distance_mm) {
  struct Candidate {
    double distance;
    std::size_t truth_index, detected_index;
  };
  std::vector<Candidate> candidates;
  for (std::size_t t = 0; t < truth.size(); ++t) {
    for (std::size_t d = 0; d < detected.size(); ++d) {
      const double distance = (detected[d].centroid.head<2>() - truth[t].centre_mm).norm();
      if (distance <= max_pairing_distance_mm) candidates.push_back({distance, t, d});
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
  TruthComparison comparison;
  comparison.pairs.resize(truth.size());
  std::vector<bool> detection_used(detected.size(), false);
  for (std::size_t t = 0; t < truth.size(); ++t) comparison.pairs[t].truth_index = static_cast<int>(t);
  for (const Candidate& candidate : candidates) {
    TruthPairing& pair = comparison.pairs[candidate.truth_index];
    if (pair.detected_index >= 0 || detection_used[candidate.detected_index]) continue;
    detection_used[candidate.detected_index] = true;
    const ObjectPose& pose = detected[candidate.detected_index];
    const SceneObject& object = truth[candidate.truth_index];
    pair.detected_index = static_cast<int>(candidate.detected_index);
    pair.centroid_error_mm = candidate.distance;
    pair.height_error_mm = pose.height_mm - object.height_mm();
    pair.yaw_defined = object.shape == SceneObject::Shape::kBox;
    if (pair.yaw_defined) {
      // The yaw a robot gets: 0 for a top taken for round (app: SensedObjectsOf).
      const double sent_yaw = pose.round ? 0.0 : pose.yaw_deg;
      pair.yaw_error_deg = std::abs(NormaliseAxisAngle(sent_yaw - object.yaw_deg));
    }
    ++comparison.detected;
  }
  for (bool used : detection_used) {
    if (!used) ++comparison.false_objects;
  }
  return comparison;
}

}  // namespace hnnstereo::vision
