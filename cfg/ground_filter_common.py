"""Parameters shared by every ground_filter nodelet's .cfg file.

Each .cfg imports this module: add_def_parameters() adds a method's parameters from its
definition files (include/ground_filter/params/*.def, the one place a parameter's name, type,
default, range, unit, group, paper value and description are written; the C++ params structs
and their tables include the same files), add_common_parameters() the working volume of every
nodelet.
"""
import ast
import os
import re

from dynamic_reconfigure.parameter_generator_catkin import bool_t, double_t, int_t, str_t

PARAMS_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.realpath(__file__))),
                          "include", "ground_filter", "params")
_TYPES = {"double": double_t, "int": int_t, "bool": bool_t, "string": str_t}
_FIELDS = ("type", "name", "default", "min", "max", "unit", "group", "paper", "description")


# ---- height above ground (issue 42): the band of ~obstacles (src/nodelets/hag_outputs.h).
# Nodelet-only parameters (no filter table row: test_param_tables' kNodeletOnly); the private
# start parameters hag_field, hag_cell, hag_radius are in src/nodelets/hag_outputs.cpp
# (hagParamChecks(), HagOutputs::init()).
def add_height_above_ground_parameters(gen):
    """Adds the obstacle band of ~obstacles (group "height_above_ground"); min < max is checked
    by the nodelet (a set with min >= max is refused)."""
    hag = gen.add_group("height_above_ground", type="")
    hag.add("obstacle_min_height", double_t, 0,
            "~obstacles: non-ground points at least this high above the ground surface; below "
            "obstacle_max_height [m]", 0.2, -10.0, 100.0)
    hag.add("obstacle_max_height", double_t, 0,
            "~obstacles: non-ground points at most this high above the ground surface (an "
            "overhang above it is left out) [m]", 2.5, -10.0, 1000.0)
# ---- end height above ground


def _value(node):
    """A .def argument: a bare word (type, name, group, true/false) or a literal."""
    if isinstance(node, ast.Name):
        return {"true": True, "false": False}.get(node.id, node.id)
    return ast.literal_eval(node)


def read_def(name):
    """The GF_PARAM lines of include/ground_filter/params/<name> as dicts (keys: _FIELDS), in
    file order. The format is a C preprocessor one; `//` comment lines are skipped and each
    GF_PARAM(...) call is read as a Python call expression (adjacent string literals join as in
    C)."""
    with open(os.path.join(PARAMS_DIR, name)) as f:
        text = "\n".join(l for l in f.read().splitlines() if not l.lstrip().startswith("//"))
    params = []
    for call in re.findall(r"^GF_PARAM\((?:[^()\"]|\"(?:[^\"\\]|\\.)*\")*\)", text, re.M):
        node = ast.parse(call, mode="eval").body
        args = [_value(a) for a in node.args]
        if len(args) != len(_FIELDS):
            raise ValueError("%s: %d arguments, want %d: %s" % (name, len(args), len(_FIELDS),
                                                                call))
        p = dict(zip(_FIELDS, args))
        if p["type"] not in _TYPES:
            raise ValueError("%s: %s: unknown type %s" % (name, p["name"], p["type"]))
        params.append(p)
    if not params or len(params) != text.count("GF_PARAM("):
        raise ValueError("%s: %d GF_PARAM lines read of %d" % (name, len(params),
                                                               text.count("GF_PARAM(")))
    return params


def cfg_description(p):
    """The dynamic_reconfigure description: "<description> [unit] (paper: <value>)"."""
    text = "%s [%s]" % (p["description"], p["unit"] or "-")
    return text + (" (paper: %s)" % p["paper"] if p["paper"] else "")


def add_def_parameters(groups, def_names, edit_methods=None):
    """gen.add() of every parameter of the .def files `def_names` (in order) into its group.

    groups: {group name: the .cfg's gen.add_group() result}; edit_methods: {parameter name:
    gen.enum(...)} for the string parameters with fixed choices. All at level 0: every change
    rebuilds the filter.
    """
    edit_methods = edit_methods or {}
    for def_name in def_names:
        for p in read_def(def_name):
            args = [p["name"], _TYPES[p["type"]], 0, cfg_description(p), p["default"]]
            if p["type"] in ("double", "int"):
                args += [p["min"], p["max"]]
            kwargs = {}
            if p["name"] in edit_methods:
                kwargs["edit_method"] = edit_methods[p["name"]]
            groups[p["group"]].add(*args, **kwargs)


def scan_type_enum(gen):
    """The choices of scan_type (morph_params.def), the same in every method."""
    # Scan kind (docs/scan_types.md): auto decides per scan from the cloud itself whether it is
    # a ground-level scan (the method's own steps) or an airborne one (the morphological
    # surface, max_range off for it); the other values force one.
    return gen.enum([
        gen.const("auto", str_t, "auto", "decide per scan from the cloud"),
        gen.const("ground", str_t, "ground", "ground-level sensor (vehicle, robot)"),
        gen.const("airborne", str_t, "airborne", "airborne / nadir: morphological ground surface"),
        gen.const("tls", str_t, "tls", "terrestrial scanner on a tripod (ground-level steps)"),
        gen.const("registered", str_t, "registered",
                  "merged stations or sweeps, no sensor at the origin (ground-level steps)"),
    ], "scan kind")


def add_common_parameters(gen):
    """Adds the working volume every ground filter nodelet has (its own group, level 0)."""
    # Working volume around the sensor origin (include/ground_filter/working_volume.h): points
    # farther away, or nearer than min_range, are published as non-ground and counted. The hard
    # limit of 5000 m per axis (kWorkingVolumeHardLimit) holds also with max_range 0.
    volume = gen.add_group("working_volume", type="")
    volume.add("max_range", double_t, 0,
               "points farther than this from the sensor origin are non-ground and counted "
               "(out of range points); 0 = off (a hard limit of 5000 m per axis always holds) [m]",
               1000.0, 0.0, 5000.0)
    volume.add("min_range", double_t, 0,
               "points nearer than this to the sensor origin (the vehicle's own body) take no "
               "part in the ground model, are non-ground and counted (near points); below "
               "max_range; 0 = off; see also the private parameter body_box [m]",
               0.0, 0.0, 5000.0)
    add_height_above_ground_parameters(gen)
