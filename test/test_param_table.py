"""README parameter tables vs cfg/*.cfg (run by catkin_add_nosetests after the build).

Fails when README.md drifts from the .cfg files (fix: scripts/gen_param_table.py), and checks
the generator itself against what catkin generated from the same .cfg files
(devel: ground_filter.cfg.<Name>Config), so a table that looks right but is wrong also fails.
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

    def test_readme_is_up_to_date(self):
        rc, out = run("--check")
        self.assertEqual(rc, 0, "README.md parameter tables drifted from cfg/*.cfg; run "
                         "scripts/gen_param_table.py\n" + out)

    def test_check_detects_drift(self):
        with open(os.path.join(ROOT, "README.md")) as f:
            text = f.read()
        b = text.index(gen_param_table.BEGIN)
        e = text.index(gen_param_table.END)
        block = re.sub(r"(\| `\w+` \| \w+ \| )([^|]*)( \|)", r"\g<1>12345\3", text[b:e],
                       count=1)
        drifted = text[:b] + block + text[e:]
        self.assertNotEqual(drifted, text, "no generated table row found in README.md")
        with tempfile.NamedTemporaryFile("w", suffix=".md", delete=False) as f:
            f.write(drifted)
        try:
            rc, out = run("--check", "--readme", f.name)
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
            # Independent of the generator: names in gen.add(...) of the .cfg and its helpers.
            sources = [path] + glob.glob(os.path.join(ROOT, "cfg", "*.py"))
            added = set()
            for src in sources:
                with open(src) as f:
                    added |= set(re.findall(r"\.add\(\s*[\"'](\w+)[\"']", f.read()))
            for p in parsed[name]:
                self.assertIn(p, added, "%s: table row %s not in any gen.add" % (name, p))

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


if __name__ == "__main__":
    unittest.main()
