// scripts/corpus (tools/corpus/corpus.py) on a small catkin tree written here
// (test/corpus/src): which files are descriptions, the arguments a launch file passes,
// the table's rows and counts.
#include <gtest/gtest.h>

#include <string>

#include "run_command.h"

namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;

mechanism_sim::testing_util::CommandResult corpus(const std::string& args) {
  return mechanism_sim::testing_util::runCommand("/usr/bin/python3 " + kSource + "/tools/corpus/corpus.py --simulate " +
                                                 SIMULATE_BIN + " " + args + " " + kSource + "/test/corpus/src 2>/dev/null");
}

// The macro-only file is no description; the pendulum takes length:=0.5 from the launch file.
TEST(CorpusCli, ListsTheDescriptionsWithTheirLaunchArguments) {
  const auto r = corpus("--list");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("demo_description/urdf/pendulum.urdf.xacro length:=0.5  (launch)\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("demo_description/urdf/reversed.urdf \n"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("pendulum_macro.xacro"), std::string::npos) << r.out;
}

// One row each: the pendulum runs (one link moves: 2 links, 1 joint, no loop), the reversed
// limit is refused in one line with its cause; no defect, so exit code 0.
TEST(CorpusCli, RunsEachAndCountsRunsRefusalsAndDefects) {
  const auto r = corpus("--duration 0.1");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("| demo_description/urdf/pendulum.urdf.xacro | length:=0.5 | runs |  | 2 | 1 | 0 | "),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("| demo_description/urdf/reversed.urdf |  | refused: simulate: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("reversed.urdf:10: limit: lower limit exceeds upper limit | loader | 2 | 1 |"),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("2 configurations: 1 run, 1 refused, 0 defects"), std::string::npos) << r.out;
}

}  // namespace
