"""package.xml against what the package uses (a simple text scan, run by catkin_add_nosetests).

Used by the shipped build or code (CMakeLists.txt outside the tests, src/, include/): a
build_depend or depend. Used at run time (launch files, installed Python tools, libraries
linked): an exec_depend or depend. Used by the tests (test/, test-only CMake, commands the tests
run): declared in any role. And every declared dependency must be used somewhere."""
import importlib.util
import os
import re
import sysconfig
import unittest
import xml.etree.ElementTree as ET

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))

# find_package / include / import names whose rosdep key differs from the name.
KEYS = {"Eigen3": "eigen", "Eigen": "eigen", "PCL": "libpcl-all-dev", "pcl": "libpcl-all-dev",
        "ros": "roscpp", "numpy": "python3-numpy", "rospkg": "python3-rospkg",
        "nanoflann": "nanoflann", "boost": "boost", "gtest": "gtest", "GTest": "gtest",
        "yaml": "python3-yaml"}
# Provided by the compiler / toolkit / C library, or this package itself: no rosdep key.
NO_KEY = {"OpenMP", "Threads", "CUDAToolkit", "cub", "sys", "ground_filter", "catkin"}
# Commands the tests and tools run, and the package that provides each.
COMMANDS = {"xvfb-run": "xvfb", "import": "imagemagick", "convert": "imagemagick",
            "identify": "imagemagick", "roslaunch": "roslaunch", "rosrun": "rosbash"}
# Declared for tools catkin or CMake use implicitly: catkin_add_gtest, catkin_add_nosetests,
# rostest's runner, roslaunch_add_file_check.
IMPLICIT = {"gtest": "catkin_add_gtest", "rosunit": "catkin_add_gtest",
            "python3-nose": "catkin_add_nosetests"}
# Optional test references found by CMake only when installed, deliberately not in package.xml:
# nanoflann's rosdep key is null on focal (test/test_rosdep_keys.py); laspy: the optional LAZ
# reader of scripts/data_convert.py (no Debian package; the script names it when missing).
OPTIONAL_UNDECLARED = {"nanoflann", "laspy"}
INSTALLED_TOOLS = ("scripts/make_bag.py",)
# Maintainer tools run by hand, neither installed nor run by the tests (their imports are theirs).
MAINTAINER_TOOLS = ("scripts/gen_rosdep_keys.py",)
# Nodelet plugin namespaces loaded in launch files (`load NS/Class manager`) -> their package.
NODELET_PLUGIN_PACKAGES = {"pcl": "pcl_ros", "ground_filter": "ground_filter"}  # catkin_install_python in CMakeLists.txt
THIS = "test/test_package_deps.py"
STDLIB = os.path.realpath(sysconfig.get_paths()["stdlib"])


def read(rel):
    with open(os.path.join(ROOT, rel), encoding="utf-8") as f:
        return f.read()


def files(folder, exts):
    out = []
    for dirpath, _, names in os.walk(os.path.join(ROOT, folder)):
        out += [os.path.relpath(os.path.join(dirpath, n), ROOT) for n in sorted(names)
                if n.endswith(exts)]
    return out


def key(name):
    return None if name in NO_KEY else KEYS.get(name, name)


def cpp_includes(rel):
    """Top-level folder of each #include; quoted includes found next to the file or in the
    package's own include directories (include/, src/core/, src/ for eval/) are the package's
    own."""
    here = os.path.dirname(os.path.join(ROOT, rel))
    names = set()
    for quote, path in re.findall(r'#include\s*([<"])([A-Za-z0-9_]+/[^">]*)[">]', read(rel)):
        own_dirs = (here, os.path.join(ROOT, "src", "core"), os.path.join(ROOT, "src"),
                    os.path.join(ROOT, "include"))
        if quote == '"' and any(os.path.exists(os.path.join(d, path)) for d in own_dirs):
            continue
        names.add(path.split("/", 1)[0])
    return names


def is_stdlib(module):
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return False
    if spec is None:
        return False
    origin = spec.origin or ""
    return origin in ("built-in", "frozen") or (
        os.path.realpath(origin).startswith(STDLIB + os.sep) and "-packages" not in origin)


def py_imports(rel):
    local = {os.path.splitext(n)[0] for d in ("scripts", "cfg")  # the package's own modules
             for n in os.listdir(os.path.join(ROOT, d))}
    names = set(re.findall(r"^\s*(?:import|from)\s+([A-Za-z0-9_]+)", read(rel), re.M))
    return {n for n in names if n not in local and not is_stdlib(n)}


def commands(rel):
    """Commands run as a quoted argv word ("import") or at the start of a shell snippet."""
    text = read(rel)
    return {c for c in COMMANDS
            if re.search(r'(?:["\']|; |\$\()%s["\'\s]' % re.escape(c), text)}


def cmake_parts():
    """(package names the shipped build finds, names only the test block finds)."""
    text = re.sub(r"#[^\n]*", "", read("CMakeLists.txt"))
    start = text.index("if(CATKIN_ENABLE_TESTING)")
    main, tests = text[:start], text[start:]

    def found(part):
        names = set()
        for args in re.findall(r"find_package\(([^)]*)\)", part):
            words = args.split()
            names.add(words[0])
            if words[0] == "catkin" and "COMPONENTS" in words:
                names |= set(words[words.index("COMPONENTS") + 1:])
        return {w for w in names if w not in ("REQUIRED", "QUIET", "COMPONENTS")}

    main_found = found(main)
    # PCL's COMPONENTS are PCL modules, not packages.
    main_found -= {"common", "io", "kdtree"}
    return main_found, found(tests)


def launch_packages(rel):
    text = read(rel)
    plugins = {NODELET_PLUGIN_PACKAGES.get(ns, ns)
               for ns in re.findall(r'args="[^"]*\bload\s+([A-Za-z0-9_]+)/', text)}
    return (set(re.findall(r'pkg="([^"$]+)"', text)) | set(re.findall(r"\$\(find ([^)]+)\)", text))
            | plugins)


class PackageDepsTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        root = ET.parse(os.path.join(ROOT, "package.xml")).getroot()
        cls.declared = {}
        for el in root:
            if el.tag.endswith("depend"):
                cls.declared.setdefault(el.text.strip(), set()).add(el.tag)
        build_cmake, test_cmake = cmake_parts()
        cls.used_build, cls.used_run, cls.used_test = {}, {}, {}

        def note(table, name, where):
            k = key(name)
            if k and k != "ground_filter":
                table.setdefault(k, set()).add(where)

        for n in build_cmake:
            note(cls.used_build, n, "CMakeLists.txt find_package")
            note(cls.used_run, n, "CMakeLists.txt find_package (linked)")
        for n in test_cmake:
            note(cls.used_test, n, "CMakeLists.txt test find_package")
        for rel in files("src", (".cpp", ".h")) + files("include", (".h",)):
            for n in cpp_includes(rel):
                note(cls.used_build, n, rel)
        for rel in files("test", (".cpp", ".h")):
            for n in cpp_includes(rel):
                note(cls.used_test, n, rel)
        for rel in files("launch", (".launch",)):
            for n in launch_packages(rel):
                note(cls.used_run, n, rel)
        for rel in files("test", (".test",)):
            for n in launch_packages(rel):
                note(cls.used_test, n, rel)
        for rel in files("scripts", (".py",)) + files("test", (".py",)):
            if rel == THIS or rel in MAINTAINER_TOOLS:
                continue
            table = cls.used_run if rel in INSTALLED_TOOLS else cls.used_test
            for n in py_imports(rel):
                note(table, n, rel)
            for c in commands(rel):
                note(table, COMMANDS[c], rel + " runs " + c)

    def missing(self, used, roles):
        out = []
        for k, where in sorted(used.items()):
            if k in OPTIONAL_UNDECLARED and k not in self.declared:
                continue
            if not self.declared.get(k, set()) & roles:
                out.append("%s (used by %s)" % (k, ", ".join(sorted(where))))
        return out

    def test_scan_found_the_usual_suspects(self):
        # The scan itself works: names we know are used must be seen.
        for k in ("roscpp", "eigen", "libpcl-all-dev", "boost"):
            self.assertIn(k, self.used_build)
        for k in ("nodelet", "rviz", "rosbag", "pcl_ros", "python3-numpy"):
            self.assertIn(k, self.used_run)
        for k in ("rostest", "nanoflann", "xvfb", "imagemagick", "rospy", "std_srvs"):
            self.assertIn(k, self.used_test)

    def test_build_dependencies_declared(self):
        self.assertEqual(self.missing(self.used_build, {"depend", "build_depend"}), [],
                         "used by the build but no <depend>/<build_depend>")

    def test_run_dependencies_declared(self):
        self.assertEqual(self.missing(self.used_run, {"depend", "exec_depend"}), [],
                         "used at run time but no <depend>/<exec_depend>")

    def test_test_dependencies_declared(self):
        any_role = {"depend", "build_depend", "exec_depend", "test_depend"}
        self.assertEqual(self.missing(self.used_test, any_role), [],
                         "used by the tests but not in package.xml")

    def test_nanoflann_optional_and_undeclared(self):
        # Found by the test CMake when present (the kd-tree comparison), never by the build.
        self.assertIn("nanoflann", self.used_test)
        self.assertNotIn("nanoflann", self.used_build)
        self.assertNotIn("nanoflann", self.declared)

    def test_run_time_only_dependencies(self):
        # pcl_ros (CropBox nodelet in launch/crop_and_filter.launch) and rosbag (play_bag.launch,
        # make_bag.py) are used at run time only: exec_depend, not linked or found by CMake.
        for k in ("pcl_ros", "rosbag"):
            self.assertEqual(self.declared.get(k), {"exec_depend"}, k)
            self.assertIn(k, self.used_run, k)
            self.assertNotIn(k, self.used_build, k)
        self.assertIn("launch/crop_and_filter.launch", self.used_run["pcl_ros"])

    def test_every_declared_dependency_is_used(self):
        used = set(self.used_build) | set(self.used_run) | set(self.used_test) | set(IMPLICIT) | {"catkin"}
        self.assertEqual(sorted(set(self.declared) - used), [],
                         "declared in package.xml but not used anywhere")


if __name__ == "__main__":
    unittest.main()
