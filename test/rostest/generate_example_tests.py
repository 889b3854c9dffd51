#!/usr/bin/env python3
"""Writes one rostest per example mechanism: the real node on the model, checked by the
installed constraint_monitor (violation bound over 4 s, and the two joint points of every
extension loop closure that holds them together staying together on tf)."""
import glob
import os
import xml.etree.ElementTree as ET

HERE = os.path.dirname(os.path.abspath(__file__))
URDF = os.path.join(HERE, "..", "..", "urdf")
NS = "{https://mechanism-sim.github.io/urdf-extension}"

for path in sorted(glob.glob(os.path.join(URDF, "*.urdf"))):
    name = os.path.basename(path)[:-5]
    pairs = []
    for j in ET.parse(path).getroot().iter(NS + "joint"):
        # Only joints that hold their two points together; a prismatic, cylindrical,
        # screw or planar closure lets them move apart along its free directions.
        if j.find("parent") is None or j.get("type") not in ("revolute", "continuous", "spherical", "universal", "fixed"):
            continue
        a = j.find("origin").get("xyz", "0 0 0") if j.find("origin") is not None else "0 0 0"
        b = j.find("child_origin").get("xyz", "0 0 0") if j.find("child_origin") is not None else "0 0 0"
        pairs.append("{frame_a: %s, point_a: [%s], frame_b: %s, point_b: [%s]}" % (
            j.find("parent").get("link"), ", ".join(a.split()), j.find("child").get("link"), ", ".join(b.split())))
    coincident = ('\n    <rosparam param="coincident">[%s]</rosparam>' % ", ".join(pairs)) if pairs else ""
    with open(os.path.join(HERE, "example_%s.test" % name), "w") as out:
        out.write(f'''<!-- Written by generate_example_tests.py: {name} runs in the node within the bound. -->
<launch>
  <param name="robot_description" textfile="$(find mechanism_sim)/urdf/{name}.urdf"/>
  <node name="mechanism_sim" pkg="mechanism_sim" type="mechanism_sim_node" required="true">
    <rosparam command="load" file="$(find mechanism_sim)/config/default.yaml"/>
  </node>
  <test test-name="{name}_constraints" pkg="mechanism_sim" type="constraint_monitor" time-limit="60">
    <param name="duration" value="4.0"/>
    <param name="bound" type="double" value="1e-10"/>
    <param name="frame_tolerance" type="double" value="1e-8"/>{coincident}
  </test>
</launch>
''')
