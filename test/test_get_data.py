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

    def plain_las(self, path, fmt, xyz_int, cls, version=(1, 2)):
        """A made-up uncompressed LAS file: scale 0.01, offset (1000, 2000, 0)."""
        rec = 20 if fmt < 6 else 30
        hdr = bytearray(227)
        hdr[0:4] = b"LASF"
        hdr[24], hdr[25] = version
        struct.pack_into("<H", hdr, 94, 227)
        struct.pack_into("<I", hdr, 96, 227)
        hdr[104] = fmt
        struct.pack_into("<H", hdr, 105, rec)
        struct.pack_into("<I", hdr, 107, len(cls))
        struct.pack_into("<3d", hdr, 131, 0.01, 0.01, 0.01)
        struct.pack_into("<3d", hdr, 155, 1000.0, 2000.0, 0.0)
        body = bytearray()
        for (x, y, z), c in zip(xyz_int, cls):
            r = bytearray(rec)
            struct.pack_into("<3iH", r, 0, x, y, z, 7)
            if fmt < 6:
                r[15] = c | 0x40  # a synthetic flag in the upper bits: not part of the class
            else:
                r[16] = c
            body += r
        with open(path, "wb") as f:
            f.write(bytes(hdr) + bytes(body))

    def test_plain_las(self):
        pts = [(150, 250, 1234), (-50, 0, 99), (1, 2, 3)]
        with tempfile.TemporaryDirectory() as tmp:
            for fmt in (1, 3, 6):
                src = os.path.join(tmp, "t%d.las" % fmt)
                self.plain_las(src, fmt, pts, [2, 6, 31])
                out = os.path.join(tmp, "t%d.pcd" % fmt)
                data_convert.convert_las(src, out, (1000.0, 2000.0), [31])
                f = data_convert.read_pcd(out)
                self.assertEqual(list(f["label"]), [1, 0, 255], fmt)
                np.testing.assert_allclose(f["x"], [1.5, -0.5, 0.01], atol=1e-6)
                np.testing.assert_allclose(f["y"], [2.5, 0.0, 0.02], atol=1e-6)
                np.testing.assert_allclose(f["z"], [12.34, 0.99, 0.03], atol=1e-5)
                self.assertEqual(list(f["intensity"]), [7, 7, 7])
            # LAZ (compressed-points bit set) is left to laspy / PDAL; a truncated file is refused.
            laz = os.path.join(tmp, "t.laz")
            self.plain_las(laz, 3 | 0x80, pts, [2, 2, 2])
            self.assertIsNone(data_convert.read_plain_las(laz))
            short = os.path.join(tmp, "short.las")
            self.plain_las(short, 1, pts, [2, 2, 2])
            with open(short, "r+b") as f:
                f.truncate(227 + 30)
            with self.assertRaises(data_convert.ConvertError):
                data_convert.read_plain_las(short)


class HeldOutManifest(unittest.TestCase):
    HELD = os.path.join(ROOT, "scripts", "heldout_manifest.tsv")

    def rows(self, path):
        return [l.split("\t") for l in open(path).read().splitlines()
                if l and not l.startswith("#")]

    def test_rows(self):
        rows = self.rows(self.HELD)
        self.assertEqual(len(rows), 16)
        dev = {r[0] for r in self.rows(MANIFEST)}
        for r in rows:
            self.assertEqual(len(r), 6, r)
            self.assertRegex(r[1], "^[0-9a-f]{64}$")
            self.assertNotIn(r[0], dev)  # never a dev file
            for url in r[3].split():
                self.assertRegex(url, r"^https://raw\.githubusercontent\.com/[^/]+/[^/]+/"
                                 r"[0-9a-f]{40}/")
        # The dev ISPRS tiles and the held-out ones are disjoint samples of one test.
        isprs = {os.path.basename(r[0]) for r in rows if r[0].startswith("isprs/")}
        self.assertEqual(len(isprs), 7)
        self.assertFalse(isprs & {os.path.basename(p) for p in dev if p.startswith("isprs/")})

    def test_list_names_the_held_out_files(self):
        rc, out, err = run(["--held-out", "--list"])
        self.assertEqual(rc, 0, err)
        self.assertIn("isprs/samp42.pcd", out)
        self.assertIn("airborne_pdal/sample_c.pcd", out)
        self.assertNotIn("seq00", out)

    def test_list_into_a_closed_pipe(self):
        # `--list | head -1` once head has gone: a quiet exit (no BrokenPipeError trace). `true`
        # reads nothing and exits at once, before python has started.
        p = subprocess.run(["bash", "-c", "bash '%s' --held-out --list | true; "
                            "exit ${PIPESTATUS[0]}" % SCRIPT], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, universal_newlines=True, timeout=60)
        self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(p.stderr, "")

    def test_held_out_goes_below_the_data_folder(self):
        with tempfile.TemporaryDirectory() as tmp:
            rc, out, err = run(["--held-out", "--check"], GF_DATA_DIR=tmp)
            self.assertNotEqual(rc, 0)
            self.assertIn(os.path.join(tmp, "heldout"), out + err)


if __name__ == "__main__":
    unittest.main()
