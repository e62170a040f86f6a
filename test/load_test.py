#!/usr/bin/env python3
"""rostest (load.test): a burst of 100 clouds, large clouds at 10 Hz, stamps jumping back. The
queue policy holds (clouds lost only by it, counted), every published pair keeps all points, the
nodelet recovers without a restart and the manager's memory returns after the large clouds."""
import os
import sys
import threading
import time
import xmlrpc.client

import numpy as np
import rosgraph
import rospkg
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import PointCloud2, PointField

PKG = "ground_filter"
NAME = "load_filter"
sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
from rostest_helpers import RosTestCase  # noqa: E402
from soak import header_and_size, rss_kb  # noqa: E402

FIELDS = ("x", "y", "z", "intensity")


def street(points, seed):
    """A flat street (80 %) with box-like objects 0.5-3 m tall (20 %), 100 m square."""
    rng = np.random.default_rng(seed)
    xyz = rng.uniform(-50.0, 50.0, size=(points, 4)).astype(np.float32)
    xyz[:, 2] = rng.normal(-1.7, 0.02, points)
    above = rng.random(points) < 0.2
    xyz[above, 2] += rng.uniform(0.5, 3.0, int(above.sum()))
    xyz[:, 3] = 1.0
    return xyz


def cloud(xyz, stamp, seq):
    msg = PointCloud2()
    msg.header.frame_id = "velodyne"
    msg.header.stamp = stamp
    msg.header.seq = seq
    msg.height, msg.width = 1, xyz.shape[0]
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(FIELDS)]
    msg.point_step, msg.row_step = 16, 16 * xyz.shape[0]
    msg.is_bigendian, msg.is_dense = False, True
    msg.data = xyz.tobytes()
    return msg


class LoadTest(RosTestCase):
    POLL_S = 0.05

    @classmethod
    def setUpClass(cls):
        rospy.init_node("load_test")
        cls.lock = threading.Lock()
        cls.values = {}
        cls.pairs = {}  # stamp ns -> [ground points, nonground points]
        rospy.Subscriber("/diagnostics", DiagnosticArray, cls._on_diag, queue_size=50)
        for i, part in enumerate(("ground", "nonground")):
            rospy.Subscriber("/%s/%s" % (NAME, part), rospy.AnyMsg, cls._on_out, i,
                             queue_size=200)
        cls.pub = rospy.Publisher("/gf_load/points", PointCloud2, queue_size=200)
        cls.small = street(20000, 1)
        cls.seq = 0
        cls.stamp_s = 2000.0

    @classmethod
    def _on_diag(cls, msg):
        with cls.lock:
            for st in msg.status:
                if st.name.split(":")[0] == NAME:
                    cls.values = {kv.key: kv.value for kv in st.values}

    @classmethod
    def _on_out(cls, msg, part):
        _, stamp_ns, points = header_and_size(msg._buff)
        with cls.lock:
            cls.pairs.setdefault(stamp_ns, [None, None])[part] = points

    def number(self, key):
        with self.lock:
            v = self.values.get(key)
        try:
            return int(float(v))
        except (TypeError, ValueError):
            return 0

    def send(self, xyz, stamp_step=0.1):
        LoadTest.seq += 1
        LoadTest.stamp_s += stamp_step
        stamp = rospy.Time.from_sec(LoadTest.stamp_s)
        self.pub.publish(cloud(xyz, stamp, LoadTest.seq))
        return stamp.to_nsec()

    def pair(self, stamp_ns):
        with self.lock:
            p = self.pairs.get(stamp_ns)
            return None if p is None or None in p else sum(p)

    def manager_rss_kb(self):
        uri = rosgraph.Master("/load_test").lookupNode("/gf_load_manager")
        return rss_kb(xmlrpc.client.ServerProxy(uri).getPid("/load_test")[2])

    def settle(self, stamp_ns, n):
        """Waits for the output pair of `stamp_ns` (n points) and 2 s more (trim, diagnostics)."""
        self.wait_for(lambda: self.pair(stamp_ns) is not None, "no output pair for a cloud")
        self.assertEqual(self.pair(stamp_ns), n)
        time.sleep(2.0)

    def test_stream_bad_moments(self):
        self.wait_for(lambda: self.pub.get_num_connections() > 0, "the nodelet never subscribed")
        self.wait_for(lambda: "clouds in" in self.values, "no diagnostics")
        for _ in range(5):  # warm: the filter's buffers sized for the usual clouds
            last = self.send(self.small)
            time.sleep(0.2)
        self.settle(last, len(self.small))

        # A burst of 100 clouds at once: the queue (3) keeps the newest; the rest are lost by
        # policy and counted from the seq gaps; the last one is always processed.
        in0, lost0 = self.number("clouds in"), self.number("lost before the filter (seq/stamp gaps)")
        burst = set()
        for _ in range(100):
            last = self.send(self.small, 0.001)
            burst.add(last)
        self.settle(last, len(self.small))
        got = self.number("clouds in") - in0
        lost = self.number("lost before the filter (seq/stamp gaps)") - lost0
        self.assertEqual(got + lost, 100, "in %d + lost %d" % (got, lost))
        self.assertEqual(self.number("dropped"), 0, "a cloud dropped for a reason, not by policy")

        # Large clouds on the live topic at 10 Hz, then the usual ones: the nodelet keeps going
        # and, once the large clouds stop, gives their buffers back.
        base_kb = self.manager_rss_kb()
        big = street(rospy.get_param("~big_points"), 2)
        releases0 = self.number("buffer releases (after a large cloud)")
        for _ in range(3):
            big_last = self.send(big)
            time.sleep(0.1)
        del big
        self.wait_for(lambda: self.pair(big_last) is not None, "no output for the large cloud",
                      timeout=120.0)
        self.assertEqual(self.pair(big_last), rospy.get_param("~big_points"))
        for _ in range(15):
            last = self.send(self.small)
            time.sleep(0.1)
        self.settle(last, len(self.small))
        self.wait_for(lambda: self.number("buffer releases (after a large cloud)") > releases0,
                      "the filter's buffers were never released after the large clouds")
        time.sleep(1.5)  # a malloc_trim period and more
        grown_mb = (self.manager_rss_kb() - base_kb) / 1024.0
        print("manager RSS %d KB before the large clouds, %+.1f MB after" % (base_kb, grown_mb))
        # Measured: +0.1 MB with the release, +33 MB without it (3 M points, voxel).
        self.assertLess(grown_mb, 12.0, "manager RSS %+.0f MB after the large clouds" % grown_mb)

        # Stamps jump back 1000 s (a bag looping, a clock reset): still processed, nothing
        # counted as lost or dropped for it.
        lost0 = self.number("lost before the filter (seq/stamp gaps)")
        last = self.send(self.small, -1000.0)
        self.settle(last, len(self.small))
        for _ in range(3):
            last = self.send(self.small)
            time.sleep(0.2)
        self.settle(last, len(self.small))
        self.assertEqual(self.number("lost before the filter (seq/stamp gaps)"), lost0)
        self.assertEqual(self.number("dropped"), 0)
        # Both outputs of every cloud reach this subscriber, except where the outputs' latest-only
        # publisher queue (1) replaced an output that this Python subscriber was still reading:
        # a large cloud's (tens of MB), or one of the burst's, whose outputs follow each other
        # within a millisecond (seen once in a CI run on 2 cores). Outside those, none may miss.
        with self.lock:
            broken = {s: p for s, p in self.pairs.items() if None in p}
        small = {s: p for s, p in broken.items()
                 if s not in burst and max(n or 0 for n in p) <= len(self.small)}
        self.assertEqual(small, {}, "outputs without their partner (stamp ns: [ground, nonground])")
        large = {s: p for s, p in broken.items() if max(n or 0 for n in p) > len(self.small)}
        self.assertLessEqual(len(large), 3, "large clouds' outputs without their partner: %s"
                             % large)
        # Every pair that did arrive whole holds all the points of its cloud.
        with self.lock:
            sizes = {sum(p) for p in self.pairs.values() if None not in p}
        self.assertLessEqual(sizes, {len(self.small), rospy.get_param("~big_points")})


if __name__ == "__main__":
    rostest.rosrun(PKG, "load", LoadTest)
