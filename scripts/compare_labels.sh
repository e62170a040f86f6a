# Sourced by scripts/check_arm64.sh and scripts/check_gcc9.sh: label files of two builds compared
# byte for byte.
#   gf_compare_labels <tool> <what> <reference file> <file>
# prints "labels <what>: N of M differ" and returns 0 only when both files exist, have the same
# length and N is 0 (a missing or shorter file is named on stderr with <tool>).
gf_compare_labels() {
  local tool="$1" what="$2" ref="$3" got="$4" n
  if [[ ! -s "${ref}" || ! -s "${got}" ]] || [[ $(stat -c %s "${ref}") != $(stat -c %s "${got}") ]]; then
    echo "${tool}: ${what}: labels missing or of another length" >&2
    return 1
  fi
  n=$(cmp -l "${ref}" "${got}" | wc -l || true)
  echo "labels ${what}: ${n} of $(stat -c %s "${ref}") differ"
  [[ "${n}" == 0 ]]
}
