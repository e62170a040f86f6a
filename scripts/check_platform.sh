#!/usr/bin/env bash
# Runs the README's two commands in a minimal root of another release, as a new user would:
#   bash scripts/check_platform.sh bullseye [--quick] [--fresh]
# 1. debootstraps a minimal Debian root (--variant=minbase, this machine's Debian mirror) once and
#    keeps it under ${GF_PLATFORM_CACHE:-/var/tmp/ground_filter_platform}/<release>/root;
# 2. clones this checkout's HEAD (committed work only) into it as /work/ground_filter, with the
#    data folder (scripts/common.sh gf_data_dir: $GF_DATA_DIR, data/, ../shared/data) bind-mounted
#    read-only at /work/shared/data (the clone's ../shared/data);
# 3. runs `bash scripts/demo.sh` and `bash scripts/run_tests.sh` there; the install step
#    (apt, scripts/common.sh gf_install_deps) has the network, the demo and the tests run in a
#    network namespace of their own (loopback only: no port or X display shared with this machine,
#    and proof that they need no network);
# 4. checks the "existing ROS comes first" path with a stand-in /opt/ros/noetic (Debian's ROS
#    sourced from /usr) and bad input (ROS 2 distro, broken setup.bash, no network).
# --quick: the build, the core gtests, one rostest and the demo instead of every test.
# --fresh: remove the cached root and compiler cache first (a cold run).
# GF_PLATFORM_GCC9=0 leaves out the GCC 9 steps (scripts/check_gcc9.sh in the root, x86-64 and aarch64).
# Compiles go through ccache (CMake's CMAKE_<LANG>_COMPILER_LAUNCHER environment variables, a cache
# kept beside the root; GF_PLATFORM_CCACHE=0 turns it off), so a second run rebuilds fast.
# Needs root (debootstrap, chroot, mount, unshare), debootstrap and git on this machine.
# Exit status 0 only when every step passed. Mounts are undone on exit (also on failure / ^C).
set -euo pipefail
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:${PATH}"

usage() { echo "usage: $0 bullseye [--quick] [--fresh]" >&2; exit 2; }
[ $# -ge 1 ] || usage
RELEASE="$1"; shift
QUICK=0; FRESH=0
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) QUICK=1 ;;
    --fresh) FRESH=1 ;;
    *) usage ;;
  esac
  shift
done
case "${RELEASE}" in
  bullseye) ;;  # Debian 11: Noetic's ROS 1 versions (catkin 0.8.9, CMake 3.18, GCC 10, PCL 1.11)
  *) echo "[platform] only 'bullseye' is supported (got '${RELEASE}')" >&2; exit 2 ;;
esac

die() { echo "[platform] ERROR: $*" >&2; exit 1; }
[ "$(id -u)" = 0 ] || die "needs root (debootstrap, chroot, mount): run it with sudo"
if ! command -v debootstrap >/dev/null; then
  echo "[platform] installing debootstrap (apt)"
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=900 debootstrap \
    >/dev/null || die "debootstrap is missing and apt could not install it: apt-get install debootstrap"
fi
command -v unshare >/dev/null || die "unshare (util-linux) is missing"

# shellcheck source=scripts/common.sh
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"  # GF_ROOT
DATA="$(gf_data_dir --or-repo)"
CACHE="${GF_PLATFORM_CACHE:-/var/tmp/ground_filter_platform}/${RELEASE}"
ROOT="${CACHE}/root"
CLONE_IN="/work/ground_filter"   # path inside the root; the data is at /work/shared/data
mkdir -p "${CACHE}"

# This machine's Debian mirror (deb822 .sources or a one-line sources.list; GF_DEBIAN_MIRROR
# overrides it).
mirror() {
  local m=""
  if [ -n "${GF_DEBIAN_MIRROR:-}" ]; then echo "${GF_DEBIAN_MIRROR}"; return; fi
  m="$(grep -h -E '^URIs:' /etc/apt/sources.list.d/*.sources 2>/dev/null | awk '{print $2}' |
       grep -v -- '-security' | head -n 1 || true)"
  [ -n "${m}" ] || m="$(grep -h -E '^deb ' /etc/apt/sources.list 2>/dev/null |
       awk '{for(i=2;i<=NF;i++) if ($i ~ /^https?:/) {print $i; exit}}' | grep -v -- '-security' |
       head -n 1 || true)"
  [ -n "${m}" ] || die "no Debian mirror found in /etc/apt/sources.list*: set GF_DEBIAN_MIRROR"
  echo "${m}"
}

# One run at a time per root.
exec 9>"${CACHE}.lock"
flock -n 9 || { echo "[platform] waiting for another run on ${ROOT}"; flock 9; }

MOUNTS=()
cleanup() {
  local i
  for ((i = ${#MOUNTS[@]} - 1; i >= 0; i--)); do
    umount -l "${MOUNTS[$i]}" 2>/dev/null || true
  done
  MOUNTS=()
}
trap cleanup EXIT
trap 'exit 130' INT TERM
mnt() {  # mnt <target> <mount args...>
  local target="$1"; shift
  mkdir -p "${target}"
  mount "$@" "${target}"
  MOUNTS+=("${target}")
}
mounted_under() { grep -q " ${ROOT}[/ ]" /proc/self/mounts; }

t_start=${SECONDS}
phase() { echo "[platform] $(date +%H:%M:%S) +$((SECONDS - t_start)) s: $*"; }

# ---------------------------------------------------------------- the root (cached)
if mounted_under; then
  die "something is still mounted under ${ROOT} (a run killed with -9?): umount -R -l those first"
fi
if [ "${FRESH}" = 1 ] || [ ! -f "${CACHE}/.base_complete" ]; then
  MIRROR="$(mirror)"; [ -n "${MIRROR}" ] || exit 1
  phase "debootstrap --variant=minbase ${RELEASE} from ${MIRROR}"
  rm -rf "${ROOT}" "${CACHE}/.base_complete" "${CACHE}/ccache"
  debootstrap --variant=minbase "${RELEASE}" "${ROOT}" "${MIRROR}" >"${CACHE}/debootstrap.log" 2>&1 ||
    { tail -n 20 "${CACHE}/debootstrap.log"; die "debootstrap failed (log ${CACHE}/debootstrap.log)"; }
  touch "${CACHE}/.base_complete"
  phase "debootstrap done"
else
  phase "reusing ${ROOT} (--fresh for a cold run)"
fi
cp -L /etc/resolv.conf "${ROOT}/etc/resolv.conf"
# debootstrap leaves no /etc/hosts; an installed Debian has one (localhost must resolve for ROS).
if [ ! -s "${ROOT}/etc/hosts" ]; then
  printf '127.0.0.1\tlocalhost\n::1\t\tlocalhost ip6-localhost ip6-loopback\n' >"${ROOT}/etc/hosts"
fi

# ---------------------------------------------------------------- the clone and the data
head_sha="$(git -C "${GF_ROOT}" rev-parse HEAD)"
rm -rf "${ROOT}${CLONE_IN}"
mkdir -p "$(dirname "${ROOT}${CLONE_IN}")"
git clone -q --no-hardlinks "${GF_ROOT}" "${ROOT}${CLONE_IN}"
git -C "${ROOT}${CLONE_IN}" checkout -q --detach "${head_sha}"
phase "cloned ${head_sha:0:12} into ${CLONE_IN}"
if [ -d "${DATA}" ]; then
  mnt "${ROOT}/work/shared/data" --bind "${DATA}"
  mount -o remount,bind,ro "${ROOT}/work/shared/data"
else
  echo "[platform] no data at ${DATA}: the data tests report themselves skipped"
fi
mnt "${ROOT}/proc" -t proc proc
mnt "${ROOT}/sys" -t sysfs sysfs
mnt "${ROOT}/dev" --bind /dev
mnt "${ROOT}/dev/pts" -t devpts devpts -o newinstance,ptmxmode=0666
mnt "${ROOT}/dev/shm" -t tmpfs tmpfs -o mode=1777
mnt "${ROOT}/tmp" -t tmpfs tmpfs -o mode=1777
CCACHE_ENV=""
if [ "${GF_PLATFORM_CCACHE:-1}" = 1 ]; then
  mkdir -p "${CACHE}/ccache"
  mnt "${ROOT}/var/cache/gf-ccache" --bind "${CACHE}/ccache"
  CCACHE_ENV="CCACHE_DIR=/var/cache/gf-ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache CMAKE_C_COMPILER_LAUNCHER=ccache"
fi

# A clean login-like environment: nothing of this machine's ROS / Python setup leaks in.
in_root() {  # in_root [--offline] <bash command>
  local net=()
  if [ "$1" = "--offline" ]; then
    net=(unshare --net -- /bin/sh -c 'ip link set lo up && exec "$@"' sh); shift
  fi
  "${net[@]}" chroot "${ROOT}" /usr/bin/env -i HOME=/root USER=root LOGNAME=root SHELL=/bin/bash \
    PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 TERM=dumb \
    GF_CHECK_PLATFORM=0 GF_CHECK_ARM64=0 ${CCACHE_ENV} ${GF_PLATFORM_ENV:-} \
    /bin/bash -c "$1"
}

rc=0
step() {  # step <name> [--offline] <command>: runs it, times it, records pass/fail
  local name="$1" t0=${SECONDS} r; shift
  phase "${name}: start"
  set +e
  in_root "$@"
  r=$?
  set -e
  phase "${name}: exit ${r} after $((SECONDS - t0)) s"
  echo "RESULT ${name} $([ "${r}" = 0 ] && echo passed || echo failed) $((SECONDS - t0))s" \
    >>"${CACHE}/results.txt"
  [ "${r}" = 0 ] || rc=1
}
: >"${CACHE}/results.txt"

# ---------------------------------------------------------------- the README's commands
# The install part of both commands (idempotent: nothing to do on a warm root), with the network.
step install "cd ${CLONE_IN} && bash -c 'source scripts/common.sh; gf_install_deps'"
# The harness's own tool (not part of the README's commands): ccache, with the network.
if [ -n "${CCACHE_ENV}" ] && [ ! -x "${ROOT}/usr/bin/ccache" ]; then
  in_root "DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ccache" \
    >/dev/null 2>&1 || { echo "[platform] ccache not installable: building without it"; CCACHE_ENV=""; }
fi
# The main job, and no roscpp [ERROR] line in what a new user sees (demo.sh once printed one on
# every run: its monitor asked the master before roslaunch had started it).
step demo --offline "cd ${CLONE_IN} && set -o pipefail && bash scripts/demo.sh 2>&1 | \
  tee /tmp/gf_demo.log && ! grep -n '\[ERROR\]' /tmp/gf_demo.log"
if [ "${QUICK}" = 1 ]; then
  # The build (demo.sh did it), the core gtests and one rostest on a KITTI frame.
  step tests_quick --offline "cd ${CLONE_IN} && source scripts/common.sh && gf_ros_env && \
    cd \${GF_WS} && catkin_make tests -j\$(nproc) >/dev/null && rm -rf build/test_results && \
    rostest=\$(cd build && make help | grep -o 'run_tests_ground_filter_rostest_voxel_nodelet[^ ]*' | head -n 1) && \
    catkin_make -j1 run_tests_ground_filter_gtest_test_core \
      run_tests_ground_filter_gtest_test_voxel_scale \
      run_tests_ground_filter_gtest_test_normal_ground_filter \
      run_tests_ground_filter_gtest_test_normal_knn_pca \
      run_tests_ground_filter_gtest_test_normal_internals \
      run_tests_ground_filter_gtest_test_kdtree_neighbor_search \${rostest} && \
    python3 ${CLONE_IN}/scripts/test_summary.py build/test_results"
else
  step run_tests --offline "cd ${CLONE_IN} && bash scripts/run_tests.sh"
fi

# ---------------------------------------------------------------- an existing ROS comes first
step existing_ros --offline "bash ${CLONE_IN}/scripts/check_existing_ros.sh ${CLONE_IN}"

# ---------------------------------------------------------------- the GCC 9 floor (focal, JetPack 5)
# Not a README command: Debian 11's g++-9 (9.3.0) and aarch64-linux-gnu-g++-9 build the core, its
# gtests run (aarch64 under qemu-user) and the labels of both builds agree (scripts/check_gcc9.sh).
if [ "${GF_PLATFORM_GCC9:-1}" = 1 ]; then
  step gcc9_install "bash ${CLONE_IN}/scripts/check_gcc9.sh --install"
  step gcc9 --offline "bash ${CLONE_IN}/scripts/check_gcc9.sh"
fi

cleanup
phase "done: $(grep -c ' passed ' "${CACHE}/results.txt") steps passed, \
$(grep -c ' failed ' "${CACHE}/results.txt" || true) failed (${CACHE}/results.txt)"
cat "${CACHE}/results.txt"
exit "${rc}"
