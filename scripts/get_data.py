#!/usr/bin/env python3
"""The evaluation scans: fetched from their public sources (scripts/data_manifest.tsv: URLs at
pinned commits, licences), converted where needed, checked against the manifest's SHA-256.
Called by scripts/get_data.sh (see there for the options). Python 3.8+, numpy for conversions.

Every file is written to DEST/<path>.part (or a temporary folder in DEST) and renamed only after
its checksum matches, so an interrupted or failed run leaves no half-written file.
"""
import argparse
import hashlib
import os
import shutil
import socket
import sys
import tempfile
import urllib.error
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
GITHUB_RAW = "https://raw.githubusercontent.com/"
PROG = "get_data.sh"


class Failure(Exception):
    """One file could not be made; the message names it and says what to do."""


class NoNetwork(Failure):
    """The source host cannot be reached: further downloads are not tried."""


def say(msg):
    print("%s: %s" % (PROG, msg), file=sys.stderr)


def read_manifest(path):
    rows = []
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise SystemExit("%s: cannot read the manifest %s: %s" % (PROG, path, e.strerror))
    for n, line in enumerate(lines, 1):
        if not line.strip() or line.startswith("#"):
            continue
        cols = line.split("\t")
        if len(cols) != 6:
            raise SystemExit("%s: %s line %d: %d columns, expected 6 (tab-separated)" %
                             (PROG, path, n, len(cols)))
        rel, sha, convert, sources, source_sha, licence = cols
        if os.path.isabs(rel) or ".." in rel.split("/"):
            raise SystemExit("%s: %s line %d: path %r leaves the data folder" %
                             (PROG, path, n, rel))
        urls, shas = sources.split(), source_sha.split()
        if len(urls) != len(shas) or not urls:
            raise SystemExit("%s: %s line %d: %d sources but %d source checksums" %
                             (PROG, path, n, len(urls), len(shas)))
        rows.append({"path": rel, "sha256": sha, "convert": convert, "urls": urls,
                     "url_sha256": shas, "licence": licence})
    return rows


def sha256_of(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def remove_quietly(path):
    try:
        if os.path.isdir(path):
            shutil.rmtree(path)
        elif os.path.lexists(path):
            os.unlink(path)
    except OSError:
        pass


def install(tmp, final, want, what):
    """Renames tmp to final when its SHA-256 is `want`; else removes it and fails."""
    got = sha256_of(tmp)
    if got != want:
        remove_quietly(tmp)
        raise Failure("%s: checksum mismatch (sha256 %s, manifest %s); %s" % (final, got, want, what))
    os.replace(tmp, final)


def source_url(url):
    base = os.environ.get("GF_DATA_BASE_URL", "")
    if base and url.startswith(GITHUB_RAW):
        return base.rstrip("/") + "/" + url[len(GITHUB_RAW):]
    return url


def download(url, dest_file, want, timeout):
    """Downloads url to dest_file (must not exist) and checks it; removes it on any failure."""
    real = source_url(url)
    try:
        with urllib.request.urlopen(real, timeout=timeout) as r, open(dest_file, "wb") as out:
            shutil.copyfileobj(r, out, 1 << 20)
    except urllib.error.HTTPError as e:
        remove_quietly(dest_file)
        raise Failure("cannot fetch %s: HTTP %d %s (the file moved or the commit is gone: "
                      "report it, or take a copy with --from DIR)" % (real, e.code, e.reason))
    except (urllib.error.URLError, socket.timeout, ConnectionError) as e:
        remove_quietly(dest_file)
        reason = getattr(e, "reason", e)
        if isinstance(reason, FileNotFoundError) or (
                real.startswith("file:") and isinstance(reason, OSError)):
            raise Failure("cannot fetch %s: %s (set GF_DATA_BASE_URL right or unset it)" %
                          (real, reason))
        raise NoNetwork("cannot fetch %s: %s (no network? check the connection or a proxy "
                        "(https_proxy), or take an offline copy with --from DIR)" % (real, reason))
    except BaseException:
        remove_quietly(dest_file)
        raise
    got = sha256_of(dest_file)
    if got != want:
        remove_quietly(dest_file)
        raise Failure("%s: downloaded file has sha256 %s, manifest says %s (partial download or "
                      "changed source): run again, or take a copy with --from DIR" %
                      (real, got, want))


def make_from_sources(row, dest, timeout):
    final = os.path.join(dest, row["path"])
    folder = os.path.dirname(final)
    os.makedirs(folder, exist_ok=True)
    work = tempfile.mkdtemp(prefix=".get_data.", dir=folder)
    try:
        inputs = []
        for i, (url, want) in enumerate(zip(row["urls"], row["url_sha256"])):
            f = os.path.join(work, "src%d_%s" % (i, os.path.basename(url)))
            download(url, f, want, timeout)
            inputs.append(f)
        tmp = os.path.join(work, "out")
        kind = row["convert"]
        if kind == "copy":
            os.replace(inputs[0], tmp)
        else:
            convert(kind, inputs, tmp, final, row["urls"])
        install(tmp, final, row["sha256"],
                "the conversion (%s) does not give the reference file: take a copy with "
                "--from DIR" % kind)
    finally:
        remove_quietly(work)


def convert(kind, inputs, out, final, urls):
    sys.path.insert(0, HERE)
    try:
        import data_convert as dc
    except ImportError as e:
        raise Failure("%s: converting needs python3-numpy (%s): apt-get install python3-numpy" %
                      (final, e))
    try:
        if kind == "isprs":
            dc.convert_isprs(inputs[0], inputs[1], out)
        elif kind == "rellis":
            dc.convert_rellis(inputs[0], inputs[1], out)
        elif kind.startswith("las:"):
            parts = kind.split(":")
            offset = [float(v) for v in parts[1].split(",")]
            ignore = [int(v) for v in parts[2].split(",")] if len(parts) > 2 else []
            dc.convert_las(inputs[0], out, offset, ignore)
        else:
            raise Failure("%s: unknown conversion %r in the manifest" % (final, kind))
    except dc.ConvertError as e:
        msg = str(e)
        for f, url in zip(inputs, urls):  # the source's name, not the temporary file's
            msg = msg.replace(f, os.path.basename(url))
        raise Failure("%s: %s" % (final, msg))


def copy_from(row, src_dir, dest):
    src = os.path.join(src_dir, row["path"])
    final = os.path.join(dest, row["path"])
    if not os.path.isfile(src):
        raise Failure("%s: not in %s (a copy of the data folder has every file of "
                      "scripts/data_manifest.tsv)" % (src, src_dir))
    os.makedirs(os.path.dirname(final), exist_ok=True)
    if os.path.exists(final) and os.path.samefile(src, final):
        if sha256_of(final) != row["sha256"]:
            raise Failure("%s: checksum mismatch (manifest %s)" % (final, row["sha256"]))
        return
    tmp = final + ".part"
    try:
        shutil.copyfile(src, tmp)
        install(tmp, final, row["sha256"], "the copy in %s is damaged or another version: "
                "fetch it again without --from" % src_dir)
    except BaseException:
        remove_quietly(tmp)
        raise


def default_dest():
    env = os.environ.get("GF_DATA_DIR", "")
    if env:
        if not os.path.isdir(env):
            raise SystemExit("%s: GF_DATA_DIR=%s is not a folder: create it (mkdir -p %s), or "
                             "unset GF_DATA_DIR to use %s" % (PROG, env, env,
                                                              os.path.join(ROOT, "data")))
        return env
    return os.path.join(ROOT, "data")


def check_writable(dest):
    try:
        os.makedirs(dest, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".get_data.probe.", dir=dest)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise SystemExit("%s: cannot write to %s (%s): pick a writable folder with --dest DIR "
                         "or GF_DATA_DIR" % (PROG, dest, e.strerror or e))


def main(argv=None):
    ap = argparse.ArgumentParser(prog=PROG, description="Fetch the evaluation scans.")
    ap.add_argument("--from", dest="src", metavar="DIR",
                    help="copy from an offline copy of the data folder instead of downloading")
    ap.add_argument("--dest", metavar="DIR",
                    help="data folder to fill (default $GF_DATA_DIR, else <repo>/data)")
    ap.add_argument("--check", action="store_true",
                    help="only check the files in the data folder against the manifest")
    ap.add_argument("--list", action="store_true", help="list the files, sources and licences")
    ap.add_argument("--held-out", action="store_true",
                    help="the held-out scans (scripts/heldout_manifest.tsv) instead, into "
                         "<data folder>/heldout unless --dest says otherwise")
    ap.add_argument("--timeout", type=float, default=60.0, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    default_manifest = "heldout_manifest.tsv" if a.held_out else "data_manifest.tsv"
    manifest = os.environ.get("GF_DATA_MANIFEST", os.path.join(HERE, default_manifest))
    rows = read_manifest(manifest)

    if a.list:
        try:
            for r in rows:
                print("%s\t%s\t%s\t%s" % (r["path"], r["convert"], " ".join(r["urls"]),
                                           r["licence"]))
            sys.stdout.flush()
        except BrokenPipeError:  # `--list | head`: the reader has seen enough
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    dest = os.path.abspath(a.dest) if a.dest else default_dest()
    if a.held_out and not a.dest:
        dest = os.path.join(dest, "heldout")

    if a.check:
        bad = 0
        for r in rows:
            f = os.path.join(dest, r["path"])
            if not os.path.isfile(f):
                say("%s: missing" % f)
                bad += 1
            elif sha256_of(f) != r["sha256"]:
                say("%s: checksum mismatch (manifest %s)" % (f, r["sha256"]))
                bad += 1
        if bad:
            say("%d of %d files missing or different in %s: run scripts/get_data.sh%s" %
                (bad, len(rows), dest, " --dest " + dest if a.dest else ""))
            return 1
        print("%s: all %d files present, checksums match" % (dest, len(rows)))
        return 0

    if a.src and not os.path.isdir(a.src):
        raise SystemExit("%s: --from %s: no such folder" % (PROG, a.src))
    missing = [r for r in rows if not (os.path.isfile(os.path.join(dest, r["path"])) and
                                       sha256_of(os.path.join(dest, r["path"])) == r["sha256"])]
    if not missing:  # nothing to write: a read-only complete folder is fine
        print("%s: all %d files present, checksums match" % (dest, len(rows)))
        return 0
    check_writable(dest)
    failed, offline = [], False
    for r in rows:
        if r not in missing:
            print("ok       %s (already there)" % r["path"])
            continue
        final = os.path.join(dest, r["path"])
        if offline:
            failed.append((r["path"], "not tried: no network"))
            continue
        try:
            if a.src:
                copy_from(r, a.src, dest)
            else:
                make_from_sources(r, dest, a.timeout)
            print("ok       %s" % r["path"])
        except NoNetwork as e:
            offline = True
            say(str(e))
            failed.append((r["path"], str(e)))
        except Failure as e:
            say(str(e))
            failed.append((r["path"], str(e)))
        except OSError as e:
            say("%s: %s" % (final, e))
            failed.append((r["path"], str(e)))
    if failed:
        say("%d of %d files not made in %s:" % (len(failed), len(rows), dest))
        for path, why in failed:
            untried = why.startswith("not tried")
            say("  %s%s" % (path, " (not tried: no network)" if untried else ""))
        return 1
    print("%s: all %d files present, checksums match" % (dest, len(rows)))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        say("interrupted (no partial file left)")
        sys.exit(130)
