// Who may publish under a name (a robot id, a robot's scan topic): the first publisher (a ROS
// node's name, from the message's connection header) heard, for as long as it keeps
// publishing. Another node using the name meanwhile is an impostor and is refused; once the
// holder has been silent for `timeout` seconds (a driver or peer that restarted under a new
// node name), the next publisher takes the name over.
#pragma once

#include <limits>
#include <string>

namespace mrslam {

class PublisherClaim {
 public:
  // Whether a publisher other than `publisher` holds the name at time `now` (seconds).
  bool heldByAnother(const std::string& publisher, double now, double timeout) const {
    return !holder_.empty() && publisher != holder_ && now - last_heard_ < timeout;
  }
  // `publisher` used the name at `now` and holds it from here on.
  void take(const std::string& publisher, double now) {
    holder_ = publisher;
    last_heard_ = now;
  }
  const std::string& holder() const { return holder_; }
  double lastHeard() const { return last_heard_; }

 private:
  std::string holder_;
  double last_heard_ = -std::numeric_limits<double>::infinity();
};

}  // namespace mrslam
