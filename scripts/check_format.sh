#!/usr/bin/env bash
# clang-format check of every C++/CUDA source of the package (.clang-format: Google-based, 100
# columns). Prints each file whose layout differs and exits 1; --fix rewrites them in place.
#   scripts/check_format.sh [--fix]
# The tree is laid out by clang-format 14 (Debian 12, Ubuntu 22.04); older versions place some
# constructs differently, so with clang-format < 14 (or none) it exits 77 with the reason
# (test/test_layout.py counts that as skipped).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
CF=""
for c in clang-format-14 clang-format; do
  if command -v "${c}" >/dev/null 2>&1; then CF="${c}"; break; fi
done
if [ -z "${CF}" ]; then
  echo "check_format: skipped: clang-format is not installed (apt install clang-format)"
  exit 77
fi
major="$("${CF}" --version | sed -E 's/.*version ([0-9]+).*/\1/')"
if [ "${major}" -lt 14 ] 2>/dev/null; then
  echo "check_format: skipped: ${CF} ${major} is older than clang-format 14, which lays out the tree"
  exit 77
fi
mapfile -t files < <(cd "${ROOT}" && find include src cuda test scripts/peers \
  \( -name '*.h' -o -name '*.hpp' -o -name '*.cpp' -o -name '*.cu' -o -name '*.cuh' \) \
  -not -path '*/fuzz_corpus/*' | sort)
cd "${ROOT}"
if [ "${1:-}" = "--fix" ]; then
  "${CF}" -i --style=file "${files[@]}"
  echo "check_format: ${#files[@]} files formatted with ${CF} ${major}"
  exit 0
fi
# One clang-format process for all files; each misplaced line is reported as FILE:LINE:COL.
mapfile -t bad < <("${CF}" --dry-run --style=file "${files[@]}" 2>&1 |
  sed -nE 's/^([^:]+):[0-9]+:[0-9]+: (warning|error):.*/\1/p' | sort -u)
for f in "${bad[@]}"; do echo "not formatted: ${f}  (fix: ${CF} -i ${f})"; done
echo "check_format: ${#files[@]} files checked with ${CF} ${major}, ${#bad[@]} not formatted"
[ "${#bad[@]}" = 0 ]
