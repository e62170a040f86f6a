#!/usr/bin/env python3
"""rostest: switching knn_backend (kdtree <-> gpu) of the normal-vector nodelet through
dynamic_reconfigure while clouds stream loses no message and does not crash the nodelet.

A real KITTI frame (x y z intensity, float32) is published at 10 Hz with a unique stamp per
message while the backend is switched kdtree -> gpu -> kdtree -> gpu -> kdtree. Every published
cloud must come out as a ground/non-ground pair whose sizes add up to the input. Without CUDA or a
usable GPU, "gpu" falls back to the kd-tree: one WARN per switch to gpu (never one per cloud).

Private parameters: ~data_file (KITTI .bin), ~filter_name (e.g. /normal_filter), ~input_topic.
"""

import sys
import threading
import time
import unittest

import numpy as np
import rospy
import rostest
from dynamic_reconfigure.client import Client as ReconfigureClient
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import PointCloud2, PointField

PKG = "ground_filter"
WAIT_S = 120.0  # generous: the test machine may be slow; never a timing assertion
SEQUENCE = ["gpu", "kdtree", "gpu", "kdtree"]  # after the initial kdtree


def kitti_cloud(xyzi, stamp):
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = "velodyne"
    msg.height = 1
    msg.width = xyzi.shape[0]
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(["x", "y", "z", "intensity"])]
    msg.is_bigendian = False
    msg.point_step = 16
    msg.row_step = 16 * msg.width
    msg.data = xyzi.astype("<f4").tobytes()
    msg.is_dense = True
    return msg


class KnnBackendSwitchTest(unittest.TestCase):
    def test_switch_backend_while_streaming(self):
        rospy.init_node("knn_backend_switch_test", anonymous=True)
        name = rospy.get_param("~filter_name")
        xyzi = np.fromfile(rospy.get_param("~data_file"), dtype=np.float32).reshape(-1, 4)
        n_points = xyzi.shape[0]

        lock = threading.Condition()
        ground, nonground = {}, {}
        rosout = []

        def on_output(msg, which):
            with lock:
                which[msg.header.stamp.to_nsec()] = msg.width * msg.height
                lock.notify_all()

        def on_rosout(msg):
            with lock:
                rosout.append(msg)

        big = 1 << 26
        subs = [rospy.Subscriber(name + "/ground", PointCloud2, on_output, ground,
                                 queue_size=1000, buff_size=big),
                rospy.Subscriber(name + "/nonground", PointCloud2, on_output, nonground,
                                 queue_size=1000, buff_size=big),
                rospy.Subscriber("/rosout_agg", Log, on_rosout, queue_size=1000)]
        pub = rospy.Publisher(rospy.get_param("~input_topic"), PointCloud2, queue_size=200)
        deadline = time.monotonic() + WAIT_S
        while pub.get_num_connections() < 1 and time.monotonic() < deadline:
            time.sleep(0.1)  # lazy nodelet: subscribes to its input once outputs are watched
        self.assertGreaterEqual(pub.get_num_connections(), 1, "nodelet never subscribed")

        client = ReconfigureClient(name, timeout=WAIT_S)
        self.assertEqual(client.get_configuration(timeout=WAIT_S)["knn_backend"], "kdtree")

        stamps = []
        stop = threading.Event()

        def stream():
            rate = rospy.Rate(10)
            base = rospy.Time.now()
            while not stop.is_set() and not rospy.is_shutdown():
                s = base + rospy.Duration(0, 1000000 * (len(stamps) + 1))  # unique stamps
                stamps.append(s)
                pub.publish(kitti_cloud(xyzi, s))
                rate.sleep()

        streamer = threading.Thread(target=stream)
        streamer.start()
        try:
            for backend in SEQUENCE:
                time.sleep(0.7)
                got = client.update_configuration({"knn_backend": backend})
                self.assertEqual(got["knn_backend"], backend)
            time.sleep(0.7)
        finally:
            stop.set()
            streamer.join()

        keys = [s.to_nsec() for s in stamps]
        deadline = time.monotonic() + WAIT_S
        with lock:
            while not all(k in ground and k in nonground for k in keys):
                if time.monotonic() > deadline or rospy.is_shutdown():
                    break
                lock.wait(0.5)
            missing = [k for k in keys if k not in ground or k not in nonground]
            sizes_ok = all(ground[k] + nonground[k] == n_points
                           for k in keys if k in ground and k in nonground)
        self.assertEqual(missing, [], "%d of %d clouds streamed while switching got no output "
                         "pair" % (len(missing), len(keys)))
        self.assertTrue(sizes_ok, "ground + non-ground != input points for some cloud")
        self.assertGreaterEqual(len(keys), 20)
        rospy.loginfo("knn_backend switched %d times, %d clouds streamed, all split",
                      len(SEQUENCE), len(keys))

        # The nodelet is still alive and back on the kd-tree.
        self.assertEqual(client.get_configuration(timeout=WAIT_S)["knn_backend"], "kdtree")

        # A GPU request that falls back says so once per switch, not once per cloud.
        time.sleep(1.0)
        with lock:
            warns = [m for m in rosout
                     if m.level == Log.WARN and "knn_backend 'gpu'" in m.msg]
        self.assertLessEqual(len(warns), SEQUENCE.count("gpu"), [m.msg for m in warns])
        for s in subs:
            s.unregister()


if __name__ == "__main__":
    rostest.rosrun(PKG, "knn_backend_switch_test", KnnBackendSwitchTest, sys.argv)
