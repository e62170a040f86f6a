"""Parameters shared by every ground_filter nodelet's .cfg file.

Each .cfg imports this module and calls add_common_parameters(gen) so that shared names, ranges
and units are written once. Ranges match the C++ Params::validate() of the filters.
"""

from dynamic_reconfigure.parameter_generator_catkin import double_t, int_t


def add_common_parameters(gen, threads_default=1):
    """Adds the parameters every ground filter nodelet has (level 0: all rebuild the filter).

    threads_default: the filter's own default (its Params struct), e.g. 0 = all cores.
    """
    gen.add("threads", int_t, 0,
            "worker threads of the filter, 0 = all cores [threads]",
            threads_default, 0, 256)
    # Working volume around the sensor origin (include/ground_filter/working_volume.h): points
    # farther away are published as non-ground and counted ("out of range points"). The hard
    # limit of 5000 m per axis (kWorkingVolumeHardLimit) holds also with 0.
    gen.add("max_range", double_t, 0,
            "points farther than this from the sensor origin are non-ground and counted; 0 = off "
            "(a hard limit of 5000 m per axis always holds) [m]",
            1000.0, 0.0, 5000.0)
