"""Parameters shared by every ground_filter nodelet's .cfg file.

Each .cfg imports this module and calls add_common_parameters(gen) so that shared names, ranges
and units are written once. Ranges match the C++ Params::validate() of the filters.
"""

from dynamic_reconfigure.parameter_generator_catkin import int_t


def add_common_parameters(gen, threads_default=1):
    """Adds the parameters every ground filter nodelet has (level 0: all rebuild the filter).

    threads_default: the filter's own default (its Params struct), e.g. 0 = all cores.
    """
    gen.add("threads", int_t, 0,
            "worker threads of the filter, 0 = all cores [threads]",
            threads_default, 0, 256)
