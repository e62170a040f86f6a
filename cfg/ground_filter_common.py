"""Parameters shared by every ground_filter nodelet's .cfg file.

Each .cfg imports this module and calls add_common_parameters(gen) so that shared names, ranges
and units are written once. Ranges match the C++ Params::validate() of the filters.
"""

from dynamic_reconfigure.parameter_generator_catkin import int_t


def add_common_parameters(gen):
    """Adds the parameters every ground filter nodelet has (level 0: all rebuild the filter)."""
    gen.add("threads", int_t, 0,
            "worker threads of the filter, 0 = all cores [threads]",
            1, 0, 256)
