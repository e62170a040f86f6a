"""ground_filter_eval --score-labels (another filter's .gnd labels scored with the eval tool's own
protocol) and scripts/peers/run_peers.sh (peer rows in eval_all.sh's format) with a stand-in
peer driver; the peers themselves are not needed."""
import json
import os
import stat
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
from gf_data import built_tool, data_dir  # noqa: E402

EVAL = (os.environ.get("GF_EVAL") or built_tool()
        or os.path.join(ROOT, ".ws", "devel", "lib", "ground_filter", "ground_filter_eval"))
RUN_PEERS = os.path.join(ROOT, "scripts", "peers", "run_peers.sh")
SCENE = "builtin:lidar:1"

# A stand-in peer: labels every point below z = -1.4 m ground (KITTI .bin only), prints the
# driver interface's RESULT lines; exits 3 when FAIL_PEER is set.
FAKE_DRIVER = r'''#!/usr/bin/python3
import os, struct, sys
import numpy as np
if os.environ.get("FAIL_PEER"):
    sys.exit("fake peer: failing on purpose")
a = sys.argv[1:]
out = a[a.index("--out") + 1]
files = [f for i, f in enumerate(a)
         if not f.startswith("--") and a[i - 1] not in ("--out", "--repeats")]
for f in files:
    z = np.fromfile(f, dtype="<f4").reshape(-1, 4)[:, 2]
    stem = os.path.splitext(os.path.basename(f))[0]
    (z < -1.4).astype(np.uint8).tofile(os.path.join(out, stem + ".gnd"))
    print("RESULT fake %s points=%d median_ms=%.1f" % (stem, z.size, 10 + len(stem)))
'''


def run(cmd, **env):
    e = dict(os.environ)
    e.update(env)
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       universal_newlines=True, env=e, timeout=300)
    return p.returncode, p.stdout, p.stderr


@unittest.skipUnless(os.access(EVAL, os.X_OK), "ground_filter_eval not built: " + EVAL)
class ScoreLabels(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name
        rc, out, err = run([EVAL, "--json", "--write-labels", self.dir, SCENE])
        self.assertEqual(rc, 0, err)
        self.own = json.loads(out)["pooled"]
        self.gnd = os.path.join(self.dir, "builtin_lidar_1.gnd")

    def tearDown(self):
        self.tmp.cleanup()

    def score(self):
        rc, out, err = run([EVAL, "--json", "--score-labels", self.dir, SCENE])
        return rc, (json.loads(out) if rc == 0 else None), err

    def test_same_counts_as_the_filter_run(self):
        rc, d, err = self.score()
        self.assertEqual(rc, 0, err)
        for k in ("tp", "fp", "tn", "fn", "points", "ground", "f1"):
            self.assertEqual(d["pooled"][k], self.own[k], k)
        self.assertEqual(d["method"], "labels:" + self.dir)

    def test_flipped_label_counts(self):
        with open(self.gnd, "rb") as f:
            labels = bytearray(f.read())
        flipped = bytearray(1 - v for v in labels)  # every label the other way round
        with open(self.gnd, "wb") as f:
            f.write(flipped)
        rc, d, err = self.score()
        self.assertEqual(rc, 0, err)
        p = d["pooled"]
        self.assertEqual((p["tp"], p["fn"], p["fp"], p["tn"]),
                         (self.own["fn"], self.own["tp"], self.own["tn"], self.own["fp"]))

    def test_bad_label_files(self):
        with open(self.gnd, "r+b") as f:
            f.truncate(100)
        rc, d, err = self.score()
        self.assertEqual(rc, 1)
        self.assertIn(self.gnd + ": 100 labels for the", err)
        with open(self.gnd, "wb") as f:
            f.write(bytes([0, 1, 2] + [0] * (self.own["points"] - 3)))
        rc, d, err = self.score()
        self.assertEqual(rc, 1)
        self.assertIn("label 2 at point 2", err)
        os.unlink(self.gnd)
        rc, d, err = self.score()
        self.assertEqual(rc, 1)
        self.assertIn(self.gnd + ": cannot open", err)

    def test_not_with_repeat(self):
        rc, out, err = run([EVAL, "--score-labels", self.dir, "--repeat", "3", SCENE])
        self.assertEqual(rc, 2)
        self.assertIn("--score-labels runs no filter", err)


@unittest.skipUnless(os.access(EVAL, os.X_OK), "ground_filter_eval not built: " + EVAL)
class RunPeers(unittest.TestCase):
    def setUp(self):
        data = data_dir(optional=True)
        if data is None or not os.path.isfile(os.path.join(data, "semantickitti", "seq00",
                                                           "000000.label")):
            self.skipTest("no KITTI frames in the data folder: run scripts/get_data.sh")
        self.tmp = tempfile.TemporaryDirectory()
        self.bin = self.tmp.name
        drv = os.path.join(self.bin, "fake_driver")
        with open(drv, "w") as f:
            f.write(FAKE_DRIVER)
        os.chmod(drv, os.stat(drv).st_mode | stat.S_IXUSR)
        k = os.path.join(data, "semantickitti", "seq00")
        self.files = [os.path.join(k, "00000%d.bin" % i) for i in range(3)]

    def tearDown(self):
        self.tmp.cleanup()

    def test_row_is_the_eval_tools_score(self):
        rc, out, err = run(["bash", RUN_PEERS, "kitti"], PEER_BIN=self.bin, GF_EVAL=EVAL)
        self.assertEqual(rc, 0, err)
        row = [l for l in out.splitlines() if l.startswith("| kitti seq00 0-2 | fake |")]
        self.assertEqual(len(row), 1, out)
        cells = [c.strip() for c in row[0].strip("|").split("|")]
        # The same labels scored directly.
        labels = os.path.join(self.bin, "labels")
        os.mkdir(labels)
        subprocess.run([sys.executable, os.path.join(self.bin, "fake_driver"), "--out", labels,
                        "--repeats", "1"] + self.files, check=True, stdout=subprocess.DEVNULL)
        rc, js, err = run([EVAL, "--json", "--score-labels", labels] + self.files)
        self.assertEqual(rc, 0, err)
        p = json.loads(js)["pooled"]
        self.assertEqual(cells[2], "3")
        self.assertEqual(cells[3:6], ["%.2f" % (100 * p[k]) for k in ("precision", "recall", "f1")])
        self.assertEqual(cells[6], "48")  # 3 files x (10 + len("00000N")) ms

    def test_failing_driver(self):
        rc, out, err = run(["bash", RUN_PEERS, "kitti"], PEER_BIN=self.bin, GF_EVAL=EVAL,
                           FAIL_PEER="1")
        self.assertEqual(rc, 1)
        self.assertIn("fake_driver failed on kitti", err)
        self.assertIn("| kitti seq00 0-2 | fake | error:", out)

    def test_no_driver(self):
        rc, out, err = run(["bash", RUN_PEERS, "kitti"], PEER_BIN=os.path.join(self.bin, "none"),
                           GF_EVAL=EVAL)
        self.assertEqual(rc, 1)
        self.assertIn("no <peer>_driver in", err)


if __name__ == "__main__":
    unittest.main()


def _scene(path):
    """A KITTI .bin: a flat road 1.7 m below the sensor, a 2 x 2 m box standing on it (its points 0.6-1.5 m up), NaN
    returns and no-return placeholders at the origin. Returns the kinds of its points in file
    order: 'road', 'box' (0.6 m or more above the road: above both peers' ground bands), 'bad'
    (never given to a peer)."""
    import numpy as np
    rng = np.random.RandomState(7)
    road = np.c_[rng.uniform(-25, 25, (20000, 2)), np.full(20000, -1.7)]
    box = np.c_[rng.uniform(6, 8, 3000), rng.uniform(-1, 1, 3000), rng.uniform(-1.1, -0.2, 3000)]
    bad = np.array([[np.nan, 1, 1], [0, 0, 0], [0, 0, 0], [np.inf, 0, -1.7]])
    xyz = np.r_[road, box, bad]
    kinds = ["road"] * len(road) + ["box"] * len(box) + ["bad"] * len(bad)
    order = rng.permutation(len(xyz))
    np.c_[xyz[order], np.zeros(len(xyz))].astype("<f4").tofile(path)
    return [kinds[i] for i in order]


class PclDrivers(unittest.TestCase):
    """The PCL peers' drivers of scripts/peers (the generic builds: PCL only, no network), built
    as build.sh builds them, on a generated scan: the driver interface and its refusals."""
    DRIVERS = ("pcl_ransac", "pcl_apmf")

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.build = os.path.join(cls.tmp.name, "build")
        src = os.path.join(ROOT, "scripts", "peers")
        for cmd in (["cmake", "-S", src, "-B", cls.build, "-DCMAKE_BUILD_TYPE=Release"],
                    ["cmake", "--build", cls.build, "-j2", "--target"] +
                    [d + "_driver" for d in cls.DRIVERS]):
            p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               universal_newlines=True, timeout=1800)
            if p.returncode != 0:
                raise AssertionError("%s failed:\n%s" % (" ".join(cmd), p.stdout[-3000:]))
        cls.scan = os.path.join(cls.tmp.name, "scene.bin")
        cls.kinds = _scene(cls.scan)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def driver(self, name, *args):
        out = os.path.join(self.tmp.name, name)
        os.makedirs(out, exist_ok=True)
        return out, run([os.path.join(self.build, name + "_driver"), "--out", out] + list(args))

    def test_labels_of_every_point(self):
        for name in self.DRIVERS:
            out, (rc, stdout, err) = self.driver(name, "--repeats", "2", self.scan)
            self.assertEqual(rc, 0, err)
            self.assertIn("PARAMS " + name, stdout)
            result = [l for l in stdout.splitlines() if l.startswith("RESULT ")]
            self.assertEqual(len(result), 1, stdout)
            self.assertIn("RESULT %s scene points=%d " % (name, len(self.kinds)), result[0])
            self.assertIn("repeats=2", result[0])
            with open(os.path.join(out, "scene.gnd"), "rb") as f:
                gnd = f.read()
            self.assertEqual(len(gnd), len(self.kinds), name)
            self.assertTrue(set(gnd) <= {0, 1}, name)
            share = {}
            for kind in ("road", "box", "bad"):
                got = [g for g, k in zip(gnd, self.kinds) if k == kind]
                share[kind] = sum(got) / float(len(got))
            self.assertGreater(share["road"], 0.99, (name, share))
            self.assertLess(share["box"], 0.01, (name, share))
            self.assertEqual(share["bad"], 0.0, (name, share))

    def test_bad_command_lines_are_named(self):
        for name in self.DRIVERS:
            _, (rc, _, err) = self.driver(name, "--set", "nosuch=1", self.scan)
            self.assertEqual(rc, 1)
            self.assertIn("unknown --set nosuch", err)
            _, (rc, _, err) = self.driver(name, "--repeats", "x", self.scan)
            self.assertEqual(rc, 1)
            self.assertIn("--repeats=x: not a number", err)
            _, (rc, _, err) = self.driver(name, self.scan + ".missing")
            self.assertEqual(rc, 1)
            self.assertIn("scene.bin.missing: cannot", err)
        _, (rc, _, err) = self.driver("pcl_apmf", "--set", "slope=steep", self.scan)
        self.assertEqual(rc, 1)
        self.assertIn("slope=steep: not a number", err)
