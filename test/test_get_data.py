"""scripts/get_data.sh: a copy of the data folder checked against scripts/data_manifest.tsv, and
bad input (no network, a moved URL, a partial download, a damaged copy, GF_DATA_DIR naming no
folder, a read-only destination): a message naming the file, a non-zero exit, nothing
half-written. The downloads go to file:// and 127.0.0.1 URLs (GF_DATA_BASE_URL, GF_DATA_MANIFEST):
no network needed. The conversions (scripts/data_convert.py) on small made-up inputs."""
import functools
import hashlib
import http.server
import os
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import unittest

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "get_data.sh")
MANIFEST = os.path.join(ROOT, "scripts", "data_manifest.tsv")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import data_convert  # noqa: E402
from gf_data import data_dir  # noqa: E402

RAW = "https://raw.githubusercontent.com/"


def sha256(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def leftovers(folder):
    """Temporary files or folders of get_data.sh under folder."""
    found = []
    for d, dirs, files in os.walk(folder):
        found += [os.path.join(d, n) for n in dirs + files
                  if n.endswith(".part") or n.startswith(".get_data")]
    return found


def run(args, **env):
    e = dict(os.environ)
    e.pop("GF_DATA_DIR", None)
    e.update(env)
    p = subprocess.run(["bash", SCRIPT] + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       universal_newlines=True, env=e, timeout=120)
    return p.returncode, p.stdout, p.stderr


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()  # nothing listens there now
    return port


class RealManifest(unittest.TestCase):
    def test_manifest_rows(self):
        rows = [l.split("\t") for l in open(MANIFEST).read().splitlines()
                if l and not l.startswith("#")]
        self.assertEqual(len(rows), 22)
        for r in rows:
            self.assertEqual(len(r), 6, r)
            self.assertRegex(r[1], "^[0-9a-f]{64}$")
            for url in r[3].split():  # every source pinned at a 40-digit commit
                self.assertRegex(url, r"^https://raw\.githubusercontent\.com/[^/]+/[^/]+/"
                                 r"[0-9a-f]{40}/")
            self.assertEqual(len(r[3].split()), len(r[4].split()))
            if r[2] == "copy":
                self.assertEqual(r[1], r[4], r[0])

    def test_copy_of_the_data_folder(self):
        src = data_dir(optional=True)
        if src is None or not os.path.isdir(os.path.join(src, "semantickitti")):
            self.skipTest("no data folder with semantickitti/ (%s; $GF_DATA_DIR, data/, "
                          "../shared/data): run scripts/get_data.sh" % src)
        with tempfile.TemporaryDirectory() as tmp:
            dest = os.path.join(tmp, "data")
            rc, out, err = run(["--from", src, "--dest", dest])
            self.assertEqual(rc, 0, err)
            n = 0
            for line in open(MANIFEST).read().splitlines():
                if not line or line.startswith("#"):
                    continue
                path, want = line.split("\t")[:2]
                self.assertEqual(sha256(os.path.join(dest, path)), want, path)
                n += 1
            self.assertEqual(n, 22)
            self.assertEqual(leftovers(dest), [])
            rc, out, err = run(["--check", "--dest", dest])
            self.assertEqual(rc, 0, err)
            self.assertIn("all 22 files present", out)


class Synthetic(unittest.TestCase):
    """Two small files behind a made-up manifest."""

    def setUp(self):
        self.tmp = tempfile.mkdtemp()
        self.src = os.path.join(self.tmp, "mirror")  # raw.githubusercontent.com's layout
        self.files = {"a/one.bin": os.urandom(5000), "b/two.bin": os.urandom(300)}
        lines = ["# test manifest"]
        for rel, body in self.files.items():
            url_path = "owner/repo/%s/%s" % ("0" * 40, rel)
            os.makedirs(os.path.dirname(os.path.join(self.src, url_path)), exist_ok=True)
            with open(os.path.join(self.src, url_path), "wb") as f:
                f.write(body)
            h = hashlib.sha256(body).hexdigest()
            lines.append("\t".join([rel, h, "copy", RAW + url_path, h, "test"]))
        self.manifest = os.path.join(self.tmp, "manifest.tsv")
        with open(self.manifest, "w") as f:
            f.write("\n".join(lines) + "\n")
        self.dest = os.path.join(self.tmp, "dest")
        self.env = {"GF_DATA_MANIFEST": self.manifest, "GF_DATA_BASE_URL": "file://" + self.src}

    def tearDown(self):
        for d, dirs, _ in os.walk(self.tmp):
            for n in dirs:
                os.chmod(os.path.join(d, n), 0o755)
        shutil.rmtree(self.tmp)

    def assert_nothing_written(self):
        self.assertEqual(leftovers(self.tmp), [])
        if os.path.isdir(self.dest):
            files = [os.path.join(d, n) for d, _, ns in os.walk(self.dest) for n in ns]
            self.assertEqual(files, [])

    def test_download_then_again(self):
        rc, out, err = run(["--dest", self.dest], **self.env)
        self.assertEqual(rc, 0, err)
        for rel, body in self.files.items():
            with open(os.path.join(self.dest, rel), "rb") as f:
                self.assertEqual(f.read(), body)
        self.assertEqual(leftovers(self.dest), [])
        shutil.rmtree(self.src)  # a second run fetches nothing: the sources are not needed
        os.chmod(self.dest, 0o555)  # nor a writable folder
        rc, out, err = run(["--dest", self.dest], **self.env)
        self.assertEqual(rc, 0, err)
        self.assertIn("all 2 files present", out)
        os.unlink(os.path.join(self.dest, "b", "two.bin"))  # only the missing file is fetched
        os.chmod(self.dest, 0o755)
        rc, out, err = run(["--dest", self.dest], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn("ok       a/one.bin (already there)", out)
        self.assertIn("b/two.bin", err)

    def test_no_network(self):
        env = dict(self.env, GF_DATA_BASE_URL="http://127.0.0.1:%d" % free_port())
        rc, out, err = run(["--dest", self.dest], **env)
        self.assertEqual(rc, 1)
        self.assertIn("no network?", err)
        self.assertIn("a/one.bin", err)
        self.assertIn("not tried: no network", err)  # the second file is not tried
        self.assert_nothing_written()

    def test_moved_url(self):
        server = http.server.HTTPServer(("127.0.0.1", 0),
                                        functools.partial(QuietHandler, directory=self.tmp))
        threading.Thread(target=server.serve_forever, daemon=True).start()
        try:
            # The server's root is one folder above the mirror: every URL is a 404.
            env = dict(self.env, GF_DATA_BASE_URL="http://127.0.0.1:%d/" % server.server_port)
            rc, out, err = run(["--dest", self.dest], **env)
        finally:
            server.shutdown()
            server.server_close()
        self.assertEqual(rc, 1)
        self.assertIn("HTTP 404", err)
        self.assertIn("owner/repo/%s/a/one.bin" % ("0" * 40), err)
        self.assertIn("b/two.bin", err)  # a 404 is not "no network": the next file is tried
        self.assert_nothing_written()

    def test_partial_download(self):
        url_path = os.path.join(self.src, "owner/repo/%s/a/one.bin" % ("0" * 40))
        with open(url_path, "r+b") as f:
            f.truncate(1000)
        rc, out, err = run(["--dest", self.dest], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn("a/one.bin", err)
        self.assertIn("partial download", err)
        self.assertFalse(os.path.exists(os.path.join(self.dest, "a", "one.bin")))
        self.assertTrue(os.path.exists(os.path.join(self.dest, "b", "two.bin")))
        self.assertEqual(leftovers(self.tmp), [])

    def copy_folder(self):
        copy = os.path.join(self.tmp, "copy")
        for rel, body in self.files.items():
            os.makedirs(os.path.dirname(os.path.join(copy, rel)), exist_ok=True)
            with open(os.path.join(copy, rel), "wb") as f:
                f.write(body)
        return copy

    def test_damaged_copy(self):
        copy = self.copy_folder()
        with open(os.path.join(copy, "b", "two.bin"), "r+b") as f:
            f.write(b"X")
        rc, out, err = run(["--from", copy, "--dest", self.dest], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn("b/two.bin: checksum mismatch", err)
        self.assertFalse(os.path.exists(os.path.join(self.dest, "b", "two.bin")))
        self.assertEqual(leftovers(self.tmp), [])
        # --check names it too
        rc, out, err = run(["--check", "--dest", copy], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn("two.bin: checksum mismatch", err)

    def test_copy_missing_file(self):
        copy = self.copy_folder()
        os.unlink(os.path.join(copy, "a", "one.bin"))
        rc, out, err = run(["--from", copy, "--dest", self.dest], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn(os.path.join(copy, "a", "one.bin") + ": not in", err)

    def test_data_dir_nowhere(self):
        nowhere = os.path.join(self.tmp, "nowhere")
        rc, out, err = run([], GF_DATA_DIR=nowhere, **self.env)
        self.assertNotEqual(rc, 0)
        self.assertIn("GF_DATA_DIR=%s is not a folder" % nowhere, err)
        self.assertFalse(os.path.exists(nowhere))

    def test_read_only_destination(self):
        if os.geteuid() == 0:
            dest = "/proc/gf_test_get_data"  # root writes through a chmod; not into /proc
        else:
            dest = os.path.join(self.tmp, "ro")
            os.mkdir(dest)
            os.chmod(dest, 0o555)
        rc, out, err = run(["--from", self.copy_folder(), "--dest", dest], **self.env)
        self.assertEqual(rc, 1)
        self.assertIn("cannot write to %s" % dest, err)
        self.assertIn("--dest", err)


class Conversions(unittest.TestCase):
    def test_lzf(self):
        # literal "abc", then a back reference of 6 bytes at distance 3 (overlapping)
        self.assertEqual(data_convert.lzf_decompress(b"\x02abc\x80\x02", 9), b"abcabcabc")
        with self.assertRaises(data_convert.ConvertError):
            data_convert.lzf_decompress(b"\x02abc\x80\x09", 9)  # reference before the start

    def test_rellis(self):
        pts = np.array([[1, 2, 3, 4], [0, 0, 0, 0], [5, 6, 7, 8], [9, 9, 9, 1], [2, 2, 2, 2]],
                       dtype="<f4")
        cls = np.array([3, 3, 19, 0, 23 | (7 << 16)], dtype="<u4")  # grass, (origin), bush, void,
        with tempfile.TemporaryDirectory() as tmp:  # concrete with an instance id
            pts.tofile(os.path.join(tmp, "s.bin"))
            cls.tofile(os.path.join(tmp, "s.label"))
            out = os.path.join(tmp, "s.pcd")
            data_convert.convert_rellis(os.path.join(tmp, "s.bin"), os.path.join(tmp, "s.label"),
                                        out)
            f = data_convert.read_pcd(out)
            self.assertEqual(list(f["label"]), [1, 0, 255, 1])
            self.assertEqual(list(f["x"]), [1, 5, 9, 2])
            self.assertEqual(list(f["intensity"]), [4, 8, 1, 2])
            with self.assertRaises(data_convert.ConvertError):  # labels of another scan
                cls[:3].tofile(os.path.join(tmp, "s.label"))
                data_convert.convert_rellis(os.path.join(tmp, "s.bin"),
                                            os.path.join(tmp, "s.label"), out)

    def test_isprs(self):
        full = np.array([[512700.875, 5403547.5, 10], [512701.5, 5403548.0, 11],
                         [512702.25, 5403549.5, 12]], dtype="<f4")
        with tempfile.TemporaryDirectory() as tmp:
            def pcd(name, xyz):
                p = os.path.join(tmp, name)
                data_convert.write_pcd(p, [("x", xyz[:, 0]), ("y", xyz[:, 1]), ("z", xyz[:, 2])])
                return p
            out = os.path.join(tmp, "t.pcd")
            data_convert.convert_isprs(pcd("u.pcd", full), pcd("g.pcd", full[[0, 2]]), out)
            f = data_convert.read_pcd(out)
            self.assertEqual(list(f["label"]), [1, 0, 1])
            self.assertEqual(list(f["x"]), [0.875, 1.5, 2.25])  # minus the metre below the minimum
            self.assertEqual(list(f["y"]), [0.5, 1.0, 2.5])
            self.assertEqual(list(f["z"]), [10, 11, 12])
            self.assertEqual(struct.unpack("<I", open(out, "rb").read()[-4:])[0], 1)


if __name__ == "__main__":
    unittest.main()
