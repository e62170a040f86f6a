#!/usr/bin/env python3
"""rostest: height above ground in the filter nodelets (hag_outputs.test): the
`height_above_ground` field of ~labeled (and of ~ground / ~nonground with ~hag_field), the lazy
~ground_surface and ~obstacles outputs on a generated street corner (a road, a kerb up to a
pavement, a pedestrian, a branch overhanging the road, a ditch point), the obstacle band
reconfigured, and a cloud without any ground."""
import os
import sys

import numpy as np
import rospkg
import rospy
import rostest
from dynamic_reconfigure.client import Client
from sensor_msgs.msg import PointCloud2, PointField

PKG = "ground_filter"
sys.path.insert(0, os.path.join(rospkg.RosPack().get_path(PKG), "scripts"))
from rostest_helpers import Outputs, RosTestCase  # noqa: E402

# What each generated point is (the `obj` field travels with the records).
GROUND, KERB, PAVEMENT, PEDESTRIAN, BRANCH, DITCH = range(6)
REC = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("obj", "u1"),
                ("pad", "V3")])
KERB_Y, KERB_H = 4.0, 0.15  # the pavement starts at y = 4 m, 0.15 m above the road
PED_XY, PED_R, PED_H = (6.0, -3.0), 0.25, 1.8
BRANCH_Z = (3.0, 3.3)  # above the road around (-4, -2): taller than obstacle_max_height 2.5
DITCH_Z = -0.3


def street_corner():
    """Road (z 0) and pavement (z 0.15) on a 0.1 m grid with the kerb face between, a
    pedestrian (a 0.25 m cylinder, 1.8 m), a horizontal branch 3-3.3 m up, a ditch point."""
    parts = []

    def add(x, y, z, obj):
        rec = np.zeros(x.size, dtype=REC)
        rec["x"], rec["y"], rec["z"], rec["obj"] = x, y, z, obj
        rec["intensity"] = np.float32(obj * 10 + 1)
        parts.append(rec)

    rng = np.random.RandomState(42)
    gx, gy = np.meshgrid(np.arange(-15.0, 15.0, 0.1), np.arange(-15.0, 15.0, 0.1))
    gx, gy = gx.ravel(), gy.ravel()
    noise = rng.normal(0.0, 0.005, gx.size)
    road = gy < KERB_Y
    add(gx[road], gy[road], noise[road], GROUND)
    add(gx[~road], gy[~road], KERB_H + noise[~road], PAVEMENT)
    kx, kz = np.meshgrid(np.arange(-15.0, 15.0, 0.05), np.arange(0.02, KERB_H, 0.03))
    add(kx.ravel(), np.full(kx.size, KERB_Y - 0.01), kz.ravel(), KERB)
    # Heights at random, as a scanner's rings meet a body at slant: no flat voxels.
    a, z = rng.uniform(0, 2 * np.pi, 1500), rng.uniform(0.1, PED_H, 1500)
    add(PED_XY[0] + PED_R * np.cos(a), PED_XY[1] + PED_R * np.sin(a), z, PEDESTRIAN)
    bx, bz = np.meshgrid(np.arange(-6.0, -2.0, 0.05), np.arange(BRANCH_Z[0], BRANCH_Z[1], 0.05))
    add(bx.ravel(), np.full(bx.size, -2.0), bz.ravel(), BRANCH)
    add(np.array([-8.05]), np.array([-8.05]), np.array([DITCH_Z]), DITCH)
    return np.concatenate(parts)


def make_cloud(rec, stamp, frame_id="map"):
    msg = PointCloud2()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    msg.height, msg.width = 1, rec.shape[0]
    types = {"obj": PointField.UINT8}
    msg.fields = [PointField(name=n, offset=REC.fields[n][1],
                             datatype=types.get(n, PointField.FLOAT32), count=1)
                  for n in REC.names if n != "pad"]
    msg.is_bigendian = False
    msg.point_step = REC.itemsize
    msg.row_step = REC.itemsize * rec.shape[0]
    msg.data = rec.tobytes()
    msg.is_dense = bool(np.all(np.isfinite(rec["x"])))
    return msg


def records(msg, dtype):
    """The records of `msg` as `dtype` (checks the layout first)."""
    assert msg.point_step == dtype.itemsize, (msg.point_step, dtype.itemsize)
    return np.frombuffer(msg.data, dtype=dtype)


def field_dtype(msg):
    """A numpy dtype from the message's fields (float32 / uint32 / uint8 only)."""
    kinds = {PointField.FLOAT32: "<f4", PointField.UINT32: "<u4", PointField.UINT8: "u1"}
    return np.dtype({"names": [f.name for f in msg.fields],
                     "formats": [kinds[f.datatype] for f in msg.fields],
                     "offsets": [f.offset for f in msg.fields], "itemsize": msg.point_step})


class HagOutputsTest(RosTestCase):
    STAMP_BASE_S = 700

    @classmethod
    def setUpClass(cls):
        rospy.init_node("hag_outputs_test")
        cls.scene = street_corner()
        cls.pubs = {n: rospy.Publisher("/gf_hag/" + n, PointCloud2, queue_size=5)
                    for n in ("plain", "fields")}

    def send(self, name, rec, topics):
        """Publishes `rec` to /gf_hag/<name> until every topic answered (the lazy outputs
        connect one by one); returns {topic: message}."""
        out = Outputs(topics)
        try:
            self.wait_for(lambda: self.pubs[name].get_num_connections() >= 1,
                          "no subscriber on /gf_hag/" + name)
            for attempt in range(3):
                stamp = self.next_stamp()
                self.pubs[name].publish(make_cloud(rec, stamp))
                try:
                    self.wait_for(lambda: all(out.get(t, stamp) for t in topics),
                                  "outputs " + str(topics), timeout=20.0 if attempt < 2 else None)
                    return {t: out.get(t, stamp) for t in topics}
                except AssertionError:
                    if attempt == 2:
                        raise
        finally:
            out.close()

    def test_labeled_heights_surface_obstacles(self):
        """~labeled carries the heights; ~obstacles keeps the pedestrian, not the kerb, the
        branch, the ground; ~ground_surface lies on the road and the pavement."""
        t = ["/plain_filter/labeled", "/plain_filter/obstacles", "/plain_filter/ground_surface"]
        got = self.send("plain", self.scene, t)
        lab_msg = got[t[0]]
        names = [f.name for f in lab_msg.fields]
        self.assertIn("height_above_ground", names)
        fld = [f for f in lab_msg.fields if f.name == "height_above_ground"][0]
        self.assertEqual(fld.datatype, PointField.FLOAT32)
        lab = records(lab_msg, field_dtype(lab_msg))
        np.testing.assert_array_equal(lab["obj"], self.scene["obj"])  # input order, all records
        h, obj = lab["height_above_ground"], lab["obj"]
        road = obj == GROUND
        self.assertLess(float(np.nanmedian(np.abs(h[road]))), 0.02)
        self.assertGreater(float(np.mean(np.isfinite(h))), 0.99)
        ped = obj == PEDESTRIAN
        top = ped & (self.scene["z"] > PED_H - 0.1)
        np.testing.assert_allclose(h[top], self.scene["z"][top], atol=0.1)
        br = h[obj == BRANCH]
        self.assertTrue(np.all(br > 2.8), "branch heights %s" % br[:5])
        self.assertLess(float(h[obj == DITCH][0]), -0.2, "a point below the surface: negative")

        obs_msg = got[t[1]]
        self.assertEqual([(f.name, f.offset, f.datatype) for f in obs_msg.fields],
                         [(f.name, f.offset, f.datatype) for f in make_cloud(self.scene[:1],
                                                                             rospy.Time()).fields])
        obs = records(obs_msg, REC)
        kinds = np.bincount(obs["obj"], minlength=6)
        rospy.loginfo("~obstacles: %d points by kind %s", obs.shape[0], kinds.tolist())
        self.assertEqual(kinds[BRANCH], 0, "the overhanging branch is an obstacle")
        self.assertEqual(kinds[KERB], 0, "the kerb is an obstacle")
        self.assertEqual(kinds[GROUND] + kinds[PAVEMENT], 0, "ground in ~obstacles")
        # The filter labels the pedestrian's feet ground (up to ~0.45 m in this scene): above
        # 0.5 m it is all non-ground, all in the band.
        ped_band = ped & (self.scene["z"] >= 0.5)
        ped_obs = obs["obj"] == PEDESTRIAN
        rospy.loginfo("pedestrian: %d of %d points above 0.5 m non-ground; ~obstacles from "
                      "%.2f m up", int(np.sum(ped_band & (lab["ground"] == 0))),
                      int(ped_band.sum()), float(np.min(obs["z"][ped_obs])))
        self.assertGreaterEqual(int(np.sum(ped_obs & (obs["z"] >= 0.5))),
                                0.98 * int(ped_band.sum()),
                                "the pedestrian is missing from ~obstacles")
        # Whole records: intensity came along.
        np.testing.assert_array_equal(obs["intensity"], obs["obj"].astype(np.float32) * 10 + 1)

        surf_msg = got[t[2]]
        self.assertEqual([(f.name, f.datatype) for f in surf_msg.fields],
                         [("x", PointField.FLOAT32), ("y", PointField.FLOAT32),
                          ("z", PointField.FLOAT32), ("points", PointField.UINT32),
                          ("confidence", PointField.FLOAT32)])
        self.assertEqual(surf_msg.header.frame_id, "map")
        surf = records(surf_msg, field_dtype(surf_msg))
        self.assertGreater(surf.shape[0], 500)  # 30 m x 30 m at 1 m
        # Away from the pedestrian, whose feet the filter labels ground (that cell is raised).
        away = np.hypot(surf["x"] - PED_XY[0], surf["y"] - PED_XY[1]) > 1.5
        on_road = away & (surf["y"] < KERB_Y - 1.0)
        on_pave = away & (surf["y"] > KERB_Y + 1.0)
        self.assertLess(float(np.max(np.abs(surf["z"][on_road]))), 0.05)
        self.assertLess(float(np.max(np.abs(surf["z"][on_pave] - KERB_H))), 0.05)
        self.assertTrue(np.all((surf["confidence"] > 0) & (surf["confidence"] <= 1)))
        self.assertGreater(int(np.median(surf["points"])), 50)

    def test_hag_field_on_split_outputs(self):
        """~hag_field (YAML): ~ground, ~nonground and ~obstacles carry the field too, matching
        ~labeled."""
        t = ["/fields_filter/ground", "/fields_filter/nonground", "/fields_filter/labeled",
             "/fields_filter/obstacles"]
        got = self.send("fields", self.scene, t)
        lab = records(got[t[2]], field_dtype(got[t[2]]))
        h = lab["height_above_ground"]
        band = (lab["ground"] == 0) & (h >= np.float32(0.2)) & (h <= np.float32(2.5))
        for topic, keep in ((t[0], lab["ground"] == 1), (t[1], lab["ground"] == 0), (t[3], band)):
            msg = got[topic]
            self.assertIn("height_above_ground", [f.name for f in msg.fields], topic)
            rec = records(msg, field_dtype(msg))
            np.testing.assert_array_equal(rec["obj"], lab["obj"][keep], topic)
            np.testing.assert_array_equal(rec["height_above_ground"], h[keep], topic)
        self.assertGreater(int(band.sum()), 0, "no obstacle in the scene")

    def test_reconfigured_band_and_refused_band(self):
        """The band through dynamic_reconfigure: 2.9-3.5 m takes the branch and leaves the
        pedestrian; min >= max is refused (the previous band stays)."""
        client = Client("/fields_filter", timeout=30)
        try:
            client.update_configuration({"obstacle_min_height": 2.9, "obstacle_max_height": 3.5})
            obs_msg = self.send("fields", self.scene, ["/fields_filter/obstacles"])[
                "/fields_filter/obstacles"]
            obs = records(obs_msg, field_dtype(obs_msg))  # REC + height_above_ground
            kinds = np.bincount(obs["obj"], minlength=6)
            self.assertGreater(kinds[BRANCH], 0.9 * int(np.sum(self.scene["obj"] == BRANCH)))
            self.assertEqual(kinds[PEDESTRIAN], 0)
            cfg = client.update_configuration({"obstacle_min_height": 3.0,
                                               "obstacle_max_height": 1.0})
            self.assertEqual((cfg["obstacle_min_height"], cfg["obstacle_max_height"]), (2.9, 3.5),
                             "a band with min >= max was accepted")
        finally:
            client.update_configuration({"obstacle_min_height": 0.2, "obstacle_max_height": 2.5})
            client.close()

    def test_no_ground_nan_inf(self):
        """A cloud of NaN / Inf points only: every height NaN, no obstacle, an empty surface;
        the nodelet goes on with the next cloud."""
        bad = self.scene[:100].copy()
        bad["x"][:50] = np.nan
        bad["z"][50:] = np.inf
        t = ["/plain_filter/labeled", "/plain_filter/obstacles", "/plain_filter/ground_surface"]
        got = self.send("plain", bad, t)
        lab = records(got[t[0]], field_dtype(got[t[0]]))
        self.assertTrue(np.all(np.isnan(lab["height_above_ground"])))
        self.assertEqual(got[t[1]].width, 0)
        self.assertEqual(got[t[2]].width, 0)
        again = self.send("plain", self.scene, t)
        self.assertGreater(again[t[1]].width, 0)


if __name__ == "__main__":
    rostest.rosrun(PKG, "hag_outputs", HagOutputsTest)
