"""The user documentation: README.md and docs/*.md (run by catkin_add_nosetests; no build
needed).

- The README keeps the two commands verbatim (and .ci/run the test command) and stays at most
  250 lines (details go to docs/; the generated parameter tables live in docs/parameters.md).
- Every relative link (file and #anchor) in README.md and docs/*.md resolves.
- The user docs speak the user's words: no development machine, agent or shared folder
  (docs/development_notes.md, for developers, may keep history). Figures name the CPU model,
  SIMD path, cores, command and date instead.
Each checker also runs on a planted file, so one that stopped finding anything fails too.
"""
import glob
import os
import re
import shutil
import tempfile
import unittest

ROOT = os.path.dirname(os.path.dirname(os.path.realpath(__file__)))
README_MAX_LINES = 250  # issue 39: the README at most 250 lines, details in docs/
# Developer history may stay here; every other page is user documentation.
DEV_ONLY = {"docs/development_notes.md"}
# Words of the development setup that mean nothing on a user's machine (case-sensitive where
# the word has another meaning; code names such as rostest_helpers.py or
# cloud_subscription_helper do not match \b...\b).
FORBIDDEN = [
    (re.compile(r"\bVMs?\b"), "a VM (name the CPU: lscpu's model name, SIMD path, cores)"),
    (re.compile(r"\b[Ss]essions?\b"), "a session"),
    (re.compile(r"\b[Hh]elpers?\b"), "a helper"),
    (re.compile(r"\b[Dd]evice pool\b"), "the device pool (name the GPU)"),
    (re.compile(r"\.\./shared|/shared/(data|peers)\b"),
     "../shared (data: data/ or $GF_DATA_DIR from scripts/get_data.sh; peers: scripts/peers/)"),
    (re.compile(r"\d UTC\b"), "a time of day (give the date)"),
    (re.compile(r"\bload (average )?\d"), "a load average (name the CPU and cores instead)"),
]
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)")


def user_docs(root=ROOT):
    files = [os.path.join(root, "README.md")]
    files += sorted(glob.glob(os.path.join(root, "docs", "*.md")))
    return [f for f in files if os.path.relpath(f, root) not in DEV_ONLY]


def forbidden_words(md_files, root=ROOT):
    """'file:line: word (what instead)' for every development-setup word in the files."""
    found = []
    for md in md_files:
        with open(md) as f:
            for n, line in enumerate(f, 1):
                for rx, why in FORBIDDEN:
                    m = rx.search(line)
                    if m:
                        found.append("%s:%d: '%s': %s" % (os.path.relpath(md, root), n,
                                                          m.group(0), why))
    return found


def github_anchor(heading):
    """The id GitHub gives a Markdown heading: lower case, punctuation dropped, spaces -> '-'."""
    text = heading.strip().lower().replace("`", "").replace("*", "")
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)  # a link in a heading keeps its text
    return re.sub(r"[^\w\- ]", "", text, flags=re.UNICODE).replace(" ", "-")


def anchors(path):
    """Anchors of every heading of a Markdown file (headings inside code blocks excluded)."""
    out, fence = set(), False
    with open(path) as f:
        for line in f:
            if line.startswith("```"):
                fence = not fence
            m = None if fence else re.match(r"^#{1,6} (.*?)\s*#*\s*$", line)
            if m:
                out.add(github_anchor(m.group(1)))
    return out


def broken_links(md_files, root=ROOT):
    """'file: target (why)' for every relative link whose file or #anchor does not exist."""
    broken = []
    for md in md_files:
        with open(md) as f:
            text = re.sub(r"```.*?```", "", f.read(), flags=re.S)  # no links in code blocks
        for m in LINK.finditer(text):
            target = m.group(1) or m.group(2)
            if re.match(r"^[a-z]+:", target):
                continue  # http(s), mailto: not checked here
            path, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(md), path)) if path else md
            where = os.path.relpath(md, root)
            if not os.path.exists(dest):
                broken.append("%s: %s (no such file)" % (where, target))
                continue
            if anchor and dest.endswith(".md") and anchor not in anchors(dest):
                broken.append("%s: %s (no such heading)" % (where, target))
    return broken


class ReadmeDocsTest(unittest.TestCase):

    def test_readme_two_commands_verbatim_and_short(self):
        with open(os.path.join(ROOT, "README.md")) as f:
            lines = f.read().splitlines()
        for cmd in ("bash scripts/demo.sh", "bash scripts/run_tests.sh"):
            self.assertTrue(any(l.split("#")[0].strip() == cmd for l in lines),
                            "README.md lost the command line: " + cmd)
        with open(os.path.join(ROOT, ".ci", "run")) as f:
            self.assertIn("bash scripts/run_tests.sh", f.read().splitlines(),
                          ".ci/run must call the README's test command verbatim")
        self.assertLessEqual(len(lines), README_MAX_LINES,
                             "README.md has %d lines (at most %d): move details to docs/"
                             % (len(lines), README_MAX_LINES))

    def test_relative_links_resolve(self):
        files = [os.path.join(ROOT, "README.md")]
        files += sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
        self.assertGreater(len(files), 1, "no docs/*.md found")
        broken = broken_links(files)
        self.assertEqual(broken, [], "broken links:\n" + "\n".join(broken))

    def test_user_docs_in_the_users_words(self):
        files = user_docs()
        self.assertIn(os.path.join(ROOT, "docs", "evaluation.md"), files)
        self.assertNotIn(os.path.join(ROOT, "docs", "development_notes.md"), files)
        found = forbidden_words(files)
        self.assertEqual(found, [], "words of the development setup in the user docs "
                         "(history may go to docs/development_notes.md):\n" + "\n".join(found))

    def test_word_checker_finds_planted_words(self):
        d = tempfile.mkdtemp()
        try:
            os.makedirs(os.path.join(d, "docs"))
            lines = ["Measured on the project's 2-core VM.",            # 1
                     "in the session above",                            # 2
                     "a GPU machine of the device pool",                # 3
                     "`../shared/data/semantickitti/seq00`",            # 4
                     "2026-11-27 21:30-21:31 UTC, load 1.1-1.2",        # 5
                     "the Python launch helper",                        # 6
                     "cloud_subscription_helper.cpp, rostest_helpers.py, VMware-free, "
                     "2026-11-27 on an AMD EPYC, 2 cores"]              # 7: none
            with open(os.path.join(d, "README.md"), "w") as f:
                f.write("\n".join(lines) + "\n")
            with open(os.path.join(d, "docs", "development_notes.md"), "w") as f:
                f.write("the shared 2-core VM, ../shared/data\n")
            files = user_docs(d)
            self.assertEqual(files, [os.path.join(d, "README.md")])
            found = forbidden_words(files, d)
            self.assertEqual([x.split(":")[1] for x in found], ["1", "2", "3", "4", "5", "5", "6"],
                             "\n".join(found))
        finally:
            shutil.rmtree(d)

    def test_link_checker_finds_broken_links(self):
        self.assertEqual(github_anchor("Gravity frame (tilted sensors)"),
                         "gravity-frame-tilted-sensors")
        self.assertEqual(github_anchor("`ground_filter_eval` (accuracy)"),
                         "ground_filter_eval-accuracy")
        d = tempfile.mkdtemp()
        try:
            with open(os.path.join(d, "b.md"), "w") as f:
                f.write("# B\n\n## Real heading\n\n```\n## Not a heading\n```\n")
            with open(os.path.join(d, "a.md"), "w") as f:
                f.write("[ok](b.md#real-heading) [bad anchor](b.md#not-a-heading) "
                        "[no file](c.md) [web](https://example.org/x#y)\n"
                        "```\n[in code](nowhere.md)\n```\n")
            broken = broken_links([os.path.join(d, "a.md")], root=d)
            self.assertEqual(broken, ["a.md: b.md#not-a-heading (no such heading)",
                                      "a.md: c.md (no such file)"])
        finally:
            shutil.rmtree(d)


if __name__ == "__main__":
    unittest.main()
