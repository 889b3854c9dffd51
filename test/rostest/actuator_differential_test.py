#!/usr/bin/env python3
"""~actuator_effort_command on a differential (test/urdf/differential_wrist.urdf: two discs
on vertical axles, no gravity torque; E = [20 40; 30 -60]; the rotors' B = E^T diag(J) E =
[0.022 -0.028; -0.028 0.088] beside the discs' diag(0.02, 0.03)). Motor torques tau_theta
reach the joints as tau_q = E^T tau_theta, each motor on both joints; from rest the joints
then accelerate at (M + B)^-1 E^T tau_theta, constant, so after t s q_dot = a t and
q = a t^2 / 2 (exact for the integrator); the motors turn at theta = E q. An actuator not
named keeps its last torque."""
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState

from node_client import advance_service, connected_publisher

PKG = "mechanism_sim"
E = ((20.0, 40.0), (30.0, -60.0))
MB = ((0.02 + 0.022, -0.028), (-0.028, 0.03 + 0.088))  # M + B
H = 1e-3  # config/default.yaml's step


def joint_efforts(tau_theta):  # E^T tau_theta
    return [E[0][k] * tau_theta[0] + E[1][k] * tau_theta[1] for k in range(2)]


def solve(A, b):  # A x = b, 2 x 2
    det = A[0][0] * A[1][1] - A[0][1] * A[1][0]
    return [(A[1][1] * b[0] - A[0][1] * b[1]) / det, (A[0][0] * b[1] - A[1][0] * b[0]) / det]


def joints():
    js = rospy.wait_for_message("/joint_states", JointState, 10.0)
    i = [js.name.index(n) for n in ("joint_a", "joint_b")]
    return [js.position[k] for k in i], [js.velocity[k] for k in i], [js.effort[k] for k in i]


def motors():
    a = rospy.wait_for_message("/mechanism_sim/actuator_states", JointState, 10.0)
    assert list(a.name) == ["m1", "m2"], a.name
    return list(a.position), list(a.velocity), list(a.effort)


class ActuatorDifferential(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("actuator_differential_test")
        cls.pub = connected_publisher("/mechanism_sim/actuator_effort_command", JointState)
        cls.advance = advance_service()

    def command(self, names, efforts):
        self.pub.publish(JointState(name=names, effort=efforts))
        time.sleep(1.0)  # the node's callback has run

    def test_1_motor_torques_reach_both_joints_by_e_transpose(self):
        tau_theta = [0.01, -0.005]
        self.command(["m1", "m2"], tau_theta)
        tau_q = joint_efforts(tau_theta)  # [0.05, 0.7]
        a = solve(MB, tau_q)
        steps = 200
        self.advance(steps)
        t = steps * H
        q, q_dot, tau = joints()
        for k in range(2):
            self.assertAlmostEqual(tau[k], tau_q[k], delta=1e-12 * abs(tau_q[1]))
            self.assertAlmostEqual(q_dot[k], a[k] * t, delta=1e-9 * abs(a[1]) * t)
            self.assertAlmostEqual(q[k], 0.5 * a[k] * t * t, delta=1e-9 * abs(a[1]) * t * t)
        theta, theta_dot, tau_m = motors()
        for i in range(2):
            self.assertAlmostEqual(theta[i], E[i][0] * q[0] + E[i][1] * q[1], delta=1e-9 * 60 * abs(q[1]))
            self.assertAlmostEqual(theta_dot[i], E[i][0] * q_dot[0] + E[i][1] * q_dot[1], delta=1e-9 * 60 * abs(q_dot[1]))
            self.assertAlmostEqual(tau_m[i], tau_theta[i], delta=1e-15)

    def test_2_an_actuator_not_named_keeps_its_torque(self):
        self.command(["m2"], [0.002])
        self.advance(1)
        q, q_dot, tau = joints()
        tau_q = joint_efforts([0.01, 0.002])  # m1 still at 0.01
        for k in range(2):
            self.assertAlmostEqual(tau[k], tau_q[k], delta=1e-12 * abs(tau_q[0]))
        theta, theta_dot, tau_m = motors()
        self.assertAlmostEqual(tau_m[0], 0.01, delta=1e-15)
        self.assertAlmostEqual(tau_m[1], 0.002, delta=1e-15)


if __name__ == "__main__":
    rostest.rosrun(PKG, "actuator_differential_test", ActuatorDifferential)
