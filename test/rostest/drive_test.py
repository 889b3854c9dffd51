#!/usr/bin/env python3
"""The node with a driven mechanism: ~drive_command ramps the drive at ~drive_acceleration,
bad commands are rejected whole, ~joint_reactions names every joint and carries the
driving torque, and the reaction arrows are among the markers."""
import math
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState
from visualization_msgs.msg import MarkerArray

from mechanism_sim.msg import JointReactions
from node_client import connected_publisher

PKG = "mechanism_sim"
ACC = 20.0  # ~drive_acceleration in drive.test


def state():
    return rospy.wait_for_message("/joint_states", JointState, 10.0)


def crank_velocity():
    js = state()
    return js.velocity[js.name.index("crank_joint")]


class Drive(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("drive_test")
        cls.pub = connected_publisher("/mechanism_sim/drive_command", JointState)

    def command(self, names, velocities):
        self.pub.publish(JointState(name=names, velocity=velocities))

    def wait_velocity(self, target, timeout=10.0):
        deadline = time.time() + timeout
        v = None
        while time.time() < deadline:
            v = crank_velocity()
            if abs(v - target) < 1e-9:
                return v
            time.sleep(0.05)
        return v

    def test_1_runs_at_the_file_speed(self):
        self.assertAlmostEqual(crank_velocity(), 2 * math.pi, places=9)

    def test_2_command_ramps_to_the_new_speed(self):
        self.command(["crank_joint"], [2.0])
        # while ramping, the velocity moves at most ACC per second of simulation time
        seen = []
        deadline = time.time() + 10
        while time.time() < deadline:
            js = state()
            v = js.velocity[js.name.index("crank_joint")]
            seen.append((js.header.stamp.to_sec(), v))
            if abs(v - 2.0) < 1e-9:
                break
        self.assertAlmostEqual(seen[-1][1], 2.0, places=9)
        for (t0, v0), (t1, v1) in zip(seen, seen[1:]):
            if t1 > t0:
                self.assertLessEqual(abs(v1 - v0), ACC * (t1 - t0) * 1.5 + 1e-9)

    def test_3_bad_commands_are_rejected_whole(self):
        self.command(["crank_joint"], [3.0])
        self.assertAlmostEqual(self.wait_velocity(3.0), 3.0, places=9)
        for names, velocities in ((["crank_joint", "slider_joint"], [1.0, 1.0]),  # slider not driven
                                  (["crank_joint", "nope"], [1.0, 1.0]),
                                  (["crank_joint"], [float("nan")]),
                                  (["crank_joint"], [])):
            self.command(names, velocities)
        time.sleep(1.0)
        self.assertAlmostEqual(crank_velocity(), 3.0, places=9)

    def test_4_reactions_name_every_joint_and_carry_the_drive(self):
        r = rospy.wait_for_message("/mechanism_sim/joint_reactions", JointReactions, 10.0)
        self.assertEqual(list(r.name), ["crank_joint", "rod_joint", "slider_joint", "wrist_pin"])
        self.assertEqual(len(r.wrench), 4)
        # the drive's torque crosses zero twice a turn: its peak over a few samples is not zero
        peak = 0.0
        for _ in range(30):
            js = state()
            peak = max(peak, abs(js.effort[js.name.index("crank_joint")]))
        self.assertGreater(peak, 1e-2)
        r = rospy.wait_for_message("/mechanism_sim/joint_reactions", JointReactions, 10.0)
        for w in r.wrench:
            for x in (w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z):
                self.assertTrue(math.isfinite(x))
        # pin loads are not zero: the slider is pushed along
        self.assertGreater(math.hypot(r.wrench[3].force.x, r.wrench[3].force.z), 1e-3)

    def test_5_reaction_arrows_are_markers(self):
        deadline = time.time() + 10
        arrows = []
        while time.time() < deadline and not arrows:
            ma = rospy.wait_for_message("/mechanism_sim/constraint_markers", MarkerArray, 10.0)
            arrows = [m for m in ma.markers if m.ns == "reactions"]
        self.assertEqual(len(arrows), 4)
        for a in arrows:
            self.assertEqual(len(a.points), 2)


if __name__ == "__main__":
    rostest.rosrun(PKG, "drive_test", Drive)
