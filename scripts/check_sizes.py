#!/usr/bin/env python3
"""Checks the size limits of the sources: no file over 700 lines, no function over 120 lines.

    scripts/check_sizes.py [ROOT] [--list N]   # exit 1 and one line per file/function over;
                                               # --list N also prints the N longest functions

Functions are found the way clang-format lays them out here (Google style, namespaces not
indented): a definition starts at column 0 (its signature may continue on indented lines) and
ends at the next line that is just "}". Lambdas and local classes count towards the function
that holds them. Inline member functions inside a class body are not measured (short by habit).
"""
import os
import re
import sys

from check_includes import source_files  # the same C++/CUDA files, one walker

MAX_FILE_LINES = 700
MAX_FUNCTION_LINES = 120  # body lines between the braces
NOT_FUNCTION = re.compile(r"^(namespace\b|class\b|struct\b|union\b|enum\b|using\b|typedef\b|"
                          r"extern\s+\"C\"\s*\{|#|//|/\*|\*|}|template\s*<[^>]*>\s*$)")


def functions(lines):
    """Yields (name, first line number, body lines) of every column-0 function definition."""
    i, n = 0, len(lines)
    while i < n:
        line = lines[i]
        if not line or line[0].isspace() or NOT_FUNCTION.match(line):
            i += 1
            continue
        # A column-0 statement: gather its continuation lines up to '{' or ';'.
        j, text = i, line.rstrip()
        while not text.endswith("{") and not text.endswith(";") and j + 1 < n and \
                (lines[j + 1][:1].isspace() or lines[j + 1].startswith(")")):
            j += 1
            text += " " + lines[j].strip()
        if text.endswith("{") and "(" in text and "=" not in text.split("(")[0]:
            end = j + 1
            while end < n and lines[end].rstrip() != "}":
                end += 1
            name = re.sub(r"\s*\(.*", "", text).split()[-1] if text.split("(")[0].split() else "?"
            yield name, i + 1, end - j - 1
            i = end + 1
        else:
            i = j + 1


def check(root, list_n=0):
    errors, all_funcs = [], []
    for rel in sorted(set(source_files(root))):
        with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
            lines = f.read().split("\n")
        if lines and lines[-1] == "":
            lines.pop()
        if len(lines) > MAX_FILE_LINES:
            errors.append(f"{rel}: {len(lines)} lines (at most {MAX_FILE_LINES})")
        for name, first, body in functions(lines):
            all_funcs.append((body, f"{rel}:{first}: {name}"))
            if body > MAX_FUNCTION_LINES:
                errors.append(f"{rel}:{first}: {name}: {body} lines "
                              f"(at most {MAX_FUNCTION_LINES})")
    longest = sorted(all_funcs, reverse=True)[:list_n]
    return errors, len(all_funcs), longest


def main():
    args = sys.argv[1:]
    list_n = 0
    if "--list" in args:
        k = args.index("--list")
        list_n = int(args[k + 1])
        del args[k:k + 2]
    root = os.path.abspath(args[0] if args else os.path.join(os.path.dirname(__file__), ".."))
    errors, count, longest = check(root, list_n)
    for body, where in longest:
        print(f"{body:5d}  {where}")
    for e in errors:
        print(e)
    print(f"check_sizes: {count} functions measured, {len(errors)} over the limits")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
