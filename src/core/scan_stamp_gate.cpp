#include "mrslam/scan_stamp_gate.h"

#include <algorithm>

namespace mrslam {

namespace {
std::string seconds(double s) { return std::to_string(s) + " s"; }

std::string aheadReason(double t, double now, const std::optional<double>& last) {
  std::string reason = "scan stamped";
  if (now > 0) reason += " " + seconds(t - now) + " ahead of the clock";
  if (last) reason += std::string(now > 0 ? " and" : "") + " " + seconds(t - *last) + " after the last scan";
  return reason;
}
}  // namespace

StampVerdict ScanStampGate::check(double t, double now) {
  StampVerdict verdict;
  if (t == 0) return {StampVerdict::Kind::kRefuse, "scan stamped 0", 0};
  verdict.clock_lag = now > 0 ? std::max(0.0, t - now) : 0;
  const double horizon = std::max(now, last_.value_or(now));
  if ((now > 0 || last_) && t > horizon + rules_.future_tolerance) {
    verdict.kind = StampVerdict::Kind::kRefuse;
    verdict.reason = aheadReason(t, now, last_);
    return verdict;
  }
  if (!last_ || t >= *last_ - rules_.max_time_jump) {
    going_back_ = 0;
    return verdict;
  }
  const bool in_order = going_back_ == 0 || t > last_back_;
  going_back_ = in_order ? going_back_ + 1 : 1;
  last_back_ = t;
  if (going_back_ < rules_.restart_scans) {
    verdict.kind = StampVerdict::Kind::kRefuse;
    verdict.reason = "scan stamped " + seconds(*last_ - t) + " before the last one";
    return verdict;
  }
  verdict.kind = StampVerdict::Kind::kRestart;
  verdict.reason = "time went back " + seconds(*last_ - t) + " for " + std::to_string(going_back_) + " scans in a row";
  last_.reset();
  going_back_ = 0;
  return verdict;
}

}  // namespace mrslam
