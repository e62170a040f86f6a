"""The source layout rules (run by catkin_add_nosetests): includes point one way between the
core's rooms (scripts/check_includes.py), no file over 700 lines and no function over 120
(scripts/check_sizes.py), clang-format's layout (scripts/check_format.sh). The two checkers
also run on a small planted tree, so one that stopped finding anything fails here too."""
import os
import shutil
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
INCLUDES = os.path.join(ROOT, "scripts", "check_includes.py")
SIZES = os.path.join(ROOT, "scripts", "check_sizes.py")
FORMAT = os.path.join(ROOT, "scripts", "check_format.sh")


def run(script, root):
    p = subprocess.run([sys.executable, script, root], stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, universal_newlines=True)
    return p.returncode, p.stdout


def run_planted(script, files):
    """`script` on a temporary tree of `files` ({relative path: text}): (exit status, output)."""
    tmp = tempfile.mkdtemp()
    try:
        for rel, text in files.items():
            path = os.path.join(tmp, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w") as f:
                f.write(text)
        return run(script, tmp)
    finally:
        shutil.rmtree(tmp)


class TestLayout(unittest.TestCase):
    def test_repository_includes_point_one_way(self):
        rc, out = run(INCLUDES, ROOT)
        self.assertEqual(rc, 0, out)
        self.assertIn("0 point the wrong way", out)

    def test_repository_sizes(self):
        rc, out = run(SIZES, ROOT)
        self.assertEqual(rc, 0, out)

    def test_clang_format(self):
        p = subprocess.run(["bash", FORMAT], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           universal_newlines=True)
        if p.returncode == 77:
            self.skipTest(p.stdout.strip())
        self.assertEqual(p.returncode, 0, p.stdout)

    def test_include_checker_finds_planted_cycles(self):
        rc, out = run_planted(INCLUDES, {
            "include/ground_filter/voxel_ground_filter_params.h": "\n",
            "include/ground_filter/voxel_ground_filter.h":
                '#include "ground_filter/voxel_ground_filter_params.h"\n',
            "src/core/common/util.h": '#include "voxel/stage.h"\n',                  # up
            "src/core/voxel/stage.h": '#include "ground_filter/voxel_ground_filter.h"\n',  # class
            "src/core/voxel/other.cpp": '#include "normal/x.h"\n',                   # sideways
            "src/core/normal/x.h": "\n",
            "src/core/knn/tree.cpp": '#include "normal/x.h"\n',                      # up
            "src/core/voxel/voxel_ground_filter.cpp":
                '#include "ground_filter/voxel_ground_filter.h"\n#include "voxel/stage.h"\n',
            "src/core/newroom/a.cpp": "\n",  # no room: top of the core, allowed
        })
        self.assertEqual(rc, 1, out)
        self.assertIn("src/core/common/util.h:1: common includes src/core/voxel/stage.h", out)
        self.assertIn("src/core/voxel/stage.h:1: includes the filter class", out)
        self.assertIn("src/core/voxel/other.cpp:1: voxel includes src/core/normal/x.h", out)
        self.assertIn("src/core/knn/tree.cpp:1: knn includes src/core/normal/x.h", out)
        self.assertNotIn("voxel_ground_filter.cpp", out)  # its own class and its stages
        self.assertIn("4 point the wrong way", out)

    def test_include_checker_keeps_the_core_off_the_cuda_library(self):
        rc, out = run_planted(INCLUDES, {
            "cuda/include/ground_filter/cuda_knn.h": "\n",
            "cuda/src/gpu_search.h": '#include "ground_filter/cuda_knn.h"\n',
            "src/core/knn/knn_backend.h": "\n",
            "src/core/knn/kdtree.h": "\n",
            "src/core/normal/cpu_gpu_common.h": "\n",
            "src/core/knn/factory.cpp": '#include "ground_filter/cuda_knn.h"\n',  # core -> cuda
            "src/core/normal/stage.cpp": '#include "gpu_search.h"\n',             # core -> cuda
            "cuda/src/gpu_search.cpp":  # the interface it implements, shared maths: allowed
                '#include "knn/knn_backend.h"\n#include "normal/cpu_gpu_common.h"\n'
                '#include "knn/kdtree.h"\n',  # another core header: not
        })
        self.assertEqual(rc, 1, out)
        self.assertIn("src/core/knn/factory.cpp:1: knn includes "
                      "cuda/include/ground_filter/cuda_knn.h (cuda_api)", out)
        self.assertIn("src/core/normal/stage.cpp:1: normal includes cuda/src/gpu_search.h", out)
        self.assertIn("cuda/src/gpu_search.cpp:3: cuda includes src/core/knn/kdtree.h", out)
        self.assertIn("3 point the wrong way", out)

    def test_size_checker_finds_planted_long_function_and_file(self):
        body = "".join("  x += %d;\n" % i for i in range(121))
        rc, out = run_planted(SIZES, {
            "src/core/voxel/long.cpp":
                "namespace a {\n\nint longOne(int x,\n            int y) {\n" + body +
                "  return x;\n}\n\nint shortOne() {\n  return 1;\n}\n\n}  // namespace a\n",
            "src/core/voxel/big.h": "// line\n" * 701,
        })
        self.assertEqual(rc, 1, out)
        self.assertIn("src/core/voxel/long.cpp:3: longOne: 122 lines", out)
        self.assertNotIn("shortOne", out)
        self.assertIn("src/core/voxel/big.h: 701 lines", out)
        self.assertIn("2 over the limits", out)

if __name__ == "__main__":
    unittest.main()
