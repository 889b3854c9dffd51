#!/usr/bin/env python3
"""~actuator_states and ~actuator_effort_command on a pendulum behind an 80:1 gearbox
(test/urdf/geared_pendulum.urdf.xacro: m g L = 9.81 N m, q = 0 horizontal, gravity's torque
m g L cos q, the arm 0.501 kg m^2 about the hinge; the rotor's 4e-5 kg m^2 from
~actuators_file), paused at q = 1 rad. A motor torque tau_m reaches the joint as N tau_m
(tau_q = E^T tau_theta); tau_m = -m g L cos(1) / N holds the arm where it is. The motor's
position, speed and torque are N q, N q_dot and tau_m."""
import math
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState

from node_client import advance_service, connected_publisher

PKG = "mechanism_sim"
N, MGL, Q0 = 80.0, 2 * 9.81 * 0.5, 1.0
I_ARM = 2 * 0.5**2 + 1e-3  # the arm about the hinge
HOLD = -MGL * math.cos(Q0) / N


def joint():
    js = rospy.wait_for_message("/joint_states", JointState, 10.0)
    i = js.name.index("hinge")
    return js.position[i], js.velocity[i], js.effort[i]


def motor():
    a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
    assert list(a.name) == ["motor"], a.name
    return a.position[0], a.velocity[0], a.effort[0]


class Actuator(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("actuator_test")
        cls.pub = connected_publisher("/mechanism_sim/actuator_effort_command", JointState)
        cls.advance = advance_service()

    def command(self, names, efforts):
        self.pub.publish(JointState(name=names, effort=efforts))
        time.sleep(1.0)  # the node's callback has run

    def assert_geared(self):
        q, q_dot, tau = joint()
        theta, theta_dot, tau_m = motor()
        self.assertAlmostEqual(theta, N * q, delta=1e-12 * N)
        self.assertAlmostEqual(theta_dot, N * q_dot, delta=1e-12 * N * max(1.0, abs(q_dot)))
        return q, q_dot, tau, tau_m

    def test_1_at_rest_the_motor_is_n_times_the_joint(self):
        q, q_dot, tau, tau_m = self.assert_geared()
        self.assertAlmostEqual(q, Q0, delta=1e-12)
        self.assertAlmostEqual(tau_m, 0.0, delta=1e-15)

    def test_2_a_motor_torque_holds_the_arm(self):
        self.command(["motor"], [HOLD])
        self.advance(1000)  # 1 s
        q, q_dot, tau, tau_m = self.assert_geared()
        self.assertAlmostEqual(tau, N * HOLD, delta=1e-12 * MGL)  # the joint's effort: N times the motor's
        self.assertAlmostEqual(tau_m, HOLD, delta=1e-12 * MGL / N)
        self.assertAlmostEqual(q, Q0, delta=1e-9)  # held: gravity's torque is met
        self.assertAlmostEqual(q_dot, 0.0, delta=1e-9)

    def test_3_bad_commands_are_rejected_whole(self):
        for names, efforts in ((["motor", "nope"], [0.0, 0.0]), (["motor"], [float("nan")]), (["motor"], [])):
            self.pub.publish(JointState(name=names, effort=efforts))
        time.sleep(1.0)
        self.advance(10)
        q, q_dot, tau, tau_m = self.assert_geared()
        self.assertAlmostEqual(tau, N * HOLD, delta=1e-12 * MGL)

    def test_4_a_smaller_torque_lets_it_fall_geared(self):
        self.command(["motor"], [0.5 * HOLD])
        # from rest the arm and the rotor accelerate together: (I + N^2 J) q_ddot = N tau_m +
        # m g L cos q, with J = 4e-5 kg m^2 from ~actuators_file (the file's 2e-5 would make
        # it 20% faster); one 1 ms step moves q_dot to q_ddot h, to O(h)
        self.advance(1)
        q, q_dot, tau, tau_m = self.assert_geared()
        q_ddot = (0.5 * N * HOLD + MGL * math.cos(Q0)) / (I_ARM + N * N * 4e-5)
        self.assertAlmostEqual(q_dot, q_ddot * 1e-3, delta=1e-2 * abs(q_ddot) * 1e-3)
        self.advance(299)
        q, q_dot, tau, tau_m = self.assert_geared()
        self.assertAlmostEqual(tau, 0.5 * N * HOLD, delta=1e-12 * MGL)
        self.assertAlmostEqual(tau_m, 0.5 * HOLD, delta=1e-12 * MGL / N)
        self.assertGreater(q, Q0 + 1e-3)  # falls toward hanging
        self.assertGreater(q_dot, 1e-3)


if __name__ == "__main__":
    rostest.rosrun(PKG, "actuator_test", Actuator)
