// The matcher's enums have one name each, the one every command, the facade, Python and the
// reports use (api/matcher_settings.cc resolves them): Name and Parse are inverses. The memory
// budget has one default, in MB as `--memory-budget-mb` takes it.
#include <gtest/gtest.h>

#include "host/decode.h"
#include "host/hopfield_network.h"
#include "host/hopfield_options.h"
#include "host/hopfield_problem.h"
#include "host/opencl_engine.h"

namespace hnnstereo::hnn {
namespace {

// Name(value) parses back to value, for every value; an unknown name parses to nothing.
template <class Enum, class NameFn, class ParseFn>
void ExpectRoundTrip(std::initializer_list<Enum> values, NameFn name, ParseFn parse) {
  for (Enum value : values) {
    const std::string_view text = name(value);
    EXPECT_NE(text, "unknown");
    ASSERT_TRUE(parse(text).has_value()) << text;
    EXPECT_EQ(*parse(text), value) << text;
  }
  EXPECT_FALSE(parse("no-such-name").has_value());
}

TEST(HopfieldOptionNames, ActivationNamesRoundTrip) {
  ExpectRoundTrip({Activation::kContinuous, Activation::kDiscrete}, ActivationName,
                  ParseActivation);
  EXPECT_EQ(ActivationName(Activation::kContinuous), "continuous");
}

TEST(HopfieldOptionNames, StopRuleNamesRoundTrip) {
  using Rule = DynamicsOptions::StopRule;
  ExpectRoundTrip({Rule::kEnergy, Rule::kDecisions}, StopRuleName, ParseStopRule);
  EXPECT_EQ(StopRuleName(Rule::kDecisions), "decisions");
}

TEST(HopfieldOptionNames, NetworkKindNamesRoundTrip) {
  ExpectRoundTrip({NetworkKind::kFeatureVsFeature, NetworkKind::kFeatureVsDisparity},
                  NetworkKindName, ParseNetworkKind);
  EXPECT_EQ(NetworkKindName(NetworkKind::kFeatureVsDisparity), "disparity");
}

TEST(HopfieldOptionNames, ObjectiveInitDecodeAndStorageNamesRoundTrip) {
  ExpectRoundTrip({Objective::kThesis, Objective::kPrinted0, Objective::kPrinted1,
                   Objective::kPrinted2, Objective::kGeometrySimilarity},
                  ObjectiveName, ParseObjective);
  ExpectRoundTrip({InitialState::kAllOff, InitialState::kAllOn, InitialState::kRandomBinary,
                   InitialState::kRandomContinuous, InitialState::kConstant,
                   InitialState::kConstantNoise, InitialState::kCorrelation},
                  InitialStateName, ParseInitialState);
  ExpectRoundTrip({DecodeMethod::kThesisPruning, DecodeMethod::kOneToOne}, DecodeMethodName,
                  ParseDecodeMethod);
  ExpectRoundTrip({WeightStorage::kAuto, WeightStorage::kCsr, WeightStorage::kBlockedFloat,
                   WeightStorage::kBlockedHalf, WeightStorage::kOnTheFly},
                  WeightStorageName, ParseWeightStorage);
}

TEST(HopfieldMemoryBudget, DefaultIs2048Megabytes) {
  EXPECT_EQ(kBytesPerMegabyte, std::size_t{1} << 20);
  EXPECT_EQ(kDefaultMemoryBudgetBytes, 2048 * kBytesPerMegabyte);
}

}  // namespace
}  // namespace hnnstereo::hnn
