#!/usr/bin/env python3
"""rostest (soak_driver.test): the SoakDriver nodelet publishes its scan into the manager, pairs
the voxel nodelet's outputs there (every pair conserves the points), stops while ~pause is true
and resumes after, and counts a pair whose two parts miss a point (the "fake" filter: this test
publishing /fake/ground and /fake/nonground)."""

import threading
import time
import unittest

import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Bool

PKG = "ground_filter"
WAIT_S = 120.0  # generous: never a timing assertion
STATUS = "soak_driver: outputs"


class SoakDriverTest(unittest.TestCase):
    def setUp(self):
        rospy.init_node("soak_driver_test", anonymous=True)
        self.cv = threading.Condition()
        self.counts = {}
        rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diag, queue_size=20)

    def on_diag(self, msg):
        for st in msg.status:
            if st.name == STATUS:
                with self.cv:
                    self.counts = {kv.key: kv.value for kv in st.values}
                    self.cv.notify_all()

    def wait_counts(self, cond, what):
        deadline = time.monotonic() + WAIT_S
        with self.cv:
            while not (self.counts and cond(self.counts)):
                left = deadline - time.monotonic()
                self.assertGreater(left, 0, "timed out waiting for %s; last counts %s"
                                   % (what, self.counts))
                self.cv.wait(min(left, 1.0))
            return dict(self.counts)

    def test_publishes_pairs_pauses_and_counts_a_short_pair(self):
        c = self.wait_counts(lambda c: int(c["drv_voxel pairs"]) >= 5, "five voxel pairs")
        points = int(c["points per cloud"])
        self.assertGreater(points, 1000)
        self.assertEqual(c["drv_voxel points not conserved"], "0", c)
        # Paused: the count stops (two reports apart), then goes on once resumed.
        pause = rospy.Publisher("/soak_driver/pause", Bool, queue_size=2, latch=True)
        pause.publish(Bool(True))
        time.sleep(2.5)
        before = int(self.wait_counts(lambda c: True, "a report")["published"])
        time.sleep(2.5)
        after = int(self.wait_counts(lambda c: True, "a report")["published"])
        self.assertEqual(before, after, "clouds published while paused")
        pause.publish(Bool(False))
        self.wait_counts(lambda c: int(c["published"]) >= after + 5, "clouds after the pause")
        # The fake filter: one pair that conserves the points, one that misses one.
        ground = rospy.Publisher("/fake/ground", PointCloud2, queue_size=10, latch=False)
        nonground = rospy.Publisher("/fake/nonground", PointCloud2, queue_size=10, latch=False)
        deadline = time.monotonic() + WAIT_S
        while (ground.get_num_connections() == 0 or nonground.get_num_connections() == 0) \
                and time.monotonic() < deadline:
            time.sleep(0.05)
        for i, missing in enumerate((0, 1)):
            g, ng = PointCloud2(), PointCloud2()
            for m in (g, ng):
                m.header.stamp = rospy.Time(100 + i)
                m.height = 1
            g.width = points // 3
            ng.width = points - g.width - missing
            ground.publish(g)
            nonground.publish(ng)
        c = self.wait_counts(lambda c: int(c["fake pairs"]) == 2, "the fake pairs")
        self.assertEqual(c["fake points not conserved"], "1", c)
        self.assertEqual(c["fake unpaired"], "0", c)
        self.assertEqual(c["drv_voxel points not conserved"], "0", c)


if __name__ == "__main__":
    rostest.rosrun(PKG, "soak_driver_check", SoakDriverTest)
