#!/usr/bin/env python3
"""Generates the dynamic_reconfigure parameter tables of docs/parameters.md from cfg/*.cfg.

The .cfg files take their parameters from include/ground_filter/params/*.def (one GF_PARAM line
per parameter, also included by the C++ params structs), so a parameter is edited there.

Each .cfg is executed with a stand-in for dynamic_reconfigure's ParameterGenerator that records
the gen.add()/gen.enum() calls (so shared helpers such as cfg/ground_filter_common.py are
followed exactly as catkin follows them), and one Markdown table per group of each nodelet
(gen.add_group) is written between
the markers `<!-- params:begin -->` and `<!-- params:end -->` in docs/parameters.md (the text
around the markers is hand-written; the README keeps a short hand-written table and links there).

  scripts/gen_param_table.py            rewrite the block of docs/parameters.md in place
  scripts/gen_param_table.py --check    exit 1 (and show a diff) when docs/parameters.md is stale
  scripts/gen_param_table.py --print    print the generated block only
  scripts/gen_param_table.py --doc F    another Markdown file with the markers (tests)
"""
import argparse
import difflib
import glob
import os
import runpy
import sys
import types

BEGIN = "<!-- params:begin -->"
END = "<!-- params:end -->"
ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
DOC = os.path.join("docs", "parameters.md")


class _Param(object):
    def __init__(self, name, ptype, level, description, default, minimum, maximum, edit_method,
                 group=""):
        self.name = name
        self.group = group
        self.type = ptype
        self.level = level
        self.description = description
        self.default = default
        self.min = minimum
        self.max = maximum
        self.edit_method = edit_method


class _Group(object):
    def __init__(self, gen, name=""):
        self._gen = gen
        self.name = name

    def add(self, name, paramtype, level, description, default=None, min=None, max=None,
            edit_method=""):
        self._gen.params.append(_Param(name, paramtype, level, description, default, min, max,
                                       edit_method, self.name))

    def add_group(self, name, type="", state=True):
        if name not in self._gen.groups:
            self._gen.groups.append(name)
        return _Group(self._gen, name)


class _RecordingGenerator(_Group):
    """Stand-in for dynamic_reconfigure's ParameterGenerator: records, generates nothing."""

    instances = []

    def __init__(self):
        _Group.__init__(self, self)
        self.params = []
        self.groups = []  # group names in add_group() order
        self.generated = None  # (package, node, name) from generate()
        _RecordingGenerator.instances.append(self)

    def const(self, name, type, value, descr):
        return {"name": name, "type": type, "value": value, "description": descr}

    def enum(self, constants, description):
        return {"constants": constants, "description": description}

    def generate(self, pkgname, nodename, name):
        self.generated = (pkgname, nodename, name)
        return 0


def _stub_modules():
    """sys.modules entries that make `from dynamic_reconfigure.parameter_generator_catkin
    import ...` resolve to the recording generator."""
    pg = types.ModuleType("dynamic_reconfigure.parameter_generator_catkin")
    pg.ParameterGenerator = _RecordingGenerator
    pg.int_t, pg.double_t, pg.str_t, pg.bool_t = "int", "double", "str", "bool"
    pkg = types.ModuleType("dynamic_reconfigure")
    pkg.__path__ = []
    pkg.parameter_generator_catkin = pg
    return {"dynamic_reconfigure": pkg, "dynamic_reconfigure.parameter_generator_catkin": pg}


def load_cfg(path):
    """Runs one .cfg with the stand-in generator; returns (generator, class name)."""
    saved = {k: sys.modules.get(k) for k in _stub_modules()}
    saved_path = list(sys.path)
    saved_argv = list(sys.argv)
    cfg_modules = set()
    _RecordingGenerator.instances = []
    try:
        sys.modules.update(_stub_modules())
        before = set(sys.modules)
        sys.argv = [path]
        try:
            runpy.run_path(path, run_name="__main__")
        except SystemExit as e:
            if e.code not in (0, None):
                raise RuntimeError("%s exited with %r" % (path, e.code))
        cfg_modules = set(sys.modules) - before  # e.g. ground_filter_common, bound to the stub
    finally:
        for k, v in saved.items():
            if v is None:
                sys.modules.pop(k, None)
            else:
                sys.modules[k] = v
        for k in cfg_modules:
            sys.modules.pop(k, None)
        sys.path[:] = saved_path
        sys.argv = saved_argv
    gens = [g for g in _RecordingGenerator.instances if g.generated]
    if len(gens) != 1:
        raise RuntimeError("%s: expected one gen.generate() call, saw %d" % (path, len(gens)))
    return gens[0]


def _fmt(value, ptype):
    if value is None:
        return ""
    if ptype == "bool":
        return "true" if value else "false"
    if ptype == "double":
        return "%g" % value
    if ptype == "str":
        return '"%s"' % value
    return str(value)


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ").strip()


def table_for(gen, cfg_rel):
    """One Markdown table per group of the .cfg (top-level parameters first, untitled)."""
    package, _, name = gen.generated
    lines = ["## `%s/%s`" % (package, name), "",
             "From `%s` (dynamic_reconfigure; also settable as private parameters at start). "
             "One table per group, as rqt_reconfigure shows them." % cfg_rel]
    for group in [""] + gen.groups:
        params = [p for p in gen.params if p.group == group]
        if not params:
            continue
        if group:
            lines += ["", "### %s (`%s`)" % (group.replace("_", " ").capitalize(), name)]
        lines += ["", "| Parameter | Type | Default | Min | Max | Description |",
                  "|---|---|---|---|---|---|"]
        lines += _rows(params)
    return "\n".join(lines)


def _rows(params):
    lines = []
    for p in params:
        desc = p.description
        if isinstance(p.edit_method, dict) and p.edit_method.get("constants"):
            choices = ", ".join("`%s` (%s)" % (_fmt(c["value"], p.type), c["description"])
                                for c in p.edit_method["constants"])
            desc = "%s; one of: %s" % (desc, choices)
        lines.append("| `%s` | %s | %s | %s | %s | %s |" % (
            p.name, p.type, _cell(_fmt(p.default, p.type)),
            _cell(_fmt(p.min, p.type)) if p.type in ("int", "double") else "",
            _cell(_fmt(p.max, p.type)) if p.type in ("int", "double") else "", _cell(desc)))
    return lines


def generate_block(root=ROOT):
    cfgs = sorted(glob.glob(os.path.join(root, "cfg", "*.cfg")))
    if not cfgs:
        raise RuntimeError("no cfg/*.cfg under %s" % root)
    parts = ["<!-- Generated by scripts/gen_param_table.py from cfg/*.cfg, which read "
             "include/ground_filter/params/*.def: edit a parameter there and rerun it (a test "
             "fails when this block is out of date). -->"]
    for path in cfgs:
        parts.append(table_for(load_cfg(path), os.path.relpath(path, root)))
    return "\n\n".join(parts)


def replace_block(doc_text, block, name=DOC):
    b = doc_text.find(BEGIN)
    e = doc_text.find(END)
    if b < 0 or e < 0 or e < b:
        raise RuntimeError("%s has no %s ... %s block: add the two marker lines where the "
                           "tables go" % (name, BEGIN, END))
    return doc_text[:b + len(BEGIN)] + "\n" + block + "\n" + doc_text[e:]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true",
                      help="exit 1 when the block in docs/parameters.md differs from the .cfg "
                      "files")
    mode.add_argument("--print", action="store_true", help="print the block, change nothing")
    ap.add_argument("--root", default=ROOT, help="package root holding cfg/ (default: this repo)")
    ap.add_argument("--doc", "--readme", dest="doc", default=None,
                    help="Markdown file to update/check (default ROOT/%s)" % DOC)
    a = ap.parse_args(argv)
    doc = a.doc or os.path.join(a.root, DOC)
    try:
        block = generate_block(a.root)
        if a.print:
            print(block)
            return 0
        with open(doc) as f:
            old = f.read()
        new = replace_block(old, block, doc)
    except (RuntimeError, OSError) as e:
        print("gen_param_table.py: error: %s" % e, file=sys.stderr)
        return 1
    if a.check:
        if new != old:
            sys.stdout.writelines(difflib.unified_diff(
                old.splitlines(True), new.splitlines(True), doc, doc + " (from cfg/*.cfg)"))
            print("gen_param_table.py: %s is out of date; run scripts/gen_param_table.py" % doc,
                  file=sys.stderr)
            return 1
        print("%s parameter tables are up to date" % doc)
        return 0
    if new != old:
        tmp = doc + ".tmp"
        try:  # a whole file or none: write beside it, then rename over it
            with open(tmp, "w") as f:
                f.write(new)
            os.replace(tmp, doc)
        except OSError as e:
            if os.path.exists(tmp):
                os.remove(tmp)
            print("gen_param_table.py: error: cannot write %s: %s" % (doc, e), file=sys.stderr)
            return 1
        print("updated %s" % doc)
    else:
        print("%s already up to date" % doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
