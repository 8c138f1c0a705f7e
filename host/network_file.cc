#include "host/network_file.h"

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <type_traits>

namespace hnnstereo::hnn {
namespace {

constexpr char kMagic[8] = {'H', 'N', 'N', 'E', 'T', '1', '\n', '\0'};

class Writer {
 public:
  template <typename T>
  void Put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    bytes_.append(raw, sizeof(T));
  }
  void PutRaw(const char* data, std::size_t n) { bytes_.append(data, n); }
  std::string Take() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  T Get(const char* what) {
    static_assert(std::is_arithmetic_v<T>);
    if (bytes_.size() - offset_ < sizeof(T)) {
      throw std::invalid_argument(std::string("network file truncated at ") + what);
    }
    T value;
    std::memcpy(&value, bytes_.data() + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  double Finite(const char* what) {
    const double value = Get<double>(what);
    if (!(value == value) || value > 1e300 || value < -1e300) {
      throw std::invalid_argument(std::string("network file: ") + what + " is not finite");
    }
    return value;
  }
  template <typename E>
  E Enum(const char* what, int count) {
    const auto value = Get<std::int32_t>(what);
    if (value < 0 || value >= count) {
      throw std::invalid_argument(std::string("network file: ") + what + " out of range");
    }
    return static_cast<E>(value);
  }
  std::size_t Remaining() const { return bytes_.size() - offset_; }
  void Skip(std::size_t n) { offset_ += n; }

 private:
  const std::string& bytes_;
  std::size_t offset_ = 0;
};

}  // namespace

std::string SerializeNetwork(const MatchingProblem& problem, const EnergyOptions& e,
                             const DynamicsOptions& d) {
  Writer w;
  w.PutRaw(kMagic, sizeof(kMagic));
  for (double v : {e.A, e.B, e.C, e.D, e.W1, e.W2, e.T, e.lambda, e.theta}) w.Put(v);
  w.Put(static_cast<std::int32_t>(e.objective));
  w.Put(static_cast<std::int32_t>(e.compatibility));
  w.Put(e.support_radius_px);
  w.Put(static_cast<std::int32_t>(e.distance_attenuation));
  for (double v : {e.attenuation_centre_px, e.attenuation_slope, e.weight_offset}) w.Put(v);
  w.Put(static_cast<std::int32_t>(d.activation));
  w.Put(d.alpha);
  w.Put(static_cast<std::int32_t>(d.initial_state));
  for (double v : {d.initial_value, d.initial_noise}) w.Put(v);
  w.Put(static_cast<std::uint64_t>(d.seed));
  for (double v : {d.time_step, d.tau}) w.Put(v);
  w.Put(static_cast<std::int32_t>(d.max_steps));
  w.Put(static_cast<std::int32_t>(d.energy_interval));
  w.Put(d.energy_tolerance);
  w.Put(static_cast<std::int32_t>(d.stable_checks));
  w.Put(static_cast<std::int32_t>(d.stop_rule));
  w.Put(d.decision_tolerance);
  w.Put(static_cast<std::int32_t>(d.max_updates));
  w.Put(static_cast<std::int32_t>(d.stable_updates));
  w.Put(d.update_tolerance);
  w.Put(static_cast<std::int32_t>(problem.kind));
  w.Put(static_cast<std::int32_t>(problem.dense));
  w.Put(static_cast<std::int32_t>(problem.n_columns));
  w.Put(static_cast<std::int64_t>(problem.left_points.size()));
  for (const Eigen::Vector2f& p : problem.left_points) {
    w.Put(p.x());
    w.Put(p.y());
  }
  w.Put(static_cast<std::int64_t>(problem.candidates.size()));
  for (const Candidate& c : problem.candidates) {
    w.Put(static_cast<std::int32_t>(c.left));
    w.Put(static_cast<std::int32_t>(c.column));
    w.Put(c.right_point.x());
    w.Put(c.right_point.y());
    w.Put(c.epipolar_distance_px);
    w.Put(c.correlation);
  }
  return w.Take();
}

CapturedNetwork ParseNetwork(const std::string& bytes) {
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    throw std::invalid_argument("not a network file (no HNNET1 header)");
  }
  Reader r(bytes);
  r.Skip(sizeof(kMagic));
  CapturedNetwork net;
  EnergyOptions& e = net.energy;
  for (double* v : {&e.A, &e.B, &e.C, &e.D, &e.W1, &e.W2, &e.T, &e.lambda, &e.theta}) {
    *v = r.Finite("energy constants");
  }
  e.objective = r.Enum<Objective>("objective", 5);
  e.compatibility = r.Enum<CompatibilityType>("compatibility", 2);
  e.support_radius_px = r.Finite("support radius");
  e.distance_attenuation = r.Enum<int>("distance attenuation", 2) != 0;
  for (double* v : {&e.attenuation_centre_px, &e.attenuation_slope, &e.weight_offset}) {
    *v = r.Finite("attenuation");
  }
  DynamicsOptions& d = net.dynamics;
  d.activation = r.Enum<Activation>("activation", 2);
  d.alpha = r.Finite("alpha");
  d.initial_state = r.Enum<InitialState>("initial state", 7);
  d.initial_value = r.Finite("initial value");
  d.initial_noise = r.Finite("initial noise");
  d.seed = r.Get<std::uint64_t>("seed");
  d.time_step = r.Finite("time step");
  d.tau = r.Finite("tau");
  d.max_steps = r.Get<std::int32_t>("max steps");
  d.energy_interval = r.Get<std::int32_t>("energy interval");
  d.energy_tolerance = r.Finite("energy tolerance");
  d.stable_checks = r.Get<std::int32_t>("stable checks");
  d.stop_rule = r.Enum<DynamicsOptions::StopRule>("stop rule", 2);
  d.decision_tolerance = r.Finite("decision tolerance");
  d.max_updates = r.Get<std::int32_t>("max updates");
  d.stable_updates = r.Get<std::int32_t>("stable updates");
  d.update_tolerance = r.Finite("update tolerance");
  if (auto why = e.Check(); !why.empty()) throw std::invalid_argument("network file: " + why);
  if (auto why = d.Check(); !why.empty()) throw std::invalid_argument("network file: " + why);
  MatchingProblem& p = net.problem;
  p.kind = r.Enum<NetworkKind>("network kind", 2);
  p.dense = r.Enum<int>("dense", 2) != 0;
  p.n_columns = r.Get<std::int32_t>("columns");
  const auto n_left = r.Get<std::int64_t>("left feature count");
  if (n_left < 0 || static_cast<std::uint64_t>(n_left) > r.Remaining() / 8) {
    throw std::invalid_argument("network file: left feature count beyond the file");
  }
  p.left_points.resize(static_cast<std::size_t>(n_left));
  for (Eigen::Vector2f& q : p.left_points) {
    const float x = r.Get<float>("left points");
    q = {x, r.Get<float>("left points")};
  }
  const auto n_candidates = r.Get<std::int64_t>("candidate count");
  if (n_candidates < 0 || static_cast<std::uint64_t>(n_candidates) > r.Remaining() / 24) {
    throw std::invalid_argument("network file: candidate count beyond the file");
  }
  p.candidates.resize(static_cast<std::size_t>(n_candidates));
  for (Candidate& c : p.candidates) {
    c.left = r.Get<std::int32_t>("candidates");
    c.column = r.Get<std::int32_t>("candidates");
    const float x = r.Get<float>("candidates");
    c.right_point = {x, r.Get<float>("candidates")};
    c.epipolar_distance_px = r.Get<float>("candidates");
    c.correlation = r.Get<float>("candidates");
  }
  if (r.Remaining() != 0) throw std::invalid_argument("network file: trailing bytes");
  if (auto why = p.Check(); !why.empty()) throw std::invalid_argument("network file: " + why);
  return net;
}

}  // namespace hnnstereo::hnn
