#!/usr/bin/env python3
"""rostest: a bag made by scripts/make_bag.py from real KITTI frames, played by
launch/play_bag.launch (simulated time) through each ground filter method.

For every method in ~methods: writes the bag (seq00 frames 0-5) once, starts
`roslaunch ground_filter play_bag.launch method:=M pause:=true` against this test's master,
subscribes to both outputs (which starts the lazy filter), resumes playback through the player's
~pause_playback service and asserts that every bag message came out as a ground/non-ground pair
with the bag's stamp and frame, the input's fields, and exactly the input's point records.
"""
import os
import sys
import tempfile
import threading
import time

import numpy as np
import rosgraph
import rospkg
import rospy
import rostest
from sensor_msgs.msg import PointCloud2
from std_srvs.srv import SetBool

PKG = "ground_filter"
WAIT_S = 60.0

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
import make_bag  # noqa: E402
from ros_launch_helpers import Process, loopback_env  # noqa: E402
from rostest_helpers import RosTestCase  # noqa: E402


def records(msg):
    """Point records of a height-1 or unpadded cloud as rows of bytes."""
    n = msg.width * msg.height
    return np.frombuffer(msg.data, dtype=np.uint8)[:n * msg.point_step].reshape(n, msg.point_step)


def sorted_records(rows):
    """Rows sorted as opaque byte strings (a multiset comparison of point records)."""
    return np.sort(np.ascontiguousarray(rows).view("V%d" % rows.shape[1]).ravel())


class Pairs(object):
    """Collects ~ground and ~nonground of one filter, keyed by header stamp."""

    def __init__(self, name):
        self.lock = threading.Lock()
        self.got = {}
        self.subs = [rospy.Subscriber("%s/%s" % (name, which), PointCloud2,
                                      self._cb, callback_args=which, queue_size=50)
                     for which in ("ground", "nonground")]

    def _cb(self, msg, which):
        with self.lock:
            self.got.setdefault(msg.header.stamp.to_nsec(), {})[which] = msg

    def complete(self, stamps):
        with self.lock:
            return all(len(self.got.get(s, {})) == 2 for s in stamps)

    def close(self):
        for s in self.subs:
            s.unregister()


class BagPlaybackTest(RosTestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("bag_playback_test")
        data_dir = rospy.get_param("~data_dir")
        cls.methods = rospy.get_param("~methods")
        cls.rate = float(rospy.get_param("~rate", 2.0))
        cls.topic = "/points_raw"
        cls.frame_id = "velodyne"
        seq = os.path.join(data_dir, "semantickitti", "seq00")
        files = make_bag.expand_inputs([seq])
        cls.files = [f for f in files if f.endswith(".bin")][:6]
        cls.tmp = tempfile.mkdtemp(prefix="gf_bag_test_")
        cls.bag = os.path.join(cls.tmp, "seq00_0-5.bag")
        t0 = time.monotonic()
        n = make_bag.write_bag(cls.files, cls.bag, cls.topic, cls.frame_id, rate=10.0, start=1.0,
                               log=lambda s: rospy.loginfo("make_bag: %s", s))
        rospy.loginfo("bag %s: %d messages in %.1f s", cls.bag, n, time.monotonic() - t0)
        # What the bag holds, read back through the rosbag API (not from make_bag's memory).
        import rosbag
        cls.inputs = {}
        with rosbag.Bag(cls.bag) as bag:
            for _, msg, _ in bag.read_messages(topics=[cls.topic]):
                cls.inputs[msg.header.stamp.to_nsec()] = msg

    @classmethod
    def tearDownClass(cls):
        try:
            os.remove(cls.bag)
            os.rmdir(cls.tmp)
        except OSError:
            pass

    def input_subscribed(self, node):
        """True when node `node` subscribes to the bag topic (master state)."""
        master = rosgraph.Master("/bag_playback_test")
        _, subs, _ = master.getSystemState()
        return any(t == self.topic and node in nodes for t, nodes in subs)

    def test_bag_has_six_real_frames(self):
        self.assertEqual(len(self.files), 6, "seq00 should hold frames 000000..000005")
        self.assertEqual(len(self.inputs), 6)
        stamps = sorted(self.inputs)
        self.assertTrue(all(b > a for a, b in zip(stamps, stamps[1:])), "stamps not increasing")
        for msg in self.inputs.values():
            self.assertGreater(msg.width, 100000)
            self.assertEqual([f.name for f in msg.fields], ["x", "y", "z", "intensity"])
            self.assertEqual(msg.header.frame_id, self.frame_id)

    def test_play_through_each_method(self):
        self.assertTrue(self.methods, "~methods is empty")
        for method in self.methods:
            self.play_through(method)

    def play_through(self, method):
        name = "%s_filter" % method
        manager = "%s_manager" % method
        cmd = ["roslaunch", PKG, "play_bag.launch", "bag:=" + self.bag, "method:=" + method,
               "name:=" + name, "manager:=" + manager, "topic:=" + self.topic,
               "pause:=true", "rate:=%g" % self.rate, "delay:=0.5"]
        rospy.loginfo("starting: %s", " ".join(cmd))
        # This test's master (rostest's); loopback when the hostname does not resolve.
        launch = Process(cmd, env=loopback_env(), text=False)
        pairs = Pairs("/" + name)
        try:
            # Our output subscription starts the lazy filter's input subscription (a nodelet's
            # subscriptions belong to its manager's node).
            self.wait_for(lambda: self.input_subscribed("/" + manager),
                          "%s (in %s) never subscribed to %s" % (name, manager, self.topic))
            service = "/%s_player/pause_playback" % name
            rospy.wait_for_service(service, timeout=WAIT_S)
            resume = rospy.ServiceProxy(service, SetBool)
            self.assertTrue(resume(False).success)
            t0 = time.monotonic()
            stamps = sorted(self.inputs)
            self.wait_for(lambda: pairs.complete(stamps),
                          "%s: not every bag message came out as a ground/non-ground pair "
                          "(got %d of %d)" % (method, len(pairs.got), len(stamps)))
            rospy.loginfo("%s: %d pairs in %.1f s of playback at rate %g", method,
                          len(stamps), time.monotonic() - t0, self.rate)
            for stamp in stamps:
                self.check_pair(method, self.inputs[stamp], pairs.got[stamp])
        finally:
            pairs.close()
            launch.stop()
            text = launch.output()
            if "ERROR" in text or "Traceback" in text:
                rospy.logwarn("roslaunch output of %s:\n%s", method, text)

    def check_pair(self, method, cloud, pair):
        ground, nonground = pair["ground"], pair["nonground"]
        n_in = cloud.width * cloud.height
        for out in (ground, nonground):
            self.assertEqual(out.header.stamp, cloud.header.stamp)
            self.assertEqual(out.header.frame_id, cloud.header.frame_id)
            self.assertEqual([(f.name, f.offset, f.datatype, f.count) for f in out.fields],
                             [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields])
            self.assertEqual(out.point_step, cloud.point_step)
        self.assertEqual(ground.width + nonground.width, n_in,
                         "%s: point count not conserved" % method)
        # Split for real: a KITTI street frame has plenty of both.
        self.assertGreater(ground.width, n_in // 5, "%s: almost no ground" % method)
        self.assertGreater(nonground.width, n_in // 5, "%s: almost no non-ground" % method)
        out_rows = np.vstack([records(ground), records(nonground)])
        np.testing.assert_array_equal(sorted_records(out_rows), sorted_records(records(cloud)),
                                      "%s: output records are not the input records" % method)
        rospy.loginfo("%s stamp %.1f: %d in, %d ground, %d non-ground", method,
                      cloud.header.stamp.to_sec(), n_in, ground.width, nonground.width)


if __name__ == "__main__":
    rostest.rosrun(PKG, "bag_playback", BagPlaybackTest, sys.argv)
