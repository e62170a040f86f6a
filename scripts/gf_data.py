"""The evaluation data folder, the same rule as scripts/common.sh gf_data_dir: $GF_DATA_DIR when
set (an error when it is not a folder), else <repo>/data (scripts/get_data.sh fills it) when it
exists, else <repo>/../shared/data when it exists; else an error saying to run get_data.sh."""
import os

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))


class NoDataError(RuntimeError):
    pass


def data_dir(optional=False):
    """The data folder; without one: None when `optional`, else NoDataError saying what to do.
    GF_DATA_DIR naming no folder is an error either way."""
    env = os.environ.get("GF_DATA_DIR", "")
    if env:
        if not os.path.isdir(env):
            raise NoDataError("GF_DATA_DIR=%s is not a folder: fix or unset it "
                              "(bash scripts/get_data.sh --dest DIR fills a folder)" % env)
        return os.path.realpath(env)
    for d in (os.path.join(ROOT, "data"), os.path.join(ROOT, "..", "shared", "data")):
        if os.path.isdir(d):
            return os.path.realpath(d)
    if optional:
        return None
    raise NoDataError("no data: run bash scripts/get_data.sh (fills %s), or set GF_DATA_DIR "
                      "to a copy" % os.path.join(ROOT, "data"))


def built_tool(name="ground_filter_eval"):
    """A tool of this build (e.g. ground_filter_eval): the devel spaces on CMAKE_PREFIX_PATH, then
    the checkout's .ws; None when it is not built."""
    prefixes = os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep)
    prefixes.append(os.path.join(ROOT, ".ws", "devel"))
    for prefix in prefixes:
        path = os.path.join(prefix, "lib", "ground_filter", name)
        if prefix and os.access(path, os.X_OK):
            return path
    return None
