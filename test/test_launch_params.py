"""Every launch argument and every YAML key reaches the nodelet as written (run by
catkin_add_nosetests after the build; needs the devel space, no master).

`roslaunch --dump-params` over each launch file with `params_file:=` a YAML that sets every
private parameter of the nodelet to a value other than its default: each value must come out
unchanged; an argument passed explicitly wins over the YAML; without either the launch file sets
nothing (the nodelet's own default applies). demo.launch: gui:=true streams until rviz is
closed, scans:=N still ends it; rviz runs in the nodelet's namespace with its input remapped, so
it follows name:= and input:= (rviz/ground_filter.rviz names relative topics).
"""
import importlib
import os
import re
import subprocess
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))

# Private parameters of the GroundFilterNodelet base (src/nodelets/param_check.cpp), each with a
# value other than its default.
BASE = {"lazy": False, "queue_size": 7, "gravity_frame": "base_link", "tf_timeout": 0.5,
        "diagnostic_period": 2.5, "malloc_trim_period": 7.0,
        "body_box": [-2.5, 1.5, -1.0, 1.0, -1.8, 0.4]}


def not_default(p):
    """A valid value other than the default of one generated dynamic_reconfigure parameter."""
    t, d, lo, hi = p["type"], p["default"], p["min"], p["max"]
    if t == "bool":
        return not d
    if t == "str":
        return "gpu" if d != "gpu" else "kdtree"
    if t == "int":
        return d + 1 if d + 1 <= hi else d - 1
    v = round((d + hi) / 2.0, 3) if hi > d else round((d + lo) / 2.0, 3)
    return v if v != d else lo


def cfg_values(name):
    mod = importlib.import_module("ground_filter.cfg.%sConfig" % name)
    out = {}

    def walk(group):
        for p in group["parameters"]:
            out[p["name"]] = not_default(p)
        for g in group["groups"]:
            walk(g)

    walk(mod.config_description)
    return out


def to_yaml(values):
    """A flat YAML mapping (bool, int, float, str, list of numbers), no yaml module needed."""
    def one(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return '"%s"' % v
        if isinstance(v, list):
            return "[" + ", ".join(repr(float(x)) for x in v) + "]"
        return repr(v)
    return "".join("%s: %s\n" % (k, one(v)) for k, v in sorted(values.items()))


def dump(launch, *args):
    """The parameters a launch sets: `roslaunch --dump-params` must succeed and name every one;
    the values are read back through roslaunch's own loader (the one --dump-params prints)."""
    p = subprocess.run(["roslaunch", "--dump-params", "ground_filter", launch] + list(args),
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True)
    if p.returncode != 0:
        raise AssertionError("roslaunch --dump-params %s %s failed:\n%s" %
                             (launch, " ".join(args), p.stdout))
    params = {name: param.value for name, param in load_config(launch, list(args)).params.items()}
    for name in params:
        if name != "/run_id" and not re.search(r"^%s:" % re.escape(name), p.stdout, flags=re.M):
            raise AssertionError("%s: %s not in the --dump-params output" % (launch, name))
    return params


def run_nodes(launch, *args):
    """`roslaunch --nodes` of a launch file, whatever its exit status (stdout with stderr)."""
    return subprocess.run(["roslaunch", "--nodes", "ground_filter", launch] + list(args),
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                          universal_newlines=True)


def nodes(launch, *args):
    p = run_nodes(launch, *args)
    assert p.returncode == 0, p.stdout
    return p.stdout.split()


def load_config(launch, argv):
    """A launch file as roslaunch reads it (parameters, nodes, remaps, namespaces)."""
    import roslaunch.config
    import roslaunch.xmlloader
    import rospkg
    path = os.path.join(rospkg.RosPack().get_path("ground_filter"), "launch", launch)
    config = roslaunch.config.ROSLaunchConfig()
    roslaunch.xmlloader.XmlLoader().load(path, config, argv=argv, verbose=False)
    return config


def load(launch, argv):
    return load_config(launch, argv).nodes


# (launch file, extra args, method cfg, nodelet name)
CASES = [("voxel_ground_filter.launch", [], "VoxelGroundFilter", "ground_filter"),
         ("normal_ground_filter.launch", ["name:=gf_n"], "NormalGroundFilter", "gf_n"),
         ("ground_filter.launch", [], "VoxelGroundFilter", "ground_filter"),
         ("ground_filter.launch", ["method:=normal", "name:=front"], "NormalGroundFilter",
          "front"),
         ("play_bag.launch", ["bag:=/tmp/none.bag"], "VoxelGroundFilter", "ground_filter"),
         ("play_bag.launch", ["bag:=/tmp/none.bag", "method:=normal"], "NormalGroundFilter",
          "ground_filter"),
         ("crop_and_filter.launch", [], "VoxelGroundFilter", "ground_filter"),
         ("crop_and_filter.launch", ["method:=normal", "name:=cf"], "NormalGroundFilter", "cf"),
         ("demo.launch", [], "VoxelGroundFilter", "ground_filter"),
         ("demo.launch", ["method:=normal", "name:=gf_demo"], "NormalGroundFilter", "gf_demo")]


class LaunchParamsTest(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="gf_launch_params_")
        cls.yamls = {}
        for cfg in ("VoxelGroundFilter", "NormalGroundFilter"):
            values = dict(BASE)
            values.update(cfg_values(cfg))
            path = os.path.join(cls.tmp, cfg + ".yaml")
            with open(path, "w") as f:
                f.write(to_yaml(values))
            cls.yamls[cfg] = (path, values)

    def test_every_yaml_key_reaches_the_nodelet(self):
        for launch, args, cfg, name in CASES:
            path, values = self.yamls[cfg]
            params = dump(launch, "params_file:=" + path, *args)
            for key, want in values.items():
                got = params.get("/%s/%s" % (name, key), "<missing>")
                self.assertEqual(got, want, "%s %s: /%s/%s" % (launch, " ".join(args), name, key))

    def test_explicit_arguments_win_over_the_yaml(self):
        explicit = {"lazy": True, "queue_size": 2, "gravity_frame": "odom", "tf_timeout": 0.25}
        for launch, args, cfg, name in CASES:
            if launch == "demo.launch":
                continue  # the demo passes no filter arguments
            path, values = self.yamls[cfg]
            params = dump(launch, "params_file:=" + path,
                          *(args + ["%s:=%s" % (k, str(v).lower() if isinstance(v, bool) else v)
                                    for k, v in explicit.items()]))
            for key, want in explicit.items():
                self.assertEqual(params.get("/%s/%s" % (name, key)), want,
                                 "%s %s: /%s/%s" % (launch, " ".join(args), name, key))
            # The rest of the YAML still reaches the nodelet.
            self.assertEqual(params.get("/%s/plane_distance" % name), values["plane_distance"])

    def test_without_yaml_or_argument_the_nodelet_default_applies(self):
        for launch, args, _, name in CASES:
            params = dump(launch, *args)
            for key in BASE:
                self.assertNotIn("/%s/%s" % (name, key), params,
                                 "%s sets %s although nobody asked for it" % (launch, key))

    def test_relaunch_starts_from_defaults_and_its_yaml(self):
        """A second launch under the same master (here: the other method after the first) must
        not inherit the first launch's keys: every filter node clears its private namespace.
        roslaunch applies a launch to the parameter server as in ROSLaunchRunner: first the
        namespaces in clear_params are deleted, then every parameter is set; that is replayed
        here on a dict, no master needed."""
        def apply(server, config):
            for ns in config.clear_params:
                for key in [k for k in server if k.startswith(ns)]:
                    del server[key]
            server.update({k: p.value for k, p in config.params.items()})

        for launch, args, cfg, name in CASES:
            ns = "/%s/" % name
            config = load_config(launch, ["params_file:=" + self.yamls[cfg][0]] + args)
            self.assertIn(ns, config.clear_params,
                          "%s %s: node %s has no clear_params" % (launch, " ".join(args), name))
            # First the other method with every key of its YAML, then this launch without one.
            other = "NormalGroundFilter" if cfg == "VoxelGroundFilter" else "VoxelGroundFilter"
            server = {}
            apply(server, load_config(launch, ["params_file:=" + self.yamls[other][0]] + args))
            second = load_config(launch, list(args))
            apply(server, second)
            left = sorted(k for k in server if k.startswith(ns) and k not in second.params)
            self.assertEqual(left, [], "%s %s: keys of the earlier launch stay on the server"
                             % (launch, " ".join(args)))
        # Every launch file that loads a filter was replayed (none slipped out of CASES).
        launches = {c[0] for c in CASES}
        for f in os.listdir(os.path.join(ROOT, "launch")):
            with open(os.path.join(ROOT, "launch", f)) as fh:
                text = fh.read()
            if "_ground_filter.launch" in text or "ground_filter.launch\"" in text or \
                    "load ground_filter/" in text:
                self.assertIn(f, launches, "%s loads a filter but is not in CASES" % f)
        # The body crop of crop_and_filter.launch too (its box would stay from an earlier launch).
        crop = load_config("crop_and_filter.launch", ["name:=cf"])
        self.assertIn("/cf_body_crop/", crop.clear_params)

    def test_manager_threads_sleep(self):
        # OMP_WAIT_POLICY=passive for every manager a launch file starts (docs/ros_integration.md,
        # "A robot's load"); the argument overrides it.
        for launch, argv in (("ground_filter.launch", []), ("crop_and_filter.launch", []),
                             ("play_bag.launch", ["bag:=/tmp/none.bag"]), ("demo.launch", [])):
            managers = [n for n in load(launch, argv) if n.args.strip() == "manager"]
            self.assertEqual(len(managers), 1, launch)
            self.assertIn(("OMP_WAIT_POLICY", "passive"),
                          [tuple(e) for e in managers[0].env_args], launch)
        for launch in ("ground_filter.launch", "crop_and_filter.launch"):
            manager = [n for n in load(launch, ["omp_wait_policy:=active"])
                       if n.args.strip() == "manager"][0]
            self.assertIn(("OMP_WAIT_POLICY", "active"), [tuple(e) for e in manager.env_args])

    def test_no_bond_where_the_launch_owns_the_manager(self):
        # A launch file that starts the manager loads with --no-bond (docs/ros_integration.md,
        # "bond": nodelet 1.10's Loader aborts when one Ctrl-C breaks the bond during its
        # shutdown); loaded into a manager of someone else's, the bond stays by default.
        def loaders(launch, *argv):
            return [n.args.split() for n in load(launch, list(argv))
                    if n.args.split()[:1] == ["load"]]
        for launch, argv in (("ground_filter.launch", []), ("ground_filter.launch",
                                                            ["method:=normal"]),
                             ("crop_and_filter.launch", []), ("demo.launch", []),
                             ("play_bag.launch", ["bag:=/tmp/none.bag"])):
            found = loaders(launch, *argv)
            self.assertTrue(found, launch)
            for args in found:
                self.assertEqual(args[-1], "--no-bond", (launch, args))
        for launch in ("voxel_ground_filter.launch", "normal_ground_filter.launch"):
            self.assertNotIn("--no-bond", loaders(launch)[0], launch)
            self.assertIn("--no-bond", loaders(launch, "bond:=false")[0], launch)
            self.assertNotIn("--no-bond", loaders(launch, "bond:=true")[0], launch)
            self.assertIn("--no-bond", loaders(launch, "bond:=0")[0], launch)
            # A typo is refused by name, not read as "no bond".
            p = run_nodes(launch, "bond:=treu")
            self.assertIn("bond must be true or false, not 'treu'", p.stdout, launch)
            self.assertNotEqual(p.returncode, 0, launch)
            self.assertNotIn("/ground_filter\n", p.stdout, launch)  # no node listed

    def test_demo_gui_streams_until_closed(self):
        self.assertEqual(dump("demo.launch")["/demo_monitor/max_scans"], 30)
        self.assertEqual(dump("demo.launch", "gui:=true")["/demo_monitor/max_scans"], 0)
        self.assertEqual(dump("demo.launch", "gui:=true", "scans:=5")["/demo_monitor/max_scans"],
                         5)
        self.assertEqual(dump("demo.launch", "scans:=0")["/demo_monitor/max_scans"], 0)

    def test_demo_gui_names_the_fixed_frame_in_tf(self):
        # rviz's Global Status warns while no transform names its fixed frame (the scans' frame):
        # with gui:=true the demo publishes world_frame -> frame_id; not without rviz, not when
        # the two frames are one, not with world_frame:=none.
        def frames(*argv):
            return [n.args.split()[-2:] for n in load("demo.launch", list(argv))
                    if n.type == "static_tf.py"]
        self.assertEqual(frames("gui:=true"), [["map", "velodyne"]])
        self.assertEqual(frames("gui:=true", "frame_id:=os_sensor"), [["map", "os_sensor"]])
        self.assertEqual(frames(), [])
        self.assertEqual(frames("gui:=true", "world_frame:=none"), [])
        self.assertEqual(frames("gui:=true", "frame_id:=map"), [])

    def test_rviz_follows_name_and_input(self):
        with open(os.path.join(ROOT, "rviz", "ground_filter.rviz")) as f:
            topics = re.findall(r"^\s+Topic: (\S+)$", f.read(), flags=re.M)
        # Relative names only: resolved in rviz's namespace (the nodelet's name).
        self.assertEqual(sorted(topics), ["ground", "input", "nonground"])
        listed = nodes("ground_filter.launch", "gui:=true", "name:=front",
                       "input:=/lidar/points")
        rviz = [n for n in listed if "rviz" in n]
        self.assertEqual(len(rviz), 1, listed)
        self.assertTrue(rviz[0].startswith("/front/"), rviz)
        # The remaps, read back the way roslaunch reads them.
        for launch in ("ground_filter.launch", "crop_and_filter.launch"):
            for name, topic in (("front", "/lidar/points"), ("ground_filter", "/points_raw")):
                argv = ["gui:=true", "name:=" + name]
                if name == "front":
                    argv.append("input:=" + topic)
                rviz = [n for n in load(launch, argv) if n.package == "rviz"][0]
                self.assertEqual(rviz.namespace, "/%s/" % name, launch)
                self.assertIn(("input", topic), [tuple(r) for r in rviz.remap_args], launch)
                self.assertTrue(rviz.required, launch)  # closing rviz ends the launch
        demo = load("demo.launch", ["gui:=true", "name:=gf2", "topic:=/sim/points"])
        rviz = [n for n in demo if n.package == "rviz"][0]
        self.assertEqual(rviz.namespace, "/gf2/")
        self.assertIn(("input", "/sim/points"), [tuple(r) for r in rviz.remap_args])
        scenes = [n for n in demo if n.type == "scene_publisher"][0]
        self.assertIn(("~output", "/sim/points"), [tuple(r) for r in scenes.remap_args])
        monitor = [n for n in demo if n.type == "demo_monitor"][0]
        self.assertIn(("~ground", "gf2/ground"), [tuple(r) for r in monitor.remap_args])

if __name__ == "__main__":
    unittest.main()
