#pragma once
// Sensed part poses scored against the synthetic cell's truth (vision/synth): tests, `demo` and
// the acceptance harness. Not part of the library (ARCHITECTURE.md: no production target links
// the renderer or the evaluation).

#include <vector>

#include "vision/sensing/object_pose.h"
#include "vision/synth/scene_render.h"

namespace hnnstereo::vision {

/// Detected parts against the renderer's truth: greedy nearest pairs in the table plane.
struct TruthPairing {
  int truth_index = -1;
  int detected_index = -1;           ///< -1 when missed
  double centroid_error_mm = 0.0;    ///< in the table plane
  double height_error_mm = 0.0;      ///< detected - true
  double yaw_error_deg = 0.0;        ///< boxes: |difference| modulo 180; cylinders: 0
  bool yaw_defined = false;          ///< boxes only
};
struct TruthComparison {
  std::vector<TruthPairing> pairs;   ///< one per true part, in truth order
  int detected = 0;                  ///< true parts found
  int false_objects = 0;             ///< detections paired with no true part
};
TruthComparison CompareWithTruth(const std::vector<ObjectPose>& detected,
                                 const std::vector<SceneObject>& truth,
                                 double max_pairing_distance_mm = 25.0);

}  // namespace hnnstereo::vision
