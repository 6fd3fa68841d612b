// A nodelet manager built with ThreadSanitizer (scripts/tsan): the same as `nodelet manager`
// (nodelet::Loader reads num_worker_threads from its private parameters), but an instrumented
// executable, since TSan cannot be preloaded into Debian's uninstrumented /usr/lib/nodelet/nodelet.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "manager");
  nodelet::Loader loader;
  ros::spin();
  return 0;
}
