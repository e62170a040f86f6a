"""scripts/gpu_trace_gaps.py: filter calls found in a synthetic CUPTI trace, the GPU's busy time
and idle gaps of each, the host's runtime calls during a gap, the medians printed."""
import gzip
import os
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "gpu_trace_gaps.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import gpu_trace_gaps  # noqa: E402


def call_lines(t0, corr, points):
    """One filter call of `points` points starting at t0 ns: upload, a kernel, a 55 us wait on
    cudaMemGetInfo, a kernel, the labels' download, the host's sync."""
    return [
        "R %d %d %d cudaSetDevice_v3020" % (t0, t0 + 1000, corr),
        "R %d %d %d cudaMemcpyAsync_v3020" % (t0 + 2000, t0 + 3000, corr + 1),
        "C %d %d %d kind1_%d" % (t0 + 10000, t0 + 20000, corr + 1, 12 * points),
        "K %d %d %d columnKeys" % (t0 + 20500, t0 + 30000, corr + 2),
        "R %d %d %d cudaMemGetInfo_v3020" % (t0 + 30000, t0 + 80000, corr + 3),
        "K %d %d %d knnQuery" % (t0 + 85000, t0 + 90000, corr + 4),
        "C %d %d %d kind2_%d" % (t0 + 90500, t0 + 91000, corr + 5, points),
        "R %d %d %d cudaStreamSynchronize_v3020" % (t0 + 86000, t0 + 92000, corr + 6),
    ]


class GpuTraceGapsTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp()
        self.path = os.path.join(self.dir, "trace.txt.gz")
        lines = call_lines(0, 1, 100) + call_lines(200000, 11, 100) + call_lines(400000, 21, 7)
        lines.append("garbage line")
        with gzip.open(self.path, "wt") as f:
            f.write("\n".join(lines) + "\n")

    def test_calls_and_their_gaps(self):
        recs = gpu_trace_gaps.read_trace(self.path)
        calls = gpu_trace_gaps.filter_calls(recs, 100)
        self.assertEqual(calls, [(0, 92000), (200000, 292000)])  # not the 7-point call
        p = gpu_trace_gaps.call_profile(recs, *calls[1])
        self.assertEqual(p["wall"], 92000)
        self.assertEqual(p["busy"], 10000 + 9500 + 5000 + 500)
        self.assertEqual(p["kernels"], 9500 + 5000)
        self.assertEqual(p["kernel_count"], 2)
        self.assertEqual(p["before_gpu"], 10000)
        self.assertEqual(p["gaps"], 500 + 55000 + 500)
        self.assertEqual(p["gap_count"], 3)
        self.assertEqual(len(p["long_gaps"]), 1)  # the two 0.5 us gaps are under 3 us
        start, length, host = p["long_gaps"][0]
        self.assertEqual((start, length), (30000, 55000))
        self.assertEqual(host["cudaMemGetInfo_v3020"], 1)
        self.assertEqual(p["host_time"]["cudaMemGetInfo_v3020"], 50000)

    def test_command_prints_the_medians(self):
        out = subprocess.run([sys.executable, SCRIPT, self.path, "--points", "100"],
                             stdout=subprocess.PIPE, universal_newlines=True, check=True).stdout
        self.assertIn("filter calls of 100 points: 2", out)
        self.assertIn("cudaMemGetInfo_v3020 x1", out)
        self.assertRegex(out, r"gaps\s+56\.0")
        none = subprocess.run([sys.executable, SCRIPT, self.path, "--points", "99"],
                              stdout=subprocess.PIPE, universal_newlines=True)
        self.assertEqual(none.returncode, 1)


if __name__ == "__main__":
    unittest.main()
