"""Parameters shared by every ground_filter nodelet's .cfg file.

Each .cfg imports this module and calls add_common_parameters(gen, performance, ...) so that
shared names, ranges and units are written once. Ranges match the C++ Params::validate() of the
filters and WorkingVolume::validate().
"""

from dynamic_reconfigure.parameter_generator_catkin import double_t, int_t


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


def add_common_parameters(gen, performance, threads_default=1, threads_note=""):
    """Adds the parameters every ground filter nodelet has (level 0: all rebuild the filter).

    performance: the .cfg's "performance" group (gets `threads`); the working volume gets its
    own group "working_volume".
    threads_default: the filter's own default (its Params struct), e.g. 0 = all cores.
    threads_note: why the method has that default (the nodelets differ), for the description.
    """
    performance.add("threads", int_t, 0,
                    "worker threads of the filter, 0 = all cores; " + threads_note + " [threads]"
                    if threads_note else "worker threads of the filter, 0 = all cores [threads]",
                    threads_default, 0, 256)
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
