#!/usr/bin/env python3
"""rostest: tf2 gravity frame, ~labeled output, diagnostics and bad streams of the filter nodelets
(see ros_extras.test for the nodelets under test)."""
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import rosbag
import rosgraph
import rospkg
import rospy
import rostest
import tf2_ros
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import String

PKG = "ground_filter"
WAIT_S = 60.0
TILT_DEG = 20.0

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
from rostest_helpers import Outputs, RosTestCase  # noqa: E402

REC = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("idx", "<u4")])
LABELED = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"),
                    ("idx", "<u4"), ("ground", "u1"), ("pad", "V3"),
                    ("height_above_ground", "<f4")])


def make_cloud(rec, frame_id, stamp):
    msg = PointCloud2()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    msg.height, msg.width = 1, rec.shape[0]
    msg.fields = [PointField(name=n, offset=REC.fields[n][1],
                             datatype=PointField.UINT32 if n == "idx" else PointField.FLOAT32,
                             count=1) for n in REC.names]
    msg.is_bigendian = False
    msg.point_step = REC.itemsize
    msg.row_step = REC.itemsize * rec.shape[0]
    msg.data = rec.tobytes()
    msg.is_dense = True
    return msg


def rot_y(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


class RosExtrasTest(RosTestCase):
    POLL_S = 0.05
    STAMP_BASE_S, STAMP_STEP_NS = 500, 0

    @classmethod
    def setUpClass(cls):
        rospy.init_node("ros_extras_test")
        raw = np.fromfile(rospy.get_param("~data_file"), dtype="<f4").reshape(-1, 4)
        cls.rec = np.zeros(raw.shape[0], dtype=REC)
        for i, n in enumerate(("x", "y", "z", "intensity")):
            cls.rec[n] = raw[:, i]
        cls.rec["idx"] = np.arange(raw.shape[0], dtype=np.uint32)
        # The tilted sensor sees p_t = R^T p; base_link <- velodyne_tilted is R.
        r = rot_y(TILT_DEG)
        xyz = np.stack([cls.rec["x"], cls.rec["y"], cls.rec["z"]], axis=1).astype(np.float64)
        tilted = xyz @ r  # row vectors: (R^T p)^T = p^T R
        cls.tilted = cls.rec.copy()
        for i, n in enumerate(("x", "y", "z")):
            cls.tilted[n] = tilted[:, i].astype(np.float32)

        # base_link <- velodyne_tilted comes from scripts/static_tf.py (ros_extras.test), the
        # route for Debian, whose packages lack tf2_ros' static_transform_publisher.
        cls.tf_buffer = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)

        cls.lock = threading.Lock()
        cls.diag = {}
        rospy.Subscriber("/diagnostics", DiagnosticArray, cls._on_diag, queue_size=50)
        # /rosout itself: rostest starts no rosout node, so nothing is aggregated.
        cls.collect_rosout(("/rosout",))
        cls.pubs = {n: rospy.Publisher("/gf_extras/" + n, PointCloud2, queue_size=20)
                    for n in ("flat", "tilted", "notf", "body", "bad")}
        cls.pubs["lost"] = rospy.Publisher("/gf_extras/lost", PointCloud2, queue_size=100)

    @classmethod
    def _on_diag(cls, msg):
        with cls.lock:
            for st in msg.status:
                cls.diag[st.name.split(":")[0]] = st

    def status(self, name):
        with self.lock:
            return self.diag.get(name)

    def value(self, name, key):
        st = self.status(name)
        if st is None:
            return None
        for kv in st.values:
            if kv.key == key:
                return kv.value
        return None

    def number(self, name, key):
        v = self.value(name, key)
        try:
            return float(v)
        except (TypeError, ValueError):
            return None

    def input_subscribed(self, topic):
        _, subs, _ = rosgraph.Master("/ros_extras_test").getSystemState()
        return any(t == topic and "/gf_extras_manager" in nodes for t, nodes in subs)

    def connect(self, pub, n=1):
        self.wait_for(lambda: pub.get_num_connections() >= n,
                      "no subscriber on " + pub.resolved_name)

    # ----------------------------------------------------------------------------------- tests

    def test_0_labeled_alone_starts_lazy_filter(self):
        """~labeled is one of the lazy outputs: a subscriber to it alone starts the input."""
        time.sleep(1.0)
        self.assertFalse(self.input_subscribed("/gf_extras/flat"),
                         "flat_filter subscribed its input with no output subscriber")
        sub = rospy.Subscriber("/flat_filter/labeled", PointCloud2, lambda m: None)
        self.wait_for(lambda: self.input_subscribed("/gf_extras/flat"),
                      "a ~labeled subscriber did not start the input subscription")
        sub.unregister()
        self.wait_for(lambda: not self.input_subscribed("/gf_extras/flat"),
                      "input kept after the last ~labeled subscriber left")

    def test_gravity_frame_tilted_kitti(self):
        """A 20-degree tilted sensor with its static transform gives the labels of the
        untilted frame (>= 99 %); outputs stay in the tilted frame with the input records.
        The transform comes from `rosrun ground_filter static_tf.py` (yaw pitch roll order of
        static_transform_publisher): it must be the 20-degree rotation about y, 1.73 m up."""
        t = self.tf_buffer.lookup_transform("base_link", "velodyne_tilted", rospy.Time(0),
                                            rospy.Duration(20.0)).transform
        half = math.radians(TILT_DEG) / 2
        got = [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w,
               t.translation.x, t.translation.y, t.translation.z]
        np.testing.assert_allclose(got, [0, math.sin(half), 0, math.cos(half), 0, 0, 1.73],
                                   atol=1e-9, err_msg="static_tf.py published another transform")
        # Bad arguments: a message naming the argument, exit status 2, nothing published.
        bad = subprocess.run(["rosrun", PKG, "static_tf.py", "0", "0", "x", "0", "0", "0",
                              "base_link", "other"], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, universal_newlines=True, timeout=60)
        self.assertEqual(bad.returncode, 2, bad.stdout)
        self.assertIn("Z = 'x' is not a number", bad.stdout)
        topics = ["/flat_filter/labeled", "/tilted_filter/labeled", "/tilted_filter/ground",
                  "/tilted_filter/nonground", "/yaml_filter/labeled"]
        out = Outputs(topics)
        try:
            self.connect(self.pubs["flat"])
            self.connect(self.pubs["tilted"])
            # tilted_filter and yaml_filter share the manager's one connection: yaml_filter may
            # subscribe a moment later, so a cloud it missed is sent again with a new stamp.
            for attempt in range(3):
                stamp = self.next_stamp()
                self.pubs["flat"].publish(make_cloud(self.rec, "velodyne", stamp))
                self.pubs["tilted"].publish(make_cloud(self.tilted, "velodyne_tilted", stamp))
                try:
                    self.wait_for(lambda: all(out.get(t, stamp) for t in topics),
                                  "outputs of " + str(topics), timeout=20.0 if attempt < 2 else
                                  WAIT_S)
                    break
                except AssertionError:
                    if attempt == 2:
                        raise
            flat = np.frombuffer(out.get(topics[0], stamp).data, dtype=LABELED)
            tilt_msg = out.get(topics[1], stamp)
            tilt = np.frombuffer(tilt_msg.data, dtype=LABELED)
            n = self.rec.shape[0]
            self.assertEqual(flat.shape[0], n)
            self.assertEqual(tilt.shape[0], n)
            a = np.zeros(n, np.uint8)
            b = np.zeros(n, np.uint8)
            a[flat["idx"]] = flat["ground"]
            b[tilt["idx"]] = tilt["ground"]
            agreement = float(np.mean(a == b))

            # Outputs keep the tilted frame, the stamp and the (untransformed) input records.
            self.assertEqual(tilt_msg.header.frame_id, "velodyne_tilted")
            for name in ("x", "y", "z", "intensity", "idx"):
                np.testing.assert_array_equal(tilt[name], self.tilted[name])
            g = out.get(topics[2], stamp)
            ng = out.get(topics[3], stamp)
            for m in (g, ng):
                self.assertEqual(m.header.frame_id, "velodyne_tilted")
                self.assertEqual(m.header.stamp, stamp)
            self.assertEqual(g.width + ng.width, n)
            self.assertEqual(g.width, int(b.sum()), "~labeled disagrees with ~ground")
            gi = np.frombuffer(g.data, dtype=REC)["idx"]
            self.assertTrue(np.all(b[gi] == 1))

            # Control: the tilted frame classified without the gravity frame (and without the
            # method's own levelling: level_tilt 0 in ros_extras.test).
            stamp2 = self.next_stamp()
            self.pubs["flat"].publish(make_cloud(self.tilted, "velodyne_tilted", stamp2))
            self.wait_for(lambda: out.get(topics[0], stamp2), "control output")
            ctl = np.frombuffer(out.get(topics[0], stamp2).data, dtype=LABELED)
            c = np.zeros(n, np.uint8)
            c[ctl["idx"]] = ctl["ground"]
            control = float(np.mean(a == c))
            rospy.loginfo("gravity frame: %d points, ground %d (untilted) / %d (tilted, "
                          "base_link): agreement %.3f %%; tilted without gravity_frame: %.3f %%",
                          n, int(a.sum()), int(b.sum()), 100 * agreement, 100 * control)
            self.assertGreaterEqual(agreement, 0.99)
            # gravity_frame from a YAML (params_file) classifies like the <param> one, and
            # unlike the tilted frame classified as it comes.
            y = np.zeros(n, np.uint8)
            yl = np.frombuffer(out.get(topics[4], stamp).data, dtype=LABELED)
            y[yl["idx"]] = yl["ground"]
            self.assertTrue(np.array_equal(y, b), "YAML gravity_frame: %d labels differ from "
                            "the <param> one" % int(np.sum(y != b)))
            self.assertLess(float(np.mean(y == c)), 0.99, "the YAML gravity_frame changed "
                            "nothing: is it read at all?")
        finally:
            out.close()

    def test_body_returns_min_range_body_box_from_yaml(self):
        """min_range and body_box from a YAML: the points they hold are non-ground and counted
        (diagnostics "near points"); the rest is split as usual."""
        out = Outputs(["/body_filter/labeled"])
        try:
            self.connect(self.pubs["body"])
            stamp = self.next_stamp()
            self.pubs["body"].publish(make_cloud(self.rec, "velodyne", stamp))
            self.wait_for(lambda: out.get("/body_filter/labeled", stamp), "body_filter output")
            lab = np.frombuffer(out.get("/body_filter/labeled", stamp).data, dtype=LABELED)
            x, y, z = (lab[k].astype(np.float64) for k in ("x", "y", "z"))
            near = (x * x + y * y + z * z < 25.0) | ((x >= -10) & (x <= -6) & (y >= -3) &
                                                      (y <= 3) & (z >= -3) & (z <= 1))
            self.assertGreater(int(near.sum()), 1000, "the box should hold road points")
            self.assertEqual(int(lab["ground"][near].sum()), 0, "near points labelled ground")
            self.assertGreater(int(lab["ground"][~near].sum()), lab.shape[0] // 4)
            self.wait_for(lambda: self.number("body_filter", "near points (min_range, body_box)")
                          == int(near.sum()), "diagnostics: near points %d" % int(near.sum()),
                          timeout=10.0)
            self.assertEqual(rospy.get_param("/body_filter/min_range"), 5.0)
        finally:
            out.close()

    def test_bad_yaml_refused_naming_each_key(self):
        """A YAML with an unknown key, wrong types, a value out of range, a body box with
        min > max and min_range above max_range: one short ERROR line per key, the defaults
        stay, the filter still splits clouds. A key an earlier launch of this name left on the
        parameter server (e.g. the other method's) is cleared by the launch file, not seen."""
        rospy.set_param("/bad_filter/earlier_launch_key", 4)
        launch = subprocess.Popen(
            ["roslaunch", PKG, "%s_ground_filter.launch" % rospy.get_param("~method"),
             "manager:=gf_extras_manager", "name:=bad_filter", "input:=/gf_extras/bad",
             "params_file:=" + os.path.join(rospkg.RosPack().get_path(PKG), "test",
                                            "ros_extras_bad.yaml")],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            self._check_bad_filter()
        finally:
            launch.send_signal(signal.SIGINT)
            launch.wait(timeout=30)

    def _check_bad_filter(self):
        for text in ("~plane_distanse: unknown parameter", "~threads: 'two' is not an integer",
                     "~plane_distance: 50 is outside [0.001, 10]",
                     "~tf_timeout: 'fast' is not a number",
                     "~queue_size: 0 is outside [1, 1000]",
                     "~body_box: body_box xmin = 1.000000 m is above xmax",
                     "min_range = 20.000000 m is not below max_range"):
            self.wait_for(lambda t=text: self.logged(Log.ERROR, t), "no ERROR: " + text,
                          timeout=30.0)
        # An unknown key far from every name: one short line, not the list of every name.
        self.wait_for(lambda: self.logged(Log.ERROR, "~sensor_colour: unknown parameter"),
                      "no ERROR for sensor_colour", timeout=30.0)
        with self.rosout_lock:
            # The start-up check's lines ("METHOD: parameter ~KEY: why; refused, ...").
            lines = [m.msg for m in self.rosout
                     if m.level >= Log.ERROR and ": parameter ~" in m.msg]
        self.assertGreaterEqual(len(lines), 6)
        for line in lines:
            self.assertLess(len(line), 200, "ERROR line of %d characters: %s" % (len(line), line))
        # clear_params: the key of an earlier launch never reached the nodelet.
        self.assertFalse(self.logged(Log.ERROR, "earlier_launch_key"),
                         "the launch kept a key of an earlier launch (no clear_params)")
        self.assertFalse(rospy.has_param("/bad_filter/earlier_launch_key"))
        # The refused set left the defaults in use (reported back to the parameter server).
        self.assertFalse(rospy.has_param("/bad_filter/plane_distanse"))
        self.assertFalse(rospy.has_param("/bad_filter/tf_timeout"))
        self.assertFalse(rospy.has_param("/bad_filter/queue_size"))
        self.assertFalse(rospy.has_param("/bad_filter/body_box"))
        self.wait_for(lambda: rospy.get_param("/bad_filter/min_range", None) == 0.0,
                      "min_range not back at its default", timeout=10.0)
        self.assertAlmostEqual(rospy.get_param("/bad_filter/plane_distance"), 0.15)
        # A set refused at run time through dynparam: it exits 0 and prints nothing (it drops
        # the server's reply), but the reply, the parameter server and `dynparam get` hold the
        # kept value, and the diagnostics name the reason.
        dyn = ["rosrun", "dynamic_reconfigure", "dynparam"]
        run = subprocess.run(dyn + ["set", "/bad_filter", "min_range", "5000"],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             universal_newlines=True, timeout=60)
        self.assertEqual(run.returncode, 0, run.stdout)
        got = subprocess.run(dyn + ["get", "/bad_filter"], stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, universal_newlines=True, timeout=60)
        self.assertIn("'min_range': 0.0", got.stdout)
        self.assertEqual(rospy.get_param("/bad_filter/min_range"), 0.0)
        self.wait_for(lambda: "min_range = 5000" in (self.value("bad_filter",
                                                                "last refused parameter set")
                                                     or ""),
                      "diagnostics do not name the refused set", timeout=10.0)
        self.assertEqual(rospy.get_param("/bad_filter/max_range"), 1000.0)
        out = Outputs(["/bad_filter/ground", "/bad_filter/nonground"])
        try:
            self.connect(self.pubs["bad"])
            stamp = self.next_stamp()
            self.pubs["bad"].publish(make_cloud(self.rec[:20000], "velodyne", stamp))
            self.wait_for(lambda: out.get("/bad_filter/ground", stamp) and
                          out.get("/bad_filter/nonground", stamp), "bad_filter output")
            self.assertEqual(out.get("/bad_filter/ground", stamp).width +
                             out.get("/bad_filter/nonground", stamp).width, 20000)
        finally:
            out.close()

    def test_lost_clouds_counted(self):
        """A burst faster than the filter into ~queue_size 1: roscpp drops queued clouds without
        a word; the seq gaps (rospy numbers every message) count them: clouds in + lost = clouds
        sent, a WARN names them, the diagnostics turn WARN."""
        name, key = "lost_filter", "lost before the filter (seq/stamp gaps)"
        pub = self.pubs["lost"]
        statuses = []
        sub = rospy.Subscriber("/diagnostics", DiagnosticArray, lambda m: statuses.extend(
            st for st in m.status if st.name.startswith(name + ":")), queue_size=50)
        out = Outputs(["/%s/ground" % name])
        try:
            self.connect(pub)
            self.wait_for(lambda: out.subs[0].get_num_connections() > 0,
                          "no connection to /%s/ground" % name)
            msg = make_cloud(self.rec, "velodyne", self.next_stamp())
            sent = 0
            # One at a time (each after its output): nothing lost, seq counting confirmed.
            for _ in range(4):
                msg.header.stamp = self.next_stamp()
                stamp = msg.header.stamp
                pub.publish(msg)
                sent += 1
                self.wait_for(lambda s=stamp: out.get("/%s/ground" % name, s) is not None,
                              "no output for a single cloud")
            self.assertEqual(self.number(name, key) or 0, 0)
            for _ in range(30):  # a burst: the manager's queue keeps only the newest
                msg.header.stamp = self.next_stamp()
                pub.publish(msg)
                sent += 1
            last = msg.header.stamp
            self.wait_for(lambda: out.get("/%s/ground" % name, last) is not None,
                          "no output for the last cloud of the burst (it is never dropped)")
            self.wait_for(lambda: (self.number(name, "clouds in") or 0) +
                          (self.number(name, key) or 0) == sent,
                          "clouds in + lost != %d sent: in %s, lost %s" % (
                              sent, self.number(name, "clouds in"), self.number(name, key)),
                          timeout=10.0)
            lost = self.number(name, key)
            self.assertGreater(lost, 0, "a 30-cloud burst into a queue of 1 lost nothing?")
            # Every cloud that reached the filter was published (the nodelet's own count; the
            # test's Python subscriber may miss some of a burst when the machine is loaded: the
            # publisher keeps a short queue per subscriber).
            self.wait_for(lambda: self.number(name, "clouds out") == sent - lost,
                          "clouds out != %d in: %s" % (sent - lost, self.number(name, "clouds out")),
                          timeout=10.0)
            self.assertLessEqual(out.count("/%s/ground" % name), sent - lost)
            self.wait_for(lambda: self.logged(Log.WARN, "lost before the filter (seq "),
                          "no WARN naming the lost clouds", timeout=10.0)
            self.wait_for(lambda: any(st.level == DiagnosticStatus.WARN and
                                      "lost before the filter" in st.message
                                      for st in list(statuses)),
                          "diagnostics not WARN while clouds were lost", timeout=10.0)
        finally:
            sub.unregister()
            out.close()

    def test_gravity_frame_never_arrives(self):
        """No transform to the gravity frame: clouds dropped and counted, WARN, nodelet not stuck
        (each cloud waits tf_timeout = 0.05 s at most)."""
        out = Outputs(["/notf_filter/ground", "/notf_filter/nonground"])
        try:
            self.connect(self.pubs["notf"])
            small = self.rec[:20000]
            for batch in (1, 2):
                for _ in range(5):
                    self.pubs["notf"].publish(make_cloud(small, "velodyne", self.next_stamp()))
                    time.sleep(0.1)
                self.wait_for(lambda b=batch: self.number(
                    "notf_filter", "dropped: no transform") == 5 * b,
                    "diagnostics: %d clouds dropped for want of a transform" % (5 * batch),
                    timeout=20.0)
            st = self.status("notf_filter")
            self.assertEqual(self.number("notf_filter", "clouds out"), 0)
            self.assertEqual(self.value("notf_filter", "gravity frame"), "frame_nobody_publishes")
            self.wait_for(lambda: self.status("notf_filter").level == DiagnosticStatus.WARN,
                          "diagnostics not WARN while clouds are dropped", timeout=10.0)
            self.wait_for(lambda: self.logged(Log.WARN, "no transform from 'velodyne' to gravity "
                                                        "frame 'frame_nobody_publishes'"),
                          "no WARN naming the missing transform", timeout=10.0)
            self.assertEqual(out.count("/notf_filter/ground"), 0)
            rospy.loginfo("notf_filter: %s", st.message)
        finally:
            out.close()

    def test_diagnostics_report(self):
        """Rates, processing time, counts and backend on /diagnostics while clouds stream."""
        out = Outputs(["/flat_filter/ground"])
        try:
            self.connect(self.pubs["flat"])
            small = self.rec[:30000]
            for _ in range(15):
                self.pubs["flat"].publish(make_cloud(small, "velodyne", self.next_stamp()))
                time.sleep(0.1)
            self.wait_for(lambda: (self.number("flat_filter", "input rate [Hz]") or 0) > 1.0 and
                          self.number("flat_filter", "processing time max [ms]") is not None,
                          "a diagnostic update with clouds flowing")
            name = "flat_filter"
            for key in ("method", "backend", "gravity frame", "input rate [Hz]",
                        "output rate [Hz]", "processing time mean [ms]",
                        "processing time max [ms]", "clouds in", "clouds out", "dropped",
                        "dropped: malformed", "dropped: no transform", "dropped: not PointCloud2",
                        "out of range points", "invalid points (NaN/Inf)", "fallbacks",
                        "frame_id changes", "stamps going back"):
                self.assertIsNotNone(self.value(name, key), "diagnostics lack '%s'" % key)
            self.assertEqual(self.value(name, "method"), rospy.get_param("~method"))
            self.assertGreater(self.number(name, "processing time max [ms]"), 0.0)
            self.assertGreaterEqual(self.number(name, "processing time max [ms]"),
                                    self.number(name, "processing time mean [ms]"))
            self.wait_for(lambda: self.number(name, "clouds out") >= 15, "clouds out >= 15")
            self.assertEqual(self.number(name, "dropped"), 0)
            # Where the cloud lies: the middle of the bounding box of at most 4096 records
            # spread evenly (finite ones), "x y z in 'frame' ...", printed to 0.1 m.
            centre = self.value(name, "cloud centre [m]")
            self.assertIsNotNone(centre, "diagnostics lack 'cloud centre [m]'")
            self.assertIn("in 'velodyne'", centre)
            got = [float(v) for v in centre.split()[:3]]
            s = small[::-(-small.shape[0] // 4096)]  # step ceil(n / 4096): <= 4096 read
            s = s[np.isfinite(s["x"]) & np.isfinite(s["y"]) & np.isfinite(s["z"])]
            for axis, g in zip(("x", "y", "z"), got):
                c = s[axis].astype(np.float64)
                self.assertAlmostEqual(g, 0.5 * (c.min() + c.max()), delta=0.051,
                                       msg="cloud centre %s: %s" % (axis, centre))
            st = self.status(name)
            rospy.loginfo("flat_filter diagnostics: level %d '%s' %s", st.level, st.message,
                          {kv.key: kv.value for kv in st.values})
        finally:
            out.close()

    def test_bad_bag_other_messages_frame_changes_loop(self):
        """A looped bag with std_msgs/String messages on the cloud topic and two frame_ids:
        strings dropped and counted, frame changes and stamps going back counted, every cloud
        split with counts conserved, the nodelet alive afterwards."""
        tmp = tempfile.mkdtemp(prefix="gf_extras_")
        bag_path = os.path.join(tmp, "mixed.bag")
        small = self.rec[:20000]
        with rosbag.Bag(bag_path, "w") as bag:
            for i, frame in enumerate(["velodyne", None, "velodyne_b", None, "velodyne"]):
                t = rospy.Time(10, 0) + rospy.Duration(0.1 * i)
                if frame is None:  # rosbag's Python writer files it under the cloud connection
                    bag.write("/gf_extras/bag", String(data="not a cloud %d" % i), t)
                else:
                    bag.write("/gf_extras/bag", make_cloud(small, frame, t), t)
        out = Outputs(["/bag_filter/ground", "/bag_filter/nonground"])
        player = None
        try:
            self.wait_for(lambda: self.input_subscribed("/gf_extras/bag"), "bag_filter input")
            player = subprocess.Popen(["rosbag", "play", "-q", "-l", "-d", "0.5", bag_path],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                                      start_new_session=True)
            name = "bag_filter"
            self.wait_for(lambda: (self.number(name, "dropped: not PointCloud2") or 0) >= 4 and
                          (self.number(name, "stamps going back") or 0) >= 1 and
                          (self.number(name, "frame_id changes") or 0) >= 2 and
                          (self.number(name, "clouds out") or 0) >= 6,
                          "bag_filter diagnostics counting the bad stream")
        finally:
            if player is not None and player.poll() is None:
                os.killpg(player.pid, signal.SIGINT)
                player.wait(timeout=20)
            os.remove(bag_path)
            os.rmdir(tmp)
        try:
            self.assertEqual(self.number(name, "dropped: malformed"), 0)
            with out.lock:
                keys = sorted({s for _, s in out.got})
                for s in keys:
                    g = out.got.get(("/bag_filter/ground", s))
                    ng = out.got.get(("/bag_filter/nonground", s))
                    if g is not None and ng is not None:
                        self.assertEqual(g.width + ng.width, small.shape[0])
                        self.assertEqual(g.header.frame_id, ng.header.frame_id)
            for text in ("dropped a message on /gf_extras/bag", "input frame_id changed",
                         "input stamp went back"):
                self.wait_for(lambda t=text: self.logged(Log.WARN, t), "no WARN '%s'" % text,
                              timeout=10.0)
            # Still alive: a good cloud published now comes out split.
            pub = rospy.Publisher("/gf_extras/bag", PointCloud2, queue_size=2)
            self.connect(pub)
            stamp = self.next_stamp()
            pub.publish(make_cloud(small, "velodyne", stamp))
            self.wait_for(lambda: out.get("/bag_filter/ground", stamp) and
                          out.get("/bag_filter/nonground", stamp), "a cloud after the bad bag")
            rospy.loginfo("bag_filter: %s", self.status(name).message)
        finally:
            out.close()


    def test_far_points_working_volume(self):
        """Issue 12: 1000 points 300 km .. 1e30 m away in a KITTI frame are published as
        non-ground and counted ("out of range points"); every other point keeps the label it
        gets without them."""
        topics = ["/flat_filter/ground", "/flat_filter/nonground"]
        out = Outputs(topics)
        try:
            self.connect(self.pubs["flat"])
            n = self.rec.shape[0]
            far = np.zeros(1000, dtype=REC)
            values = np.array([3e5, -1e7, 1e30, -1e30], dtype=np.float32)
            far["x"] = values[np.arange(1000) % 4]
            far["y"] = 1.0
            far["z"] = -1.0
            far["idx"] = n + np.arange(1000, dtype=np.uint32)
            # Far points at random places; the frame's own points keep their order (the normal
            # filter's RANSAC and neighbour ties depend on the order, not on the far points).
            rng = np.random.RandomState(3)
            is_far = np.zeros(n + 1000, dtype=bool)
            is_far[rng.choice(n + 1000, 1000, replace=False)] = True
            mixed = np.zeros(n + 1000, dtype=REC)
            mixed[~is_far] = self.rec
            mixed[is_far] = far
            self.wait_for(lambda: all(s.get_num_connections() > 0 for s in out.subs),
                          "output subscriptions connected")
            self.wait_for(lambda: self.input_subscribed("/gf_extras/flat"), "flat_filter input")
            before = self.number("flat_filter", "out of range points") or 0
            ref_stamp, far_stamp = self.next_stamp(), self.next_stamp()
            clouds = [make_cloud(self.rec, "velodyne", ref_stamp),
                      make_cloud(mixed, "velodyne", far_stamp)]
            # Published again until both come back: the input connection of the lazy filter
            # may still be the one an earlier test closed.
            deadline = time.monotonic() + WAIT_S
            while not all(out.get(t, s) for t in topics for s in (ref_stamp, far_stamp)):
                self.assertLess(time.monotonic(), deadline, "both clouds split")
                for c in clouds:
                    self.pubs["flat"].publish(c)
                end = time.monotonic() + 5.0
                while time.monotonic() < end and not all(
                        out.get(t, s) for t in topics for s in (ref_stamp, far_stamp)):
                    time.sleep(0.05)
            ref_g = np.frombuffer(out.get(topics[0], ref_stamp).data, dtype=REC)["idx"]
            far_g = np.frombuffer(out.get(topics[0], far_stamp).data, dtype=REC)["idx"]
            far_ng = np.frombuffer(out.get(topics[1], far_stamp).data, dtype=REC)["idx"]
            self.assertEqual(far_g.size + far_ng.size, n + 1000)
            self.assertGreater(ref_g.size, n // 3)
            self.assertFalse(np.any(far_g >= n), "a far point was labelled ground")
            np.testing.assert_array_equal(np.sort(far_g), np.sort(ref_g))
            self.wait_for(lambda: (self.number("flat_filter", "out of range points") or 0) >=
                          before + 1000, "diagnostics counting the 1000 out of range points")
            self.assertEqual(self.number("flat_filter", "filter errors (published as non-ground)"),
                             0)
        finally:
            out.close()

    def test_startup_bag_first_message_at_once(self):
        """Issue 12: a bag whose messages start at once, played in a burst right after the
        nodelet came up: every cloud is filtered and published, none is lost for want of a
        filter (the first filter object is built in onInit)."""
        name = "startup_filter"
        self.wait_for(lambda: self.input_subscribed("/gf_extras/startup"), "startup_filter input")
        self.assertEqual(self.number(name, "clouds in") or 0, 0, "a cloud before the bag")
        tmp = tempfile.mkdtemp(prefix="gf_startup_")
        bag_path = os.path.join(tmp, "startup.bag")
        small = self.rec  # the whole frame: its first rings alone may hold no ground
        with rosbag.Bag(bag_path, "w") as bag:
            for i in range(3):
                t = rospy.Time(20, 0) + rospy.Duration(0.001 * i)
                bag.write("/gf_extras/startup", make_cloud(small, "velodyne", t), t)
        out = Outputs(["/startup_filter/ground", "/startup_filter/nonground"])
        player = None
        try:
            self.wait_for(lambda: all(s.get_num_connections() > 0 for s in out.subs),
                          "output subscriptions connected")
            # -i: no pause between messages; --wait-for-subscribers: the first one is sent the
            # moment the nodelet's input is connected; -k: the player stays up until its send
            # queue is out (a player that exits at once may drop what it has not sent yet).
            player = subprocess.Popen(["rosbag", "play", "-q", "-i", "-k",
                                       "--wait-for-subscribers", bag_path],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT,
                                      start_new_session=True)
            for i in range(3):
                stamp = rospy.Time(20, 0) + rospy.Duration(0.001 * i)
                self.wait_for(lambda s=stamp: out.get("/startup_filter/ground", s) and
                              out.get("/startup_filter/nonground", s),
                              "cloud %d of the bag split" % i)
                g = out.get("/startup_filter/ground", stamp)
                ng = out.get("/startup_filter/nonground", stamp)
                self.assertEqual(g.width + ng.width, small.shape[0])
                self.assertGreater(g.width, 0)
            self.wait_for(lambda: self.number(name, "clouds out") == 3, "diagnostics: 3 out")
            self.assertEqual(self.number(name, "clouds in"), 3)
            self.assertEqual(self.number(name, "dropped"), 0)
            self.assertEqual(self.number(name, "filter errors (published as non-ground)"), 0)
        finally:
            if player is not None and player.poll() is None:
                os.killpg(player.pid, signal.SIGINT)
                player.wait(timeout=20)
            out.close()
            os.remove(bag_path)
            os.rmdir(tmp)

if __name__ == "__main__":
    rostest.rosrun(PKG, "ros_extras", RosExtrasTest, sys.argv)
