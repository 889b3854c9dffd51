// What the benchmarks time with: this thread's CPU time (on a loaded machine it tells a
// step's own cost apart from the time other processes took the core away) and the median
// of repeated runs.
#pragma once
#include <time.h>

#include <algorithm>
#include <vector>

namespace bench {

// CPU time of this thread [s].
inline double cpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The median of v (the upper one of an even count); v not empty.
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace bench
