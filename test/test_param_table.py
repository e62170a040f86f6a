"""Parameter tables vs cfg/*.cfg (run by catkin_add_nosetests after the build).

Fails when docs/parameters.md drifts from the .cfg files (fix: scripts/gen_param_table.py), and
checks the generator itself against what catkin generated from the same .cfg files
(devel: ground_filter.cfg.<Name>Config), so a table that looks right but is wrong also fails.
The README's short hand-written table of the parameters users change most names only real
parameters, with their methods and defaults, and links to docs/parameters.md.
(The README/docs structure and links: test_docs.py.)
"""
import glob
import importlib
import os
import re
import subprocess
import sys
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
SCRIPT = os.path.join(ROOT, "scripts", "gen_param_table.py")
DOC = os.path.join(ROOT, "docs", "parameters.md")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import gen_param_table  # noqa: E402

ROW = re.compile(r"^\| `([^`]+)` \| (\w+) \| ([^|]*) \| ([^|]*) \| ([^|]*) \| (.*) \|$")


def run(*args):
    p = subprocess.run([sys.executable, SCRIPT] + list(args), stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, universal_newlines=True)
    return p.returncode, p.stdout


def tables(block):
    """{class name: {param: (type, default, min, max)}} parsed back from the Markdown."""
    out, current = {}, None
    for line in block.splitlines():
        m = re.match(r"^#+ `[^/]+/(\w+)`", line)
        if m:
            current = out.setdefault(m.group(1), {})
            continue
        m = ROW.match(line)
        if m and current is not None:
            current[m.group(1)] = tuple(s.strip() for s in m.group(2, 3, 4, 5))
    return out


class ParamTableTest(unittest.TestCase):

    def test_doc_is_up_to_date(self):
        rc, out = run("--check")
        self.assertEqual(rc, 0, "docs/parameters.md tables drifted from cfg/*.cfg; run "
                         "scripts/gen_param_table.py\n" + out)
        self.assertIn("docs/parameters.md parameter tables are up to date", out)

    def test_check_detects_drift(self):
        with open(DOC) as f:
            text = f.read()
        b = text.index(gen_param_table.BEGIN)
        e = text.index(gen_param_table.END)
        block = re.sub(r"(\| `\w+` \| \w+ \| )([^|]*)( \|)", r"\g<1>12345\3", text[b:e],
                       count=1)
        drifted = text[:b] + block + text[e:]
        self.assertNotEqual(drifted, text, "no generated table row found in docs/parameters.md")
        with tempfile.NamedTemporaryFile("w", suffix=".md", delete=False) as f:
            f.write(drifted)
        try:
            rc, out = run("--check", "--doc", f.name)
            self.assertEqual(rc, 1, out)
            self.assertIn("12345", out)  # the diff shows the stale line
        finally:
            os.remove(f.name)

    def test_every_cfg_parameter_in_table(self):
        block = gen_param_table.generate_block(ROOT)
        parsed = tables(block)
        cfgs = sorted(glob.glob(os.path.join(ROOT, "cfg", "*.cfg")))
        self.assertTrue(cfgs)
        for path in cfgs:
            name = os.path.splitext(os.path.basename(path))[0]
            self.assertIn(name, parsed, "no table for " + path)
            # Independent of the generator: names in gen.add(...) of the .cfg and its helpers
            # and in the GF_PARAM lines of the definition files the .cfg reads.
            sources = [path] + glob.glob(os.path.join(ROOT, "cfg", "*.py"))
            added = set()
            for src in sources:
                with open(src) as f:
                    added |= set(re.findall(r"\.add\(\s*[\"'](\w+)[\"']", f.read()))
            with open(path) as f:
                defs = re.findall(r"\"(\w+\.def)\"", f.read())
            self.assertTrue(defs, path + " names no params/*.def")
            for d in defs:
                with open(os.path.join(ROOT, "include", "ground_filter", "params", d)) as f:
                    added |= set(re.findall(r"^GF_PARAM\(\s*\w+,\s*(\w+),", f.read(), re.M))
            for p in parsed[name]:
                self.assertIn(p, added, "%s: table row %s not in any gen.add" % (name, p))

    def test_def_reader_reads_every_line(self):
        """cfg/ground_filter_common.py's .def reader: every GF_PARAM line or an error (a line it
        skipped would be a C++ parameter missing from the .cfg)."""
        saved = dict(sys.modules)
        sys.modules.update(gen_param_table._stub_modules())
        sys.path.insert(0, os.path.join(ROOT, "cfg"))
        try:
            import ground_filter_common as common
            rows = common.read_def("normal_params.def")
            k = [p for p in rows if p["name"] == "k"][0]
            self.assertEqual((k["type"], k["default"], k["min"], k["max"], k["unit"], k["group"]),
                             ("int", 40, 3, 256, "points", "core"))
            self.assertIn("[points] (paper: 50)", common.cfg_description(k))
            with tempfile.NamedTemporaryFile("w", suffix=".def", delete=False) as f:
                f.write('// comment\nGF_PARAM(int, a, 1, 0, 2, "", core, "", "one")\n'
                        'GF_PARAM(int, b, (1 << 2), 0, 8, "", core, "", "two")\n')
            try:
                with self.assertRaises(ValueError):
                    common.read_def(f.name)
            finally:
                os.remove(f.name)
        finally:
            sys.path.pop(0)
            sys.modules.clear()
            sys.modules.update(saved)

    def test_one_table_per_catkin_group(self):
        """Each row sits under the heading of its dynamic_reconfigure group (gen.add_group)."""
        block = gen_param_table.generate_block(ROOT)
        placed, name, group = {}, None, ""
        for line in block.splitlines():
            m = re.match(r"^#+ `[^/]+/(\w+)`", line)
            if m:
                name, group = m.group(1), ""
                continue
            m = re.match(r"^#+ (.+) \(`(\w+)`\)$", line)
            if m:
                self.assertEqual(m.group(2), name, line)
                group = m.group(1).lower().replace(" ", "_")
                continue
            m = ROW.match(line)
            if m and name:
                placed.setdefault(name, {})[m.group(1)] = group
        self.assertEqual(sorted(placed), ["NormalGroundFilter", "VoxelGroundFilter"])
        for name, rows in placed.items():
            mod = importlib.import_module("ground_filter.cfg.%sConfig" % name)
            generated = {}

            def walk(group, gname):
                for p in group["parameters"]:
                    generated[p["name"]] = gname
                for g in group["groups"]:
                    walk(g, g["name"].lower())

            walk(mod.config_description, "")
            self.assertEqual(rows, generated, name)
            groups = set(generated.values())
            # rqt_reconfigure shows groups, not one long list: every parameter has one.
            self.assertNotIn("", groups, name + ": parameters outside any group")
            for g in ("core", "vegetation", "airborne", "performance", "working_volume"):
                self.assertIn(g, groups, name)

    def test_values_match_catkin_generated_config(self):
        """Type, default, min and max of every row equal catkin's generated <Name>Config."""
        parsed = tables(gen_param_table.generate_block(ROOT))
        for name, rows in parsed.items():
            try:
                mod = importlib.import_module("ground_filter.cfg.%sConfig" % name)
            except ImportError as e:
                self.fail("ground_filter.cfg.%sConfig not importable (build the package and "
                          "source devel/setup.bash): %s" % (name, e))
            generated = {}

            def walk(group):
                for p in group["parameters"]:
                    generated[p["name"]] = p
                for g in group["groups"]:
                    walk(g)

            walk(mod.config_description)
            self.assertEqual(sorted(rows), sorted(generated), name + ": parameter sets differ")
            for pname, (ptype, default, lo, hi) in rows.items():
                g = generated[pname]
                self.assertEqual(ptype, g["type"], "%s.%s type" % (name, pname))
                for cell, key in ((default, "default"), (lo, "min"), (hi, "max")):
                    if key != "default" and ptype not in ("int", "double"):
                        continue
                    want = g[key]
                    if ptype == "bool":
                        self.assertEqual(cell, "true" if want else "false", pname)
                    elif ptype == "str":
                        self.assertEqual(cell, '"%s"' % want, pname)
                    else:
                        self.assertAlmostEqual(float(cell), float(want),
                                               msg="%s.%s %s" % (name, pname, key),
                                               delta=1e-6 * max(1.0, abs(float(want))))


README_ROW = re.compile(r"^\| `(\w+)` \| (both|voxel|normal) \| ([^|]+) \| .+ \|$")


class ReadmeShortTableTest(unittest.TestCase):
    """The README's ten parameters: real names, the right methods, the cfg's defaults."""

    def test_readme_table_matches_cfg(self):
        cfg = {}
        for path in sorted(glob.glob(os.path.join(ROOT, "cfg", "*.cfg"))):
            gen = gen_param_table.load_cfg(path)
            method = {"VoxelGroundFilter": "voxel",
                      "NormalGroundFilter": "normal"}[gen.generated[2]]
            cfg[method] = {p.name: gen_param_table._fmt(p.default, p.type) for p in gen.params}
        self.assertEqual(sorted(cfg), ["normal", "voxel"])
        with open(os.path.join(ROOT, "README.md")) as f:
            text = f.read()
        self.assertIn("(docs/parameters.md)", text, "README.md must link to docs/parameters.md")
        self.assertNotIn(gen_param_table.BEGIN, text, "the generated tables live in "
                         "docs/parameters.md, not in README.md")
        rows = [README_ROW.match(l) for l in text.splitlines()]
        rows = [m for m in rows if m]
        self.assertEqual(len(rows), 10, "README.md: expected the ten parameters users change "
                         "most, found %s" % [m.group(1) for m in rows])
        for m in rows:
            name, where, default = m.group(1), m.group(2), m.group(3).strip()
            methods = ["voxel", "normal"] if where == "both" else [where]
            # "voxel 1, normal 0" gives one default per method; else one for all of them.
            per = dict(re.findall(r"(voxel|normal) (\S+?)(?:,|$)", default)) or \
                {mt: default for mt in methods}
            self.assertEqual(sorted(per), sorted(methods), "README row %s: %s" % (name, default))
            for mt in methods:
                self.assertTrue(name in cfg[mt], "README row %s: no such %s parameter" % (name, mt))
                self.assertEqual(per[mt], cfg[mt][name],
                                 "README row %s: %s default" % (name, mt))
            for other in set(cfg) - set(methods):
                self.assertNotIn(name, cfg[other], "README row %s is a parameter of both "
                                 "methods: say 'both'" % name)


if __name__ == "__main__":
    unittest.main()
