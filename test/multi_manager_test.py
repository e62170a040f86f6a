#!/usr/bin/env python3
"""rostest: ground filter nodelets in two nodelet managers, one under a namespace.

For each filter in ~filters ([node, manager, input topic, parameter, expected value]):
the node's outputs exist at NODE/ground and NODE/nonground, its input subscription belongs to
its manager and to no other, its parameter has the value set for it (namespaced parameters do
not leak between managers), and a real KITTI frame published on its input comes out split with
the point count conserved. All filters are fed at the same time (one frame per input topic;
filters sharing an input topic in one manager each get it).
"""
import os
import sys
import threading

import rosgraph
import rospkg
import rospy
import rostest
from dynamic_reconfigure.client import Client as ReconfigureClient
from sensor_msgs.msg import PointCloud2

PKG = "ground_filter"
WAIT_S = 60.0

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
import make_bag  # noqa: E402
from rostest_helpers import RosTestCase  # noqa: E402


class MultiManagerTest(RosTestCase):

    @classmethod
    def setUpClass(cls):
        rospy.init_node("multi_manager_test")
        cls.filters = [tuple(f) for f in rospy.get_param("~filters")]
        cls.scan = make_bag.read_scan(rospy.get_param("~data_file"))
        cls.master = rosgraph.Master("/multi_manager_test")

    def system_state(self):
        pubs, subs, _ = self.master.getSystemState()
        return dict(pubs), dict(subs)

    def test_filters_in_two_managers(self):
        self.assertGreaterEqual(len(self.filters), 2)
        managers = {f[1] for f in self.filters}
        self.assertGreaterEqual(len(managers), 2, "filters should span two managers")
        self.assertTrue(any(f[1].count("/") > 1 for f in self.filters),
                        "one manager should live under a namespace")

        # Outputs advertised by the right manager process.
        for node, manager, _, _, _ in self.filters:
            for out in ("ground", "nonground"):
                topic = "%s/%s" % (node, out)
                self.wait_for(lambda t=topic, m=manager: m in self.system_state()[0].get(t, []),
                              "%s not advertised by %s" % (topic, manager))

        # Namespaced parameters reached their own nodelet only.
        for node, _, _, pname, value in self.filters:
            cfg = ReconfigureClient(node, timeout=WAIT_S).get_configuration(timeout=WAIT_S)
            self.assertAlmostEqual(cfg[pname], value, msg="%s %s" % (node, pname))

        # Subscribing to the outputs starts each lazy filter's input subscription, in its manager.
        lock = threading.Lock()
        got = {}

        def on_cloud(msg, key):
            with lock:
                got[key] = msg

        subs = [rospy.Subscriber("%s/%s" % (node, out), PointCloud2, on_cloud,
                                 callback_args=(node, out), queue_size=5)
                for node, _, _, _, _ in self.filters for out in ("ground", "nonground")]
        inputs = sorted({f[2] for f in self.filters})
        for node, manager, topic, _, _ in self.filters:
            self.wait_for(lambda t=topic, m=manager: m in self.system_state()[1].get(t, []),
                          "%s (in %s) never subscribed to %s" % (node, manager, topic))
        for topic in inputs:
            readers = {f[1] for f in self.filters if f[2] == topic}
            self.assertEqual(set(self.system_state()[1].get(topic, [])) - {"/rosout"}, readers,
                             "unexpected subscribers of " + topic)

        pubs = {t: rospy.Publisher(t, PointCloud2, queue_size=2) for t in inputs}
        for t, p in pubs.items():
            readers = {f[1] for f in self.filters if f[2] == t}
            self.wait_for(lambda p=p, n=len(readers): p.get_num_connections() >= n,
                          "publisher on %s not connected" % t)
        stamp = rospy.Time(42, 0)
        cloud = make_bag.to_message(self.scan, "velodyne", stamp, 0)
        for p in pubs.values():
            p.publish(cloud)
        want = {(node, out) for node, _, _, _, _ in self.filters for out in ("ground",
                                                                           "nonground")}
        self.wait_for(lambda: want <= set(got), "outputs missing: %s" % sorted(want - set(got)))
        for s in subs:
            s.unregister()

        n_in = cloud.width * cloud.height
        for node, _, _, pname, value in self.filters:
            g, ng = got[(node, "ground")], got[(node, "nonground")]
            for out in (g, ng):
                self.assertEqual(out.header.stamp, stamp)
                self.assertEqual(out.header.frame_id, "velodyne")
            self.assertEqual(g.width + ng.width, n_in, node + ": count not conserved")
            self.assertGreater(g.width, 0, node)
            self.assertGreater(ng.width, 0, node)
            rospy.loginfo("%s (%s=%g): %d in, %d ground, %d non-ground", node, pname, value,
                          n_in, g.width, ng.width)


if __name__ == "__main__":
    rostest.rosrun(PKG, "multi_manager", MultiManagerTest, sys.argv)
