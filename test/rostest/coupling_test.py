#!/usr/bin/env python3
"""~coupling_reactions on the planetary train (urdf/planetary_gear.urdf: the ring held, the
sun at 10 rad/s, the carrier's 0.125 N m load carried by Willis' equation, lambda =
0.125 / 96): after 400 steps of 1 ms the node publishes what simulate --reactions writes
at t = 0.4 s."""
import csv
import os
import subprocess
import tempfile
import unittest

import roslib.packages
import rospy
import rostest
from sensor_msgs.msg import JointState

from node_client import advance_service

PKG = "mechanism_sim"
MODEL = os.path.join(roslib.packages.get_pkg_dir(PKG), "urdf/planetary_gear.urdf")
COUPLINGS = ["willis", "sun_planet0", "sun_planet1", "sun_planet2"]


def cli_reactions():
    """The last row's <name>.reaction columns of simulate --reactions over 0.4 s."""
    simulate = roslib.packages.find_node(PKG, "simulate")[0]
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "run.csv")
        subprocess.run([simulate, MODEL, "--duration", "0.4", "--dt", "1e-3", "--reactions", "--csv", out],
                       check=True, capture_output=True, timeout=120)
        with open(out) as f:
            rows = list(csv.reader(f))
    row = dict(zip(rows[0], rows[-1]))
    return float(row["time"]), [float(row[c + ".reaction"]) for c in COUPLINGS]


class Coupling(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("coupling_test")
        cls.advance = advance_service()

    def test_the_willis_reaction_is_simulates(self):
        self.advance(400)  # 0.4 s of 1 ms steps
        c = rospy.wait_for_message("/mechanism_sim/coupling_reactions", JointState, 10.0)
        js = rospy.wait_for_message("/joint_states", JointState, 10.0)
        self.assertAlmostEqual(js.position[js.name.index("sun_joint")], 4.0, delta=1e-9)  # 0.4 s at 10 rad/s
        self.assertEqual(list(c.name), COUPLINGS)
        self.assertEqual(len(c.effort), len(COUPLINGS))
        t, expected = cli_reactions()
        self.assertAlmostEqual(t, 0.4, delta=1e-12)
        self.assertAlmostEqual(c.effort[0], 0.125 / 96, delta=1e-6 * 0.125 / 96)
        for name, mine, cli in zip(COUPLINGS, c.effort, expected):
            # the CSV's 12 significant digits, character for character
            self.assertEqual("%.12g" % mine, "%.12g" % cli, name)


if __name__ == "__main__":
    rostest.rosrun(PKG, "coupling_test", Coupling)
