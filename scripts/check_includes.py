#!/usr/bin/env python3
"""Checks that #include lines point one way: from a room to itself or to a lower room.

    scripts/check_includes.py [ROOT]        # exit 1 and one line per wrong include

The rooms and what each may include are the table below (docs/architecture.md#rooms shows the
same order). A quoted include is resolved against the including file's folder, then against the
include roots (include/, src/core/, src/ (eval/), src/nodelets/, src/tools/, cuda/include/,
cuda/src/, test/);
angle-bracket includes (system, ROS, PCL, Eigen) and generated headers that do not exist in the
tree are not rooms and are ignored. Also fails on a file that belongs to no room, so a new folder gets a row.
"""
import os
import re
import sys

# (room, folder prefixes) -- the longest matching prefix decides a file's room.
ROOMS = [
    ("public", ["include/ground_filter/"]),
    # The CUDA library's interface (not installed): the library itself and the tests use it.
    ("cuda_api", ["cuda/include/"]),
    ("common", ["src/core/common/", "src/core/simd/"]),
    ("airborne", ["src/core/airborne/"]),
    ("hag", ["src/core/hag/"]),
    ("knn", ["src/core/knn/"]),
    ("voxel", ["src/core/voxel/"]),
    ("normal", ["src/core/normal/"]),
    ("core_top", ["src/core/"]),
    # The evaluation kit (scan files, metrics, generated scenes): outside the core, on its API.
    ("eval", ["src/eval/"]),
    ("cuda", ["cuda/src/"]),
    ("nodelets", ["src/nodelets/"]),
    ("tools", ["src/tools/"]),
    ("tests", ["test/", "cuda/test/", "cuda/bench/"]),
]

# What each room may include besides itself (lowest rooms first).
ALLOWED = {
    "public": set(),
    "cuda_api": {"public"},
    "common": {"public"},
    "airborne": {"public", "common"},
    "hag": {"public", "common"},
    "knn": {"public", "common"},
    "voxel": {"public", "common", "airborne"},
    "normal": {"public", "common", "airborne", "knn"},
    "core_top": {"public", "common", "airborne", "hag", "knn", "voxel", "normal"},
    "eval": {"public"},
    # The CUDA library, above the core: the public API, the common helpers, its interface, and of
    # the method rooms only the interfaces its adapters implement and the headers written to
    # compile for the kernels too (CUDA_SEES). The core never includes the CUDA library: it
    # reaches it through entry points it declares itself (knn/knn_backend.h,
    # normal/filter_executor.h), defined by cuda/src/ or by src/core/no_cuda.cpp.
    "cuda": {"public", "common", "cuda_api"},
    # Only the public API: the nodelets library is built without the core's private headers.
    "nodelets": {"public"},
    # Benchmarks time single stages (e.g. the kd-tree against PCL's): any core room.
    "tools": {"public", "common", "airborne", "hag", "knn", "voxel", "normal", "core_top",
              "eval"},
    "tests": {"public", "common", "airborne", "hag", "knn", "voxel", "normal", "core_top",
              "eval", "cuda_api", "cuda", "nodelets", "tools"},
}

# Public headers of whole filters: the rooms below the filters use the params structs
# (*_params.h) instead; only filters (files named *_filter.*, e.g. voxel_ground_filter.cpp or
# paper_voxel_filter.h, the voxel_paper filter around the voxel filter) include filter classes.
FILTER_HEADERS = {"include/ground_filter/voxel_ground_filter.h",
                  "include/ground_filter/normal_ground_filter.h",
                  "include/ground_filter/working_volume.h"}
STAGE_ROOMS = {"common", "airborne", "knn", "voxel", "normal"}

# Headers of the method rooms the CUDA library includes: the interfaces its adapters implement
# (header-only, so it links to nothing of the core) and the host/device shared maths
# (*cpu_gpu_common.h, compiled by nvcc too).
CUDA_SEES = re.compile(r"^src/core/(knn|normal)/(knn_backend|neighbor_list_store|neighborhood_pca|"
                       r"filter_executor|\w*cpu_gpu_common)\.h$")

INCLUDE_ROOTS = ["include", "src/core", "src", "src/nodelets", "src/tools", "cuda/include",
                 "cuda/src", "test", "cuda/test"]
SOURCE_DIRS = ["include", "src", "cuda/include", "cuda/src", "cuda/test", "cuda/bench", "test"]
EXTENSIONS = (".h", ".hpp", ".cpp", ".cu", ".cuh")
INCLUDE_RE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def room_of(rel):
    best, best_len = None, -1
    for room, prefixes in ROOMS:
        for p in prefixes:
            if rel.startswith(p) and len(p) > best_len:
                best, best_len = room, len(p)
    return best


def resolve(root, rel_file, target):
    here = os.path.dirname(rel_file)
    for base in [here] + INCLUDE_ROOTS:
        cand = os.path.normpath(os.path.join(base, target))
        if os.path.isfile(os.path.join(root, cand)):
            return cand
    return None


def source_files(root):
    """The C++ and CUDA files under SOURCE_DIRS (also scripts/check_sizes.py's), relative."""
    for d in SOURCE_DIRS:
        top = os.path.join(root, d)
        for dirpath, _, names in os.walk(top):
            if "fuzz_corpus" in dirpath:
                continue
            for n in sorted(names):
                if n.endswith(EXTENSIONS):
                    yield os.path.relpath(os.path.join(dirpath, n), root)


def check(root):
    errors = []
    edges = 0
    for rel in sorted(set(source_files(root))):
        src_room = room_of(rel)
        if src_room is None:
            errors.append(f"{rel}: in no room (add its folder to scripts/check_includes.py)")
            continue
        with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
            for lineno, line in enumerate(f, 1):
                m = INCLUDE_RE.match(line)
                if not m:
                    continue
                dst = resolve(root, rel, m.group(1))
                if dst is None:
                    continue  # generated (dynamic_reconfigure Config.h) or outside the tree
                dst_room = room_of(dst)
                edges += 1
                if src_room in STAGE_ROOMS and dst in FILTER_HEADERS:
                    stem = os.path.splitext(os.path.basename(rel))[0]
                    if not stem.endswith("_filter"):
                        errors.append(f"{rel}:{lineno}: includes the filter class {dst}; a "
                                      f"stage needs only its params header (*_params.h)")
                    continue
                if dst_room == src_room or dst_room in ALLOWED[src_room]:
                    continue
                if src_room == "cuda" and CUDA_SEES.match(dst):
                    continue
                errors.append(f"{rel}:{lineno}: {src_room} includes {dst} ({dst_room}): "
                              f"a {src_room} file may include only "
                              f"{', '.join(sorted(ALLOWED[src_room] | {src_room}))}")
    return errors, edges


def main():
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else
                           os.path.join(os.path.dirname(__file__), ".."))
    errors, edges = check(root)
    for e in errors:
        print(e)
    print(f"check_includes: {edges} includes between project files checked, "
          f"{len(errors)} point the wrong way")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
