"""What the node's rostests share: a publisher to one of the node's command topics, returned
once the node has subscribed to it (a message published before that would be lost), and the
node's ~advance service (the paused node's steps)."""
import time

import rospy

from mechanism_sim.srv import StepSimulation


def connected_publisher(topic, msg_type, timeout=10.0):
    pub = rospy.Publisher(topic, msg_type, queue_size=10)
    deadline = time.time() + timeout
    while pub.get_num_connections() == 0 and time.time() < deadline:
        time.sleep(0.05)
    return pub


def advance_service(timeout=10.0):
    rospy.wait_for_service("/mechanism_sim/advance", timeout)
    return rospy.ServiceProxy("/mechanism_sim/advance", StepSimulation)
