#!/usr/bin/env python3
"""~actuator_limits on urdf/winch.urdf: 10 kg on a drum of radius 0.05 m behind 20:1, the
motor's line 0.5 N m stall, 400 rad/s no load, the drive asking 15 rad/s of the drum. In the
saturating mode the drum settles where the line meets the load, 0.5 (1 - 20 w / 400) =
m g r / 20 (w = 10.19 rad/s), the motor giving m g r / 20 = 0.245 N m, its speed 20 w.
~actuator_limits set false while running: the drive, behind its profile, moves with it from
there (15 rad/s at once) and the motor gives what the load needs, above its line; set true
again: the drum settles back where the line meets the load."""
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState

from node_client import advance_service

PKG = "mechanism_sim"
N, LOAD = 20.0, 10 * 9.81 * 0.05
SETTLED = 400 / N * (1 - LOAD / N / 0.5)


class ActuatorLimits(unittest.TestCase):
    def test_the_drum_settles_where_the_line_meets_the_load(self):
        rospy.init_node("actuator_limits_test")
        advance = advance_service()
        advance(3000)  # 3 s of 1 ms
        time.sleep(0.5)  # (the state published after the steps)
        js = rospy.wait_for_message("/joint_states", JointState, 10.0)
        w = js.velocity[js.name.index("drum_joint")]
        self.assertAlmostEqual(w, SETTLED, delta=1e-9 * SETTLED)
        a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
        self.assertEqual(list(a.name), ["winch_motor"])
        self.assertAlmostEqual(a.velocity[0], N * w, delta=1e-9 * N * SETTLED)
        self.assertAlmostEqual(a.effort[0], LOAD / N, delta=1e-9 * LOAD / N)

        # the sizing mode from the next ~advance on: the drive's profile speed, whatever the torque
        rospy.set_param("/mechanism_sim/actuator_limits", False)
        advance(500)
        time.sleep(0.5)
        js = rospy.wait_for_message("/joint_states", JointState, 10.0)
        self.assertAlmostEqual(js.velocity[js.name.index("drum_joint")], 15.0, delta=1e-9 * 15)
        a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
        self.assertAlmostEqual(a.velocity[0], N * 15.0, delta=1e-9 * N * 15)
        self.assertAlmostEqual(a.effort[0], LOAD / N, delta=1e-9 * LOAD / N)  # 0.245 N m at 300 rad/s:
        self.assertGreater(a.effort[0], 0.5 * (1 - N * 15.0 / 400))  # above the line's 0.125 N m there

        # and bounded again: back to where the line meets the load
        rospy.set_param("/mechanism_sim/actuator_limits", True)
        advance(3000)
        time.sleep(0.5)
        js = rospy.wait_for_message("/joint_states", JointState, 10.0)
        w = js.velocity[js.name.index("drum_joint")]
        self.assertAlmostEqual(w, SETTLED, delta=1e-9 * SETTLED)
        a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
        self.assertAlmostEqual(a.effort[0], LOAD / N, delta=1e-9 * LOAD / N)


if __name__ == "__main__":
    rostest.rosrun(PKG, "actuator_limits_test", ActuatorLimits)
