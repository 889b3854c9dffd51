#!/usr/bin/env python3
"""~actuator_limits on urdf/winch.urdf: 10 kg on a drum of radius 0.05 m behind 20:1, the
motor's line 0.5 N m stall, 400 rad/s no load, the drive asking 15 rad/s of the drum. In the
saturating mode the drum settles where the line meets the load, 0.5 (1 - 20 w / 400) =
m g r / 20 (w = 10.19 rad/s), the motor giving m g r / 20 = 0.245 N m, its speed 20 w."""
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState

from mechanism_sim.srv import StepSimulation

PKG = "mechanism_sim"
N, LOAD = 20.0, 10 * 9.81 * 0.05
SETTLED = 400 / N * (1 - LOAD / N / 0.5)


class ActuatorLimits(unittest.TestCase):
    def test_the_drum_settles_where_the_line_meets_the_load(self):
        rospy.init_node("actuator_limits_test")
        rospy.wait_for_service("/mechanism_sim/advance", 10.0)
        advance = rospy.ServiceProxy("/mechanism_sim/advance", StepSimulation)
        advance(3000)  # 3 s of 1 ms
        time.sleep(0.5)  # (the state published after the steps)
        js = rospy.wait_for_message("/joint_states", JointState, 10.0)
        w = js.velocity[js.name.index("drum_joint")]
        self.assertAlmostEqual(w, SETTLED, delta=1e-9 * SETTLED)
        a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
        self.assertEqual(list(a.name), ["winch_motor"])
        self.assertAlmostEqual(a.velocity[0], N * w, delta=1e-9 * N * SETTLED)
        self.assertAlmostEqual(a.effort[0], LOAD / N, delta=1e-9 * LOAD / N)


if __name__ == "__main__":
    rostest.rosrun(PKG, "actuator_limits_test", ActuatorLimits)
