// mechanism_sim_node: thin glue; the physics is in the core, the model in the loader.
#include <ros/ros.h>

#include "sim_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "mechanism_sim");
  mechanism_sim::SimNode node;
  if (!node.init()) return 1;
  node.run();
  return 0;
}
