// Wall-clock pacing of the node: keeps simulation time moving at a target factor of wall
// time (doc/node.md "Time, pausing and pacing", ~real_time_factor). After each output
// sample it sleeps while the simulation is ahead; when it falls behind by more than 0.1 s
// it warns (every 5 s at most), reports it, and goes on from there instead of catching up
// in a burst.
#pragma once
#include <atomic>
#include <mutex>

#include <ros/time.h>

namespace mechanism_sim {

class Pacer {
 public:
  // target: simulated seconds per wall second; 0 runs as fast as possible.
  Pacer(double target, double sim_time);
  // Paces from here: after a pause, a reset, or a lag.
  void restart(double sim_time);
  // After a sample that reached sim_time: measures the achieved factor, then sleeps while
  // the simulation is ahead of the target (at most 0.05 s per call).
  void pace(double sim_time);

  double target() const { return target_; }
  double achieved() const { return achieved_; }  // over the last second or more
  bool behind() const { return behind_; }

 private:
  const double target_;
  std::mutex mutex_;          // restart() comes from service callbacks
  ros::WallTime pace_wall_;   // wall time and simulation time that pacing counts from
  double pace_sim_ = 0.0;
  ros::WallTime rate_wall_;   // start of the window the achieved factor is measured over
  double rate_sim_ = 0.0;
  ros::WallTime last_warn_{0};
  std::atomic<double> achieved_{0.0};
  std::atomic<bool> behind_{false};
};

}  // namespace mechanism_sim
