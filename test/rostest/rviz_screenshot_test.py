#!/usr/bin/env python3
"""Screenshot of the X display rviz draws on; the slider-crank's green connecting rod and
orange slider must be on screen (an empty scene has neither colour), and the magenta
reaction arrows of ~constraint_markers (namespace "reactions"). Private parameters set how
many pixels of each colour a model must show: ~min_green, ~min_orange (150 each: links in
those materials) and ~min_magenta (40: the reaction arrows, drawn for every model)."""
import os
import subprocess
import tempfile
import time
import unittest

import rospy
import rostest
from sensor_msgs.msg import JointState


def read_ppm(path):
    data = open(path, "rb").read()
    magic, w, h, maxval, pixels = data.split(maxsplit=4)
    assert magic == b"P6" and maxval == b"255", "unexpected PPM format"
    return int(w), int(h), pixels


def count_colours(pixels):
    green = orange = magenta = 0
    for i in range(0, len(pixels) - 2, 3):
        r, g, b = pixels[i], pixels[i + 1], pixels[i + 2]
        if g > 140 and 20 < r < 130 and b < 140 and g - r > 60:
            green += 1   # rod: rgba 0.2 0.8 0.3, shaded
        elif r > 150 and 50 < g < 130 and b < 100 and r - g > 60:
            orange += 1  # slider: rgba 0.8 0.3 0.2, shaded
        elif r > 150 and b > 140 and g < 120 and r - g > 80 and b - g > 60:
            magenta += 1  # reaction arrows: rgba 0.95 0.3 0.9
    return green, orange, magenta


class RvizDrawsTheMechanism(unittest.TestCase):
    def test_links_are_on_screen(self):
        self.assertTrue(os.environ.get("DISPLAY"), "no DISPLAY: scripts/test starts Xvfb")
        rospy.wait_for_message("/joint_states", JointState, 30.0)
        # one file per test (the two rviz tests once shared one name)
        shot = os.path.join(tempfile.gettempdir(), "mechanism_sim_%s.png" % rospy.get_name().strip("/"))
        need = (rospy.get_param("~min_green", 150), rospy.get_param("~min_orange", 150),
                rospy.get_param("~min_magenta", 40))
        best = (0, 0, 0)
        # rviz takes a while to start under software GL: on a loaded 2-core machine the
        # xacro arm's window was still blank after 60 s once, and the demo's after 100 s
        # once (alone either shows in 5 s)
        deadline = time.time() + 200
        while time.time() < deadline:
            time.sleep(3.0)
            subprocess.run(["import", "-window", "root", shot], check=True, timeout=30)
            ppm = shot[:-4] + ".ppm"
            subprocess.run(["convert", shot, ppm], check=True, timeout=30)
            w, h, pixels = read_ppm(ppm)
            counts = count_colours(pixels)
            best = tuple(max(a, b) for a, b in zip(best, counts))
            if all(b >= n for b, n in zip(best, need)):
                break
        rospy.loginfo("rviz screenshot %s: %d rod pixels, %d slider pixels, %d arrow pixels", shot, *best)
        self.assertGreaterEqual(best[0], need[0], "the green links are not drawn (screenshot: %s)" % shot)
        self.assertGreaterEqual(best[1], need[1], "the orange links are not drawn (screenshot: %s)" % shot)
        self.assertGreaterEqual(best[2], need[2], "the reaction arrows are not drawn (screenshot: %s)" % shot)


if __name__ == "__main__":
    rospy.init_node("rviz_screenshot_test")
    rostest.rosrun("mechanism_sim", "rviz_draws_the_mechanism", RvizDrawsTheMechanism)
