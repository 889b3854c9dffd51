#include "pacer.h"

#include <algorithm>

#include <ros/console.h>

namespace mechanism_sim {

Pacer::Pacer(double target, double sim_time) : target_(target) {
  restart(sim_time);
  rate_wall_ = pace_wall_;
  rate_sim_ = sim_time;
}

void Pacer::restart(double sim_time) {
  std::lock_guard<std::mutex> lock(mutex_);
  pace_wall_ = ros::WallTime::now();
  pace_sim_ = sim_time;
  if (sim_time < rate_sim_) {  // a reset took time back: measure afresh
    rate_wall_ = pace_wall_;
    rate_sim_ = sim_time;
  }
}

void Pacer::pace(double sim_time) {
  const ros::WallTime now = ros::WallTime::now();
  double ahead = 0.0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if ((now - rate_wall_).toSec() >= 1.0) {
      achieved_ = (sim_time - rate_sim_) / (now - rate_wall_).toSec();
      rate_wall_ = now;
      rate_sim_ = sim_time;
    }
    if (target_ <= 0) return;  // as fast as possible
    ahead = (sim_time - pace_sim_) / target_ - (now - pace_wall_).toSec();
  }
  if (ahead > 0) {
    behind_ = false;
    ros::WallDuration(std::min(ahead, 0.05)).sleep();
  } else if (ahead < -0.1) {
    behind_ = true;
    if ((now - last_warn_).toSec() > 5.0) {
      ROS_WARN("mechanism_sim: falling behind real time by %.2f s (real-time factor %.2f of %.2f)", -ahead,
               achieved_.load(), target_);
      last_warn_ = now;
    }
    restart(sim_time);  // do not try to catch up a lost second in a burst
  }
}

}  // namespace mechanism_sim
