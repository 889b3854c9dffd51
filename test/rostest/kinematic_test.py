#!/usr/bin/env python3
"""A massless four-bar in the node (doc/node.md): held at rest, every joint in joint_states;
moved by ~drive_command on its held crank, the rocker's angle from joint_states matches
Freudenstein's closure equation (test/urdf/test_kinematic.cpp has the derivation)."""
import math
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState

from node_client import connected_publisher

PKG = "mechanism_sim"
A, B, C, D = 0.4, 0.1, math.sqrt(0.2), 0.3  # ground, crank, coupler, rocker


def rocker_angle(t):
    a = 2 * D * (A - B * math.sin(t))
    b = -2 * B * D * math.cos(t)
    c = C * C - A * A - B * B - D * D + 2 * A * B * math.sin(t)
    return math.asin(c / math.hypot(a, b)) - math.atan2(b, a)


def state():
    return rospy.wait_for_message("/joint_states", JointState, 10.0)


class Kinematic(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("kinematic_test")
        cls.pub = connected_publisher("/mechanism_sim/drive_command", JointState)

    def test_1_held_at_rest_with_every_joint(self):
        js = state()
        for name in ("crank_joint", "coupler_joint", "rocker_joint", "loop"):
            self.assertIn(name, js.name)
        for name in ("crank_joint", "coupler_joint", "rocker_joint"):
            self.assertAlmostEqual(js.position[js.name.index(name)], 0.0, places=9)

    def test_2_the_passive_joints_follow_the_commanded_crank(self):
        self.pub.publish(JointState(name=["crank_joint"], velocity=[2.0]))
        deadline = time.time() + 10
        js = state()
        while time.time() < deadline and js.position[js.name.index("crank_joint")] < 1.0:
            time.sleep(0.05)
            js = state()
        q = {n: js.position[js.name.index(n)] for n in ("crank_joint", "coupler_joint", "rocker_joint")}
        self.assertGreater(q["crank_joint"], 1.0)
        phi = q["crank_joint"] + q["coupler_joint"] + q["rocker_joint"]
        err = math.remainder(phi - rocker_angle(q["crank_joint"]), 2 * math.pi)
        self.assertLess(abs(err), 1e-9)


if __name__ == "__main__":
    rostest.rosrun(PKG, "node_kinematic", Kinematic)
