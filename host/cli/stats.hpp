// Summary statistics of the figures the eval and bench commands print.
#pragma once

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <nlohmann/json.hpp>

namespace fb::cli {

// Nearest-rank q-quantile (q in [0, 1]) of v; 0 when v is empty.
inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto i =
      std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(i), v.end());
  return v[i];
}

// A figure's samples over frames, captures or subjects. Non-finite values (a fit that did not
// run) are skipped; an empty set reads NaN, which the JSON prints as null.
class Samples {
 public:
  void add(double x) {
    if (std::isfinite(x)) v_.push_back(x);
  }
  bool empty() const { return v_.empty(); }
  std::size_t size() const { return v_.size(); }
  double mean() const {
    return v_.empty() ? NAN
                      : std::accumulate(v_.begin(), v_.end(), 0.0) / static_cast<double>(v_.size());
  }
  double max() const { return v_.empty() ? NAN : *std::max_element(v_.begin(), v_.end()); }
  double min() const { return v_.empty() ? NAN : *std::min_element(v_.begin(), v_.end()); }

 private:
  std::vector<double> v_;
};

// Mean, median, 95th percentile and maximum of one figure over frames.
struct Summary {
  double mean = 0, median = 0, p95 = 0, max = 0;
  int count = 0;
};
inline Summary stats_of(const std::vector<double>& v) {
  Summary s;
  if (v.empty()) return s;
  s.count = static_cast<int>(v.size());
  s.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  s.median = percentile(v, 0.5);
  s.p95 = percentile(v, 0.95);
  s.max = *std::max_element(v.begin(), v.end());
  return s;
}
inline nlohmann::json to_json(const Summary& s) {
  return {{"mean", s.mean}, {"median", s.median}, {"p95", s.p95}, {"max", s.max}, {"n", s.count}};
}

}  // namespace fb::cli
