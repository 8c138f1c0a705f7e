// The pick cell's matcher (PickCellMatcherOptions, what `pick`, `serve` and the facade's
// SensePositions start from) takes hnn-default's objective and dynamics from the preset itself,
// and the data term's names are the library's one pair (DataTermKindName / ParseDataTermKind).
#include <gtest/gtest.h>

#include "vision/sensing/position_sensing.h"
#include "vision/stereo/correlation.h"
#include "vision/stereo/matcher_presets.h"

namespace hnnstereo::vision {
namespace {

TEST(PickCellSettings, ObjectiveAndDynamicsAreThoseOfTheDefaultPreset) {
  const MatcherOptions cell = PickCellMatcherOptions();
  const MatcherOptions preset = AccurateDefaultPreset().matcher;
  EXPECT_EQ(cell.energy.objective, preset.energy.objective);
  const hnn::DynamicsOptions& a = cell.dynamics;
  const hnn::DynamicsOptions& b = preset.dynamics;
  EXPECT_EQ(a.stop_rule, b.stop_rule);
  EXPECT_EQ(a.energy_interval, b.energy_interval);
  EXPECT_EQ(a.stable_checks, b.stable_checks);
  EXPECT_EQ(a.decision_tolerance, b.decision_tolerance);
  EXPECT_EQ(a.energy_tolerance, b.energy_tolerance);
  EXPECT_EQ(a.activation, b.activation);
  EXPECT_EQ(a.alpha, b.alpha);
  EXPECT_EQ(a.initial_state, b.initial_state);
  EXPECT_EQ(a.time_step, b.time_step);
  EXPECT_EQ(a.max_steps, b.max_steps);
  EXPECT_EQ(a.seed, b.seed);
}

TEST(PickCellSettings, DataTermNamesRoundTrip) {
  for (DataTermOptions::Kind kind :
       {DataTermOptions::Kind::kZncc, DataTermOptions::Kind::kCensus}) {
    ASSERT_TRUE(ParseDataTermKind(DataTermKindName(kind)).has_value());
    EXPECT_EQ(*ParseDataTermKind(DataTermKindName(kind)), kind);
  }
  EXPECT_EQ(DataTermKindName(DataTermOptions::Kind::kCensus), "census");
  EXPECT_FALSE(ParseDataTermKind("sad").has_value());
}

}  // namespace
}  // namespace hnnstereo::vision
