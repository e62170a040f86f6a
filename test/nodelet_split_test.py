#!/usr/bin/env python3
"""rostest for a ground_filter nodelet: the plumbing around the algorithm, not its accuracy.

Publishes a real KITTI frame (with extra fields) and hand-made clouds on the nodelet's input and
checks the outputs: every input record lands byte-identical in exactly one of ~ground/~nonground,
header and fields are preserved, one output pair per input at 10 Hz, malformed clouds produce no
output and do not stop the nodelet, empty clouds give two empty clouds, NaN/Inf points are
non-ground, and dynamic_reconfigure changes are applied (or clamped / refused) while clouds stream.

Private parameters:
  ~data_file          KITTI .bin scan (float32 x y z intensity)
  ~filter_name        resolved name of the nodelet, e.g. /voxel_filter
  ~input_topic        topic the nodelet's ~input is remapped to
  ~reconfigure_ok     dict of valid values, applied and read back unchanged
  ~reconfigure_clamp  dict of out-of-range values ...
  ~reconfigure_clamp_expect  ... and the values the server must clamp them to
  ~reconfigure_refused       dict the cfg ranges allow but Params::validate() refuses
"""

import math
import os
import sys
import threading
import time

import numpy as np
import rospkg
import rospy
import rostest
from dynamic_reconfigure.client import Client as ReconfigureClient
from rosgraph_msgs.msg import Log
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Float64

PKG = "ground_filter"
WAIT_S = 60.0  # generous: the test machine may be slow; never a timing assertion

sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
from rostest_helpers import RosTestCase  # noqa: E402

# Record layout of the published test clouds: x/y/z not at offset 0, a float64 and a uint16
# field, and 6 padding bytes that must be copied too (zero loss means whole records).
RECORD = np.dtype({
    "names": ["time", "x", "y", "z", "intensity", "ring", "pad"],
    "formats": ["<f8", "<f4", "<f4", "<f4", "<f4", "<u2", ("u1", (6,))],
    "offsets": [0, 8, 12, 16, 20, 24, 26],
    "itemsize": 32,
})
# Listed in an order different from the offsets on purpose.
FIELDS = [
    PointField(name="z", offset=16, datatype=PointField.FLOAT32, count=1),
    PointField(name="intensity", offset=20, datatype=PointField.FLOAT32, count=1),
    PointField(name="x", offset=8, datatype=PointField.FLOAT32, count=1),
    PointField(name="y", offset=12, datatype=PointField.FLOAT32, count=1),
    PointField(name="ring", offset=24, datatype=PointField.UINT16, count=1),
    PointField(name="time", offset=0, datatype=PointField.FLOAT64, count=1),
]

# The same with float64 x/y/z (survey and map clouds): 40-byte records.
RECORD64 = np.dtype({
    "names": ["time", "x", "y", "z", "intensity", "ring", "pad"],
    "formats": ["<f8", "<f8", "<f8", "<f8", "<f4", "<u2", ("u1", (2,))],
    "offsets": [0, 8, 16, 24, 32, 36, 38],
    "itemsize": 40,
})
FIELDS64 = [
    PointField(name="x", offset=8, datatype=PointField.FLOAT64, count=1),
    PointField(name="y", offset=16, datatype=PointField.FLOAT64, count=1),
    PointField(name="z", offset=24, datatype=PointField.FLOAT64, count=1),
    PointField(name="intensity", offset=32, datatype=PointField.FLOAT32, count=1),
    PointField(name="ring", offset=36, datatype=PointField.UINT16, count=1),
    PointField(name="time", offset=0, datatype=PointField.FLOAT64, count=1),
]


def make_records(xyzi):
    """Structured records for an (n, 4) float32 array x y z intensity."""
    n = xyzi.shape[0]
    rec = np.zeros(n, dtype=RECORD)
    rec["x"], rec["y"], rec["z"], rec["intensity"] = xyzi[:, 0], xyzi[:, 1], xyzi[:, 2], xyzi[:, 3]
    rec["ring"] = np.arange(n) % 64
    rec["time"] = np.arange(n, dtype=np.float64) * 1e-6  # unique per point: order is checkable
    rec["pad"] = (np.arange(n)[:, None] * 7 + np.arange(6)[None, :]) % 251
    return rec


def make_cloud(records, stamp, frame_id="velodyne", height=1, row_pad=0, fields=None):
    """PointCloud2 over structured records; `row_pad` bytes of junk after each row."""
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    n = records.shape[0]
    msg.height = height
    msg.width = n // height if height else 0
    msg.fields = list(fields or FIELDS)
    msg.is_bigendian = False
    msg.point_step = records.dtype.itemsize
    msg.row_step = msg.width * msg.point_step + row_pad
    raw = records.view(np.uint8).reshape(n, msg.point_step)
    if row_pad:
        rows = raw.reshape(height, msg.width * msg.point_step)
        junk = np.full((height, row_pad), 0xAB, dtype=np.uint8)
        raw = np.hstack([rows, junk])
    msg.data = raw.tobytes()
    msg.is_dense = bool(np.isfinite(np.stack([records["x"], records["y"], records["z"]])).all())
    return msg


def rows_of(msg):
    """(n, point_step) uint8 array of the records of a contiguous cloud."""
    n = msg.width * msg.height
    if n == 0:
        return np.zeros((0, msg.point_step), dtype=np.uint8)
    return np.frombuffer(msg.data, dtype=np.uint8).reshape(n, msg.point_step)


def sorted_rows(rows):
    """Rows sorted as byte strings (multiset comparison)."""
    if rows.shape[0] == 0:
        return rows
    words = np.ascontiguousarray(rows).view("<u8")  # 32-byte records -> 4 words
    order = np.lexsort(words.T[::-1])
    return rows[order]


def field_tuples(fields):
    return [(f.name, f.offset, f.datatype, f.count) for f in fields]


class PairCollector:
    """Collects ~ground/~nonground messages and pairs them by header stamp."""

    def __init__(self, filter_name):
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self.ground = {}
        self.nonground = {}
        self.arrival = {}
        big = 1 << 26  # rospy needs a large buffer for multi-MB messages
        self._subs = [
            rospy.Subscriber(filter_name + "/ground", PointCloud2, self._cb, "ground",
                             queue_size=1000, buff_size=big),
            rospy.Subscriber(filter_name + "/nonground", PointCloud2, self._cb, "nonground",
                             queue_size=1000, buff_size=big),
        ]

    def _cb(self, msg, which):
        key = msg.header.stamp.to_nsec()
        with self._cond:
            (self.ground if which == "ground" else self.nonground)[key] = msg
            if key in self.ground and key in self.nonground:
                self.arrival[key] = time.monotonic()
            self._cond.notify_all()

    def wait_pairs(self, stamps, timeout=WAIT_S):
        """Waits until every stamp has both outputs; returns {nsec: (ground, nonground)}."""
        keys = [s.to_nsec() for s in stamps]
        deadline = time.monotonic() + timeout
        with self._cond:
            while not all(k in self.ground and k in self.nonground for k in keys):
                left = deadline - time.monotonic()
                if left <= 0 or rospy.is_shutdown():
                    break
                self._cond.wait(min(left, 0.5))
            return {k: (self.ground.get(k), self.nonground.get(k)) for k in keys}

    def seen(self, stamp):
        k = stamp.to_nsec()
        with self._lock:
            return k in self.ground or k in self.nonground

    def unregister(self):
        for s in self._subs:
            s.unregister()


class NodeletSplitTest(RosTestCase):
    POLL_S = 0.05

    @classmethod
    def setUpClass(cls):
        rospy.init_node("nodelet_split_test", anonymous=True)
        cls.filter_name = rospy.get_param("~filter_name")
        cls.input_topic = rospy.get_param("~input_topic")
        data_file = rospy.get_param("~data_file")
        cls.kitti = np.fromfile(data_file, dtype=np.float32).reshape(-1, 4)
        cls.kitti_records = make_records(cls.kitti)
        cls.pub = rospy.Publisher(cls.input_topic, PointCloud2, queue_size=200)
        cls.collector = None
        # Both the raw and the aggregated log: either one is enough to see the nodelet's ERRORs.
        cls.collect_rosout(("/rosout", "/rosout_agg"))
        # The nodelet is loaded once its outputs are advertised.
        deadline = time.monotonic() + WAIT_S
        want = cls.filter_name + "/ground"
        while time.monotonic() < deadline and not rospy.is_shutdown():
            if any(t == want for t, _ in rospy.get_published_topics()):
                break
            time.sleep(0.2)
        else:
            raise AssertionError("nodelet never advertised " + want)

    def subscribe_outputs(self):
        """Subscribes to both outputs (starting the lazy input subscription) once."""
        cls = type(self)
        if cls.collector is None:
            cls.collector = PairCollector(cls.filter_name)
        self.wait_for(lambda: cls.pub.get_num_connections() >= 1,
                      "the nodelet never subscribed to " + cls.input_topic)
        return cls.collector

    def assert_split(self, cloud, ground, nonground, xyz=(8, 20, "<f4")):
        """The zero-loss contract for one input cloud and its two outputs (x/y/z at bytes
        xyz[0]:xyz[1] of a record, of type xyz[2])."""
        self.assertIsNotNone(ground, "no ~ground output")
        self.assertIsNotNone(nonground, "no ~nonground output")
        n_in = cloud.width * cloud.height
        for out in (ground, nonground):
            self.assertEqual(out.header.frame_id, cloud.header.frame_id)
            self.assertEqual(out.header.stamp, cloud.header.stamp)
            self.assertEqual(field_tuples(out.fields), field_tuples(cloud.fields))
            self.assertEqual(out.point_step, cloud.point_step)
            self.assertEqual(out.height, 1)
            self.assertEqual(out.row_step, out.width * out.point_step)
            self.assertEqual(len(out.data), out.row_step)
            self.assertFalse(out.is_bigendian)
        self.assertEqual(ground.width + nonground.width, n_in)
        if cloud.height > 1 and cloud.row_step != cloud.width * cloud.point_step:
            raw = np.frombuffer(cloud.data, dtype=np.uint8).reshape(cloud.height, cloud.row_step)
            rows_in = np.ascontiguousarray(raw[:, :cloud.width * cloud.point_step]).reshape(
                n_in, cloud.point_step)
        else:
            rows_in = rows_of(cloud)
        rows_out = np.vstack([rows_of(ground), rows_of(nonground)])
        np.testing.assert_array_equal(sorted_rows(rows_out), sorted_rows(rows_in),
                                      "output records are not the input records")
        # Input order is kept inside each output (the time field grows with the input index).
        for out in (ground, nonground):
            t = rows_of(out)[:, 0:8].copy().view("<f8").ravel()
            self.assertTrue(np.all(np.diff(t) > 0), "output not in input order")
        # Ground holds finite points only.
        g = rows_of(ground)
        if g.shape[0]:
            coords = np.ascontiguousarray(g[:, xyz[0]:xyz[1]]).view(xyz[2])
            self.assertTrue(np.isfinite(coords).all(), "NaN/Inf point in ~ground")
            self.assertTrue(ground.is_dense)

    # ------------------------------------------------------------------------------------ tests

    def test_00_lazy_subscription(self):
        """No input subscription without output subscribers; one with; none again after."""
        # unittest runs methods alphabetically: this one comes before any output subscription.
        self.assertIsNone(type(self).collector, "outputs already subscribed by an earlier test")
        time.sleep(1.0)  # nodelet loaded (setUpClass): give a wrong eager subscribe time to show
        self.assertEqual(self.pub.get_num_connections(), 0,
                         "nodelet subscribed to its input with no output subscriber")
        probe = rospy.Subscriber(self.filter_name + "/nonground", PointCloud2, lambda m: None)
        self.wait_for(lambda: self.pub.get_num_connections() >= 1,
                      "no input subscription after subscribing to ~nonground")
        probe.unregister()
        self.wait_for(lambda: self.pub.get_num_connections() == 0,
                      "input subscription kept after the last output subscriber left")

    def test_kitti_frame_split(self):
        """Real KITTI frame with extra fields: counts, bytes, header and fields preserved."""
        col = self.subscribe_outputs()
        stamp = self.next_stamp()
        cloud = make_cloud(self.kitti_records, stamp)
        self.pub.publish(cloud)
        ground, nonground = col.wait_pairs([stamp])[stamp.to_nsec()]
        self.assert_split(cloud, ground, nonground)
        rospy.loginfo("KITTI 000000: %d in, %d ground, %d non-ground", cloud.width, ground.width,
                      nonground.width)
        self.assertTrue(nonground.is_dense)  # the KITTI frame has no NaN points

    def test_rate_10hz(self):
        """N clouds published at 10 Hz give N output pairs, plus N processing-time samples."""
        col = self.subscribe_outputs()
        times = []
        time_sub = rospy.Subscriber(self.filter_name + "/processing_time_ms", Float64,
                                    lambda m: times.append(m.data), queue_size=1000)
        self.wait_for(lambda: time_sub.get_num_connections() >= 1, "no processing_time_ms pub")
        n = 20
        stamps = [self.next_stamp() for _ in range(n)]
        rate = rospy.Rate(10)
        t0 = time.monotonic()
        for s in stamps:
            self.pub.publish(make_cloud(self.kitti_records, s))
            rate.sleep()
        pairs = col.wait_pairs(stamps)
        missing = [k for k, (g, ng) in pairs.items() if g is None or ng is None]
        self.assertEqual(missing, [], "%d of %d clouds got no output pair" % (len(missing), n))
        arrivals = sorted(col.arrival[s.to_nsec()] for s in stamps)
        span = arrivals[-1] - arrivals[0]
        self.wait_for(lambda: len(times) >= n, "processing_time_ms samples", timeout=10.0)
        time_sub.unregister()
        self.assertTrue(all(math.isfinite(t) and t >= 0.0 for t in times))
        rospy.loginfo("rate: %d clouds sent in %.2f s, %d pairs received over %.2f s "
                      "(%.1f Hz); nodelet ms median %.2f max %.2f", n,
                      time.monotonic() - t0, len(pairs), span, (n - 1) / span if span else 0.0,
                      float(np.median(times)), float(np.max(times)))
        for k, (g, ng) in pairs.items():
            self.assertEqual(g.width + ng.width, self.kitti.shape[0])

    def test_empty_clouds(self):
        """width 0 (height 1) and height 0 clouds give two empty clouds each."""
        col = self.subscribe_outputs()
        stamps = []
        for height in (1, 0):
            stamp = self.next_stamp()
            cloud = make_cloud(self.kitti_records[:0], stamp, height=height)
            self.pub.publish(cloud)
            stamps.append((stamp, cloud))
        pairs = col.wait_pairs([s for s, _ in stamps])
        for stamp, cloud in stamps:
            ground, nonground = pairs[stamp.to_nsec()]
            self.assert_split(cloud, ground, nonground)
            self.assertEqual(ground.width, 0)
            self.assertEqual(nonground.width, 0)

    def test_nan_inf_points_go_to_nonground(self):
        """NaN/Inf points (any of x, y, z) all land in ~nonground; counts conserved."""
        col = self.subscribe_outputs()
        rec = self.kitti_records[:20000].copy()
        bad = np.arange(0, rec.shape[0], 7)
        rec["x"][bad[0::3]] = np.nan
        rec["y"][bad[1::3]] = np.inf
        rec["z"][bad[2::3]] = -np.inf
        stamp = self.next_stamp()
        cloud = make_cloud(rec, stamp)
        self.assertFalse(cloud.is_dense)
        self.pub.publish(cloud)
        ground, nonground = col.wait_pairs([stamp])[stamp.to_nsec()]
        self.assert_split(cloud, ground, nonground)
        bad_rows = sorted_rows(rows_of(cloud)[bad])
        ng_times = set(rows_of(nonground)[:, 0:8].copy().view("<f8").ravel().tolist())
        bad_times = rec["time"][bad].tolist()
        self.assertTrue(all(t in ng_times for t in bad_times), "a NaN/Inf point is not in ~nonground")
        self.assertGreaterEqual(nonground.width, bad_rows.shape[0])
        self.assertFalse(nonground.is_dense)
        self.assertTrue(ground.is_dense)

    def test_far_outliers_cloud_still_split(self):
        """Points 10,000 km away (wider than a voxel grid can index): the cloud still comes out
        whole, split, the outliers non-ground; the filter may refuse it (all non-ground)."""
        col = self.subscribe_outputs()
        rec = self.kitti_records[:20000].copy()
        rec["x"][[5, 500]] = np.float32(1.0e7)
        rec["y"][[5, 500]] = np.float32(-1.0e7)
        stamp = self.next_stamp()
        cloud = make_cloud(rec, stamp)
        self.pub.publish(cloud)
        ground, nonground = col.wait_pairs([stamp])[stamp.to_nsec()]
        self.assert_split(cloud, ground, nonground)
        ng_times = set(rows_of(nonground)[:, 0:8].copy().view("<f8").ravel().tolist())
        for t in rec["time"][[5, 500]].tolist():
            self.assertIn(t, ng_times, "a far outlier is not in ~nonground")

    def test_float64_xyz_cloud_split(self):
        """x/y/z as float64 (survey and map clouds): the float32 cloud's split, records whole."""
        col = self.subscribe_outputs()
        rec32 = self.kitti_records[:30000]
        rec64 = np.zeros(rec32.shape[0], dtype=RECORD64)
        for name in ("time", "x", "y", "z", "intensity", "ring"):
            rec64[name] = rec32[name]
        s32, s64 = self.next_stamp(), self.next_stamp()
        c32, c64 = make_cloud(rec32, s32), make_cloud(rec64, s64, fields=FIELDS64)
        self.pub.publish(c32)
        g32, _ = col.wait_pairs([s32])[s32.to_nsec()]
        self.pub.publish(c64)
        g64, ng64 = col.wait_pairs([s64])[s64.to_nsec()]
        self.assert_split(c64, g64, ng64, xyz=(8, 32, "<f8"))
        # The same points are ground (the coordinates are floats widened to doubles).
        t32 = rows_of(g32)[:, 0:8].copy().view("<f8").ravel()
        t64 = rows_of(g64)[:, 0:8].copy().view("<f8").ravel()
        np.testing.assert_array_equal(t64, t32, "float64 cloud split differently")
        self.assertGreater(g64.width, 100)

    def test_organised_cloud_with_row_padding(self):
        """height > 1 with row_step > width * point_step: padding skipped, records kept."""
        col = self.subscribe_outputs()
        rec = self.kitti_records[:64 * 1000]
        stamp = self.next_stamp()
        cloud = make_cloud(rec, stamp, height=64, row_pad=24)
        self.pub.publish(cloud)
        ground, nonground = col.wait_pairs([stamp])[stamp.to_nsec()]
        self.assert_split(cloud, ground, nonground)

    def test_malformed_clouds_rejected_nodelet_alive(self):
        """Malformed clouds: nothing published, an ERROR naming the reason, next cloud still works."""
        col = self.subscribe_outputs()
        good = self.kitti_records[:5000]

        def variant(mutate):
            stamp = self.next_stamp()
            msg = make_cloud(good, stamp)
            mutate(msg)
            return stamp, msg

        def drop_z(m):
            m.fields = [f for f in m.fields if f.name != "z"]

        def short_data(m):
            m.data = m.data[:-1]

        def small_point_step(m):
            m.point_step = 20  # ring (24) and time... reach past it; data kept consistent
            m.row_step = m.width * m.point_step
            m.data = m.data[:m.row_step]

        def small_row_step(m):
            m.row_step = m.width * m.point_step - 1
            m.data = m.data[:m.row_step]

        def x_float64(m):
            m.fields = [PointField(name=f.name, offset=f.offset,
                                   datatype=PointField.FLOAT64 if f.name == "x" else f.datatype,
                                   count=f.count) for f in m.fields]

        def z_count3(m):
            m.fields = [PointField(name=f.name, offset=f.offset, datatype=f.datatype,
                                   count=3 if f.name == "z" else f.count) for f in m.fields]

        def big_endian(m):
            m.is_bigendian = True

        cases = [
            (drop_z, "no field 'z'"),
            (short_data, "data size"),
            (small_point_step, "point_step 20 is smaller than field"),
            (small_row_step, "< width 5000 * point_step 32"),
            (x_float64, "field 'x' has datatype 8"),
            (z_count3, "field 'z' has count 3"),
            (big_endian, "is_bigendian"),
        ]
        bad = [variant(mutate) for mutate, _ in cases]
        for _, msg in bad:
            self.pub.publish(msg)
        ok_stamp = self.next_stamp()
        ok_cloud = make_cloud(good, ok_stamp)
        self.pub.publish(ok_cloud)
        ground, nonground = col.wait_pairs([ok_stamp])[ok_stamp.to_nsec()]
        self.assert_split(ok_cloud, ground, nonground)
        time.sleep(0.5)  # any (wrong) output of the bad clouds would have come before the good one
        for (stamp, _), (_, reason) in zip(bad, cases):
            self.assertFalse(col.seen(stamp), "output published for a cloud with " + reason)

        for _, reason in cases:
            self.wait_for(lambda r=reason: self.logged(Log.ERROR, r),
                          "no ERROR on /rosout naming '%s'" % reason, timeout=10.0)

    def test_reconfigure_while_streaming(self):
        """dynamic_reconfigure: valid values applied, out-of-range clamped, invalid refused;
        clouds streamed meanwhile all come out."""
        col = self.subscribe_outputs()
        client = ReconfigureClient(self.filter_name, timeout=WAIT_S)
        before = client.get_configuration(timeout=WAIT_S)
        ok = rospy.get_param("~reconfigure_ok")
        clamp = rospy.get_param("~reconfigure_clamp")
        clamp_expect = rospy.get_param("~reconfigure_clamp_expect")
        refused = rospy.get_param("~reconfigure_refused")

        stamps = []
        stop = threading.Event()
        rec = self.kitti_records

        def stream():
            rate = rospy.Rate(10)
            while not stop.is_set() and not rospy.is_shutdown():
                s = self.next_stamp()
                stamps.append(s)
                self.pub.publish(make_cloud(rec, s))
                rate.sleep()

        streamer = threading.Thread(target=stream)
        streamer.start()
        try:
            time.sleep(0.5)
            got = client.update_configuration(ok)
            for k, v in ok.items():
                self.assertAlmostEqual(got[k], v, msg="valid value of %s not applied" % k)
            time.sleep(0.5)
            got = client.update_configuration(clamp)
            for k, v in clamp_expect.items():
                self.assertAlmostEqual(got[k], v, msg="out-of-range %s not clamped" % k)
            time.sleep(0.5)
            previous = client.get_configuration(timeout=WAIT_S)
            got = client.update_configuration(refused)
            for k in refused:
                self.assertAlmostEqual(got[k], previous[k],
                                       msg="invalid %s accepted instead of refused" % k)
            time.sleep(0.5)
        finally:
            stop.set()
            streamer.join()
            client.update_configuration({k: before[k] for k in set(ok) | set(clamp) | set(refused)})
        pairs = col.wait_pairs(stamps)
        missing = [k for k, (g, ng) in pairs.items() if g is None or ng is None]
        self.assertEqual(missing, [], "%d of %d clouds streamed during reconfiguration got no "
                         "output" % (len(missing), len(stamps)))
        for g, ng in pairs.values():
            self.assertEqual(g.width + ng.width, rec.shape[0])
        rospy.loginfo("reconfigure: %d clouds streamed, %d pairs received", len(stamps),
                      len(pairs))

        self.wait_for(lambda: self.logged(Log.ERROR, "parameters refused"),
                      "no ERROR for the refused parameters", timeout=10.0)


if __name__ == "__main__":
    rostest.rosrun(PKG, "nodelet_split_test", NodeletSplitTest, sys.argv)
